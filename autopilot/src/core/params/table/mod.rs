//! The parameter table: every parameter of the vehicle, declared once, with the config field(s) it maps
//! onto. In: nothing (static data). Out: [`PARAMS`], in the order of their MAVLink `param_index`.
//!
//! Each entry names its [`VehicleConfig`](crate::core::config::VehicleConfig) field; the macros derive
//! both directions of the mapping from that one path. Add new parameters at the END of the table, so that
//! the indices of the existing ones stay what ground stations have cached (ArduPilot's rule); the docs
//! group them by [`ParamGroup`](super::ParamGroup) whatever their position. One file holds each part of
//! the table (the ACO, the baselines, the shared controller settings, the commander, the navigator,
//! telemetry); `SECTIONS` lists the parts in index order.

use std::sync::LazyLock;

use super::ParamDef;

/// A live REAL32 parameter on one f64 config field (its name a literal, or built with `concat!`).
macro_rules! real {
    ($group:ident, $name:expr, $default:literal, [$min:literal, $max:literal], $unit:literal, $desc:literal,
     $($field:tt)+) => {
        ParamDef {
            name: $name,
            group: ParamGroup::$group,
            kind: ParamKind::Real,
            default: $default,
            min: $min,
            max: $max,
            unit: $unit,
            restart: false,
            description: $desc,
            binding: Binding::Config { get: |c| c.$($field)+, set: |c, v| c.$($field)+ = v },
        }
    };
}

/// A whole-number parameter on one u32 config field (`set` has checked it is whole and in range).
macro_rules! whole {
    ($group:ident, $name:literal, $default:literal, [$min:literal, $max:literal], $unit:literal,
     restart = $restart:literal, $desc:literal, $($field:tt)+) => {
        ParamDef {
            name: $name,
            group: ParamGroup::$group,
            kind: ParamKind::Integer,
            default: $default,
            min: $min,
            max: $max,
            unit: $unit,
            restart: $restart,
            description: $desc,
            binding: Binding::Config { get: |c| f64::from(c.$($field)+), set: |c, v| c.$($field)+ = v as u32 },
        }
    };
}

/// A live boolean parameter (0 or 1) on one bool config field.
macro_rules! flag {
    ($group:ident, $name:literal, $default:literal, $desc:literal, $($field:tt)+) => {
        ParamDef {
            name: $name,
            group: ParamGroup::$group,
            kind: ParamKind::Boolean,
            default: $default,
            min: 0.0,
            max: 1.0,
            unit: "0/1",
            restart: false,
            description: $desc,
            binding: Binding::Config {
                get: |c| if c.$($field)+ { 1.0 } else { 0.0 },
                set: |c, v| c.$($field)+ = v != 0.0,
            },
        }
    };
}

/// A live REAL32 parameter of the nominal airframe: read from the ACO's, written to all three
/// controllers' (`control.aco`, `control.mrac`, `control.pid`).
macro_rules! airframe {
    ($name:literal, $default:literal, [$min:literal, $max:literal], $unit:literal, $desc:literal, $($field:tt)+) => {
        ParamDef {
            name: $name,
            group: ParamGroup::Airframe,
            kind: ParamKind::Real,
            default: $default,
            min: $min,
            max: $max,
            unit: $unit,
            restart: false,
            description: $desc,
            binding: Binding::Config {
                get: |c| c.control.aco.airframe.$($field)+,
                set: |c, v| {
                    c.control.aco.airframe.$($field)+ = v;
                    c.control.mrac.airframe.$($field)+ = v;
                    c.control.pid.airframe.$($field)+ = v;
                },
            },
        }
    };
}

mod aco;
mod baselines;
mod commander;
mod control;
mod manual;
mod navigation;
mod telemetry;

/// The table's sections in `param_index` order. A new section or parameter goes at the END, so that the
/// indices of the existing ones stay what ground stations have cached.
const SECTIONS: &[&[ParamDef]] = &[
    aco::CASCADE,
    aco::LMS,
    control::LOOP_RATES,
    control::AIRFRAME,
    baselines::PID,
    baselines::MRAC,
    commander::COMMANDER,
    navigation::NAVIGATOR,
    telemetry::TELEMETRY,
    navigation::TRAJECTORIES,
    commander::FAILSAFES,
    telemetry::ULOG,
    baselines::COMPETENT_CA,
    commander::MOTOR_TEST,
    manual::RADIO,
    manual::MANUAL_FLIGHT,
    manual::RADIO_CALIBRATION,
    commander::FAULTS,
];

/// How many parameters the sections hold together.
const fn total_len(sections: &[&[ParamDef]]) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < sections.len() {
        n += sections[i].len();
        i += 1;
    }
    n
}

/// The sections one after the other, at compile time.
const fn concatenated<const N: usize>(sections: &[&[ParamDef]]) -> [ParamDef; N] {
    let mut out = [sections[0][0]; N];
    let (mut n, mut i) = (0, 0);
    while i < sections.len() {
        let mut j = 0;
        while j < sections[i].len() {
            out[n] = sections[i][j];
            n += 1;
            j += 1;
        }
        i += 1;
    }
    out
}

/// The core's table as one array.
static TABLE: [ParamDef; total_len(SECTIONS)] = concatenated(SECTIONS);

/// Every parameter, in `param_index` order: the core's table, then each registered controller's own
/// ([`ControllerType::params`](crate::core::control::ControllerType::params)) in the registry's order.
/// Built at first use: a controller registered after that has no parameters.
pub static PARAMS: LazyLock<&'static [ParamDef]> = LazyLock::new(|| {
    let mut all = TABLE.to_vec();
    for kind in crate::core::control::registry::all() {
        all.extend_from_slice(kind.ty().params());
    }
    Vec::leak(all)
});

#[cfg(test)]
mod tests {
    use super::*;

    /// Every parameter's name at its `param_index`, as ground stations have cached them: a parameter
    /// moved, removed or inserted before the end changes an index and fails here.
    const INDEX_ORDER: [&str; 122] = [
        "ACO_POS_P",
        "ACO_VEL_P",
        "ACO_ROLL_P",
        "ACO_PITCH_P",
        "ACO_YAW_P",
        "ACO_ROLLRATE_P",
        "ACO_PITCHRATE_P",
        "ACO_YAWRATE_P",
        "ACO_ROLL_RMAX",
        "ACO_PITCH_RMAX",
        "ACO_YAW_RMAX",
        "ACO_VEL_MAX_NE",
        "ACO_VEL_MAX_D",
        "ACO_ACC_MAX_NE",
        "ACO_ACC_MAX_D",
        "ACO_GAM_W_T",
        "ACO_GAM_B_T",
        "ACO_GAM_C_R",
        "ACO_GAM_D_R",
        "ACO_LPF_T_HZ",
        "ACO_LPF_R_HZ",
        "ACO_W_T_MIN",
        "ACO_W_T_MAX",
        "ACO_B_T_MAX",
        "ACO_C_R_MIN",
        "ACO_C_R_MAX",
        "ACO_D_R_MAX",
        "ACO_ALPHA_REF",
        "ACO_ADAPT_EN",
        "ACO_POS_I_EN",
        "ACO_POS_I",
        "ACO_POS_I_ZONE",
        "LOOP_INNER_HZ",
        "LOOP_POS_HZ",
        "AF_MASS",
        "AF_IXX",
        "AF_IYY",
        "AF_IZZ",
        "AF_ARM",
        "AF_YAW_MOM",
        "AF_ROTOR_TAU",
        "PID_POS_P",
        "PID_VEL_P",
        "PID_VEL_I_NE",
        "PID_VEL_I_D",
        "PID_ROLL_P",
        "PID_PITCH_P",
        "PID_YAW_P",
        "PID_ROLLRATE_P",
        "PID_PITCHRATE_P",
        "PID_YAWRATE_P",
        "PID_ROLLRATE_I",
        "PID_PITCHRATE_I",
        "PID_YAWRATE_I",
        "MRAC_GAM_K_ATT",
        "MRAC_GAM_TH_ATT",
        "MRAC_GAM_K_POS",
        "MRAC_GAM_TH_POS",
        "MRAC_FREEZE_SAT",
        "MIS_TAKEOFF_ALT",
        "MPC_TKO_SPEED",
        "MPC_LAND_SPEED",
        "COM_DISARM_LAND",
        "COM_DISARM_PRFLT",
        "NAV_MC_ALT_RAD",
        "MPC_XY_CRUISE",
        "MPC_Z_VEL_MAX_UP",
        "MPC_ACC_HOR",
        "NAV_ACC_RAD",
        "RTL_RETURN_ALT",
        "COM_OF_LOSS_T",
        "ACO_WEIGHTS_HZ",
        "MPC_Z_VEL_MAX_DN",
        "MPC_ACC_UP_MAX",
        "MPC_ACC_DOWN_MAX",
        "MPC_JERK_AUTO",
        "COM_DL_LOSS_T",
        "NAV_DLL_ACT",
        "COM_LOW_BAT_ACT",
        "BAT_LOW_THR",
        "BAT_CRIT_THR",
        "BAT_EMERGEN_THR",
        "GF_ACTION",
        "GF_MAX_HOR_DIST",
        "GF_MAX_VER_DIST",
        "SDLOG_MODE",
        "MRAC_FF",
        "MRAC_WI_ATT",
        "MRAC_WI_POS",
        "MRAC_EMOD",
        "MRAC_HEDGE",
        "COM_MOT_TEST_EN",
        "RC_MAP_ROLL",
        "RC_MAP_PITCH",
        "RC_MAP_YAW",
        "RC_MAP_THROTTLE",
        "RC_MAP_FLTMODE",
        "RC_MAP_KILL_SW",
        "RC_MAP_ARM_SW",
        "COM_RC_IN_MODE",
        "COM_RC_LOSS_T",
        "COM_RC_ARM_HYST",
        "MAN_ARM_GESTURE",
        "COM_FLTMODE1",
        "COM_FLTMODE2",
        "COM_FLTMODE3",
        "COM_FLTMODE4",
        "COM_FLTMODE5",
        "COM_FLTMODE6",
        "NAV_RCL_ACT",
        "COM_RCL_EXCEPT",
        "MPC_MAN_TILT_MAX",
        "MPC_MAN_Y_MAX",
        "MPC_MANTHR_MIN",
        "MPC_THR_HOVER",
        "MPC_VEL_MANUAL",
        "MPC_ACC_HOR_MAX",
        "MPC_JERK_MAX",
        "MPC_HOLD_DZ",
        "MPC_XY_MAN_EXPO",
        "MPC_Z_MAN_EXPO",
        "MPC_YAW_EXPO",
    ];

    /// The radio's calibration, appended after the manual flight's: RC1_MIN .. RC18_DZ, channel by channel.
    fn rc_calibration_names() -> impl Iterator<Item = String> {
        (1..=18).flat_map(|n| ["MIN", "MAX", "TRIM", "REV", "DZ"].map(|s| format!("RC{n}_{s}")))
    }

    #[test]
    fn given_the_table_when_listed_then_every_parameter_keeps_its_param_index() {
        let names: Vec<&str> = PARAMS.iter().map(|d| d.name).collect();
        let faults = [
            "SYS_FAILURE_EN",
            "COM_POS_FS_DELAY",
            "FD_FAIL_R",
            "FD_FAIL_P",
            "FD_FAIL_R_TTRI",
            "FD_FAIL_P_TTRI",
            "FD_ACT",
        ];
        let expected: Vec<String> = INDEX_ORDER
            .iter()
            .map(|s| (*s).to_owned())
            .chain(rc_calibration_names())
            .chain(faults.iter().map(|s| (*s).to_owned()))
            .chain(
                crate::core::control::registry::all().iter().flat_map(|k| k.ty().params()).map(|d| d.name.to_owned()),
            )
            .collect();
        assert_eq!(names, expected);
    }
}
