//! The parameter table: every parameter of the vehicle, declared once, with the config field(s) it maps
//! onto. In: nothing (static data). Out: [`PARAMS`], in the order of their MAVLink `param_index`.
//!
//! Each entry names its [`VehicleConfig`](crate::core::config::VehicleConfig) field; the macros derive
//! both directions of the mapping from that one path. Add new parameters at the END of the table, so that
//! the indices of the existing ones stay what ground stations have cached (ArduPilot's rule); the docs
//! group them by [`ParamGroup`] whatever their position.

use super::{Binding, ParamDef, ParamGroup, ParamKind};

/// A live REAL32 parameter on one f64 config field.
macro_rules! real {
    ($group:ident, $name:literal, $default:literal, [$min:literal, $max:literal], $unit:literal, $desc:literal,
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

/// Every parameter, in `param_index` order.
pub static PARAMS: &[ParamDef] = &[
    // ACO controller: the cascade (spec A.4 steps 4-7).
    real!(
        Aco,
        "ACO_POS_P",
        0.6667,
        [0.05, 5.0],
        "1/s",
        "Position gain Kp: velocity command per metre of position error.",
        control.aco.kp_pos_per_s
    ),
    real!(
        Aco,
        "ACO_VEL_P",
        2.16,
        [0.1, 20.0],
        "1/s",
        "Velocity gain Kv: acceleration demand per m/s of velocity error.",
        control.aco.kv_vel_per_s
    ),
    real!(
        Aco,
        "ACO_ROLL_P",
        2.778,
        [0.1, 20.0],
        "1/s",
        "Roll attitude gain Kη (Eqs 22-24).",
        control.aco.k_att_per_s[0]
    ),
    real!(
        Aco,
        "ACO_PITCH_P",
        2.778,
        [0.1, 20.0],
        "1/s",
        "Pitch attitude gain Kη (Eqs 22-24).",
        control.aco.k_att_per_s[1]
    ),
    real!(Aco, "ACO_YAW_P", 1.389, [0.1, 20.0], "1/s", "Yaw attitude gain Kη (Eqs 22-24).", control.aco.k_att_per_s[2]),
    real!(
        Aco,
        "ACO_ROLLRATE_P",
        9.0,
        [0.5, 50.0],
        "1/s",
        "Roll rate gain Kω (Eq 9 inverted).",
        control.aco.k_rate_per_s[0]
    ),
    real!(
        Aco,
        "ACO_PITCHRATE_P",
        9.0,
        [0.5, 50.0],
        "1/s",
        "Pitch rate gain Kω (Eq 9 inverted).",
        control.aco.k_rate_per_s[1]
    ),
    real!(
        Aco,
        "ACO_YAWRATE_P",
        4.5,
        [0.5, 50.0],
        "1/s",
        "Yaw rate gain Kω (Eq 9 inverted).",
        control.aco.k_rate_per_s[2]
    ),
    real!(
        Aco,
        "ACO_ROLL_RMAX",
        3.5,
        [0.1, 10.0],
        "rad/s",
        "Limit on the desired roll rate.",
        control.aco.rate_limit_radps[0]
    ),
    real!(
        Aco,
        "ACO_PITCH_RMAX",
        3.5,
        [0.1, 10.0],
        "rad/s",
        "Limit on the desired pitch rate.",
        control.aco.rate_limit_radps[1]
    ),
    real!(
        Aco,
        "ACO_YAW_RMAX",
        1.5,
        [0.1, 10.0],
        "rad/s",
        "Limit on the desired yaw rate.",
        control.aco.rate_limit_radps[2]
    ),
    real!(
        Aco,
        "ACO_VEL_MAX_NE",
        3.0,
        [0.1, 20.0],
        "m/s",
        "Limit on the velocity command, north and east (per axis).",
        control.aco.vel_limit_ne_mps
    ),
    real!(
        Aco,
        "ACO_VEL_MAX_D",
        2.0,
        [0.1, 10.0],
        "m/s",
        "Limit on the vertical velocity command.",
        control.aco.vel_limit_d_mps
    ),
    real!(
        Aco,
        "ACO_ACC_MAX_NE",
        5.0,
        [0.1, 20.0],
        "m/s²",
        "Limit on the horizontal norm of the desired acceleration.",
        control.aco.acc_limit_ne_mps2
    ),
    real!(
        Aco,
        "ACO_ACC_MAX_D",
        4.0,
        [0.1, 15.0],
        "m/s²",
        "Limit on the vertical desired acceleration.",
        control.aco.acc_limit_d_mps2
    ),
    // ACO controller: the LMS identification (spec A.1, Eqs 11-18).
    real!(
        Aco,
        "ACO_GAM_W_T",
        10.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the translation gain weights w_i (gamma = 2 mu f_s).",
        control.aco.gamma_w_t_per_s
    ),
    real!(
        Aco,
        "ACO_GAM_B_T",
        5.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the translation bias weights b_i.",
        control.aco.gamma_b_t_per_s
    ),
    real!(
        Aco,
        "ACO_GAM_C_R",
        20.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the rotation gain weights c_j.",
        control.aco.gamma_c_r_per_s
    ),
    real!(
        Aco,
        "ACO_GAM_D_R",
        5.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the rotation bias weights d_j.",
        control.aco.gamma_d_r_per_s
    ),
    real!(
        Aco,
        "ACO_LPF_T_HZ",
        8.0,
        [0.5, 40.0],
        "Hz",
        "Cutoff of the 2nd-order low-pass on both sides of the translation LMS.",
        control.aco.lpf_translation_hz
    ),
    real!(
        Aco,
        "ACO_LPF_R_HZ",
        15.0,
        [0.5, 40.0],
        "Hz",
        "Cutoff of the 2nd-order low-pass on both sides of the rotation LMS.",
        control.aco.lpf_rotation_hz
    ),
    real!(
        Aco,
        "ACO_W_T_MIN",
        0.5,
        [0.05, 1.0],
        "g",
        "Lower bound of the translation gain weights w_i, in units of g.",
        control.aco.w_t_bounds_g[0]
    ),
    real!(
        Aco,
        "ACO_W_T_MAX",
        2.0,
        [1.0, 10.0],
        "g",
        "Upper bound of the translation gain weights w_i, in units of g.",
        control.aco.w_t_bounds_g[1]
    ),
    real!(
        Aco,
        "ACO_B_T_MAX",
        4.0,
        [0.0, 20.0],
        "m/s²",
        "Bound on the magnitude of the translation bias weights b_i.",
        control.aco.b_t_max_mps2
    ),
    real!(
        Aco,
        "ACO_C_R_MIN",
        0.5,
        [0.05, 1.0],
        "alpha_ref",
        "Lower bound of the rotation gain weights c_j, in units of ACO_ALPHA_REF.",
        control.aco.c_r_bounds_alpha_ref[0]
    ),
    real!(
        Aco,
        "ACO_C_R_MAX",
        2.0,
        [1.0, 10.0],
        "alpha_ref",
        "Upper bound of the rotation gain weights c_j, in units of ACO_ALPHA_REF.",
        control.aco.c_r_bounds_alpha_ref[1]
    ),
    real!(
        Aco,
        "ACO_D_R_MAX",
        8.0,
        [0.0, 50.0],
        "rad/s²",
        "Bound on the magnitude of the rotation bias weights d_j.",
        control.aco.d_r_max_radps2
    ),
    real!(
        Aco,
        "ACO_ALPHA_REF",
        10.0,
        [0.1, 1000.0],
        "rad/s²",
        "Normalisation of the rotation regressor (the nominal c_j); a change rescales the c_j.",
        control.aco.alpha_ref_radps2
    ),
    flag!(
        Aco,
        "ACO_ADAPT_EN",
        1.0,
        "LMS adaptation on; 0 freezes every weight where it is.",
        control.aco.adaptation_enabled
    ),
    flag!(
        Aco,
        "ACO_POS_I_EN",
        0.0,
        "Zoned position integral on (spec A.4, optional on hardware).",
        control.aco.pos_integral_enabled
    ),
    real!(
        Aco,
        "ACO_POS_I",
        0.1,
        [0.0, 5.0],
        "1/s",
        "Position integral gain Ki: v_c = Kp (e_p + Ki ∫e_p dt) + v_ref.",
        control.aco.ki_pos_per_s
    ),
    real!(
        Aco,
        "ACO_POS_I_ZONE",
        0.25,
        [0.01, 10.0],
        "m",
        "The position integral accumulates on an axis only while its error is below this.",
        control.aco.pos_integral_zone_m
    ),
    // Loop rates.
    whole!(
        Loop,
        "LOOP_INNER_HZ",
        500.0,
        [100.0, 2000.0],
        "Hz",
        restart = true,
        "Rate of the inner loops (rate, attitude, LMS); one tick per plant sample.",
        control.rates.inner_hz
    ),
    whole!(
        Loop,
        "LOOP_POS_HZ",
        100.0,
        [10.0, 500.0],
        "Hz",
        restart = true,
        "Rate of the position loop; must divide LOOP_INNER_HZ.",
        control.rates.position_hz
    ),
    // Nominal airframe, shared by the three controllers.
    airframe!("AF_MASS", 5.2, [0.1, 100.0], "kg", "Nominal mass m̄.", mass_kg),
    airframe!("AF_IXX", 0.08, [0.0001, 10.0], "kg·m²", "Nominal inertia Īx about the FRD x axis.", inertia_kgm2[0]),
    airframe!("AF_IYY", 0.08, [0.0001, 10.0], "kg·m²", "Nominal inertia Īy about the FRD y axis.", inertia_kgm2[1]),
    airframe!("AF_IZZ", 0.12, [0.0001, 10.0], "kg·m²", "Nominal inertia Īz about the FRD z axis.", inertia_kgm2[2]),
    airframe!("AF_ARM", 0.24, [0.02, 5.0], "m", "Arm length l, rotor to centre.", arm_m),
    airframe!(
        "AF_YAW_MOM",
        0.02703,
        [0.0001, 1.0],
        "m",
        "Yaw-moment coefficient λ: rotor yaw torque per newton of lift.",
        yaw_moment_m
    ),
    airframe!("AF_ROTOR_TAU", 0.04, [0.001, 1.0], "s", "Rotor first-order lag τ̄ (the ACO's rotor model).", rotor_tau_s),
    // PID baseline.
    real!(Pid, "PID_POS_P", 0.6667, [0.05, 5.0], "1/s", "Position gain Kp.", control.pid.kp_pos_per_s),
    real!(Pid, "PID_VEL_P", 2.16, [0.1, 20.0], "1/s", "Velocity gain Kv.", control.pid.kv_vel_per_s),
    ParamDef {
        name: "PID_VEL_I_NE",
        group: ParamGroup::Pid,
        kind: ParamKind::Real,
        default: 0.4,
        min: 0.0,
        max: 20.0,
        unit: "1/s²",
        restart: false,
        description: "Velocity integral gain Kvi, north and east (both).",
        binding: Binding::Config {
            get: |c| c.control.pid.kvi_vel_per_s2[0],
            set: |c, v| {
                c.control.pid.kvi_vel_per_s2[0] = v;
                c.control.pid.kvi_vel_per_s2[1] = v;
            },
        },
    },
    real!(
        Pid,
        "PID_VEL_I_D",
        2.0,
        [0.0, 20.0],
        "1/s²",
        "Velocity integral gain Kvi, down.",
        control.pid.kvi_vel_per_s2[2]
    ),
    real!(Pid, "PID_ROLL_P", 2.778, [0.1, 20.0], "1/s", "Roll attitude gain Kη.", control.pid.k_att_per_s[0]),
    real!(Pid, "PID_PITCH_P", 2.778, [0.1, 20.0], "1/s", "Pitch attitude gain Kη.", control.pid.k_att_per_s[1]),
    real!(Pid, "PID_YAW_P", 1.389, [0.1, 20.0], "1/s", "Yaw attitude gain Kη.", control.pid.k_att_per_s[2]),
    real!(Pid, "PID_ROLLRATE_P", 9.0, [0.5, 50.0], "1/s", "Roll rate gain Kω.", control.pid.k_rate_per_s[0]),
    real!(Pid, "PID_PITCHRATE_P", 9.0, [0.5, 50.0], "1/s", "Pitch rate gain Kω.", control.pid.k_rate_per_s[1]),
    real!(Pid, "PID_YAWRATE_P", 4.5, [0.5, 50.0], "1/s", "Yaw rate gain Kω.", control.pid.k_rate_per_s[2]),
    real!(
        Pid,
        "PID_ROLLRATE_I",
        12.0,
        [0.0, 100.0],
        "1/s²",
        "Roll rate integral gain Kri.",
        control.pid.kri_rate_per_s2[0]
    ),
    real!(
        Pid,
        "PID_PITCHRATE_I",
        12.0,
        [0.0, 100.0],
        "1/s²",
        "Pitch rate integral gain Kri.",
        control.pid.kri_rate_per_s2[1]
    ),
    real!(
        Pid,
        "PID_YAWRATE_I",
        2.25,
        [0.0, 100.0],
        "1/s²",
        "Yaw rate integral gain Kri.",
        control.pid.kri_rate_per_s2[2]
    ),
    // MRAC ("CA") baseline.
    real!(
        Mrac,
        "MRAC_GAM_K_ATT",
        1000.0,
        [0.0, 10000.0],
        "",
        "Gain adaptation rate Γk of the attitude channels.",
        control.mrac.gamma_k_att
    ),
    real!(
        Mrac,
        "MRAC_GAM_TH_ATT",
        1000.0,
        [0.0, 10000.0],
        "",
        "Offset adaptation rate Γθ of the attitude channels.",
        control.mrac.gamma_theta_att
    ),
    real!(
        Mrac,
        "MRAC_GAM_K_POS",
        0.3,
        [0.0, 100.0],
        "",
        "Gain adaptation rate Γk of the position channels.",
        control.mrac.gamma_k_pos
    ),
    real!(
        Mrac,
        "MRAC_GAM_TH_POS",
        1.0,
        [0.0, 100.0],
        "",
        "Offset adaptation rate Γθ of the position channels (CA-fast: 3).",
        control.mrac.gamma_theta_pos
    ),
    flag!(
        Mrac,
        "MRAC_FREEZE_SAT",
        1.0,
        "Stop adapting a channel while its actuator saturates (0: CA-raw).",
        control.mrac.freeze_on_saturation
    ),
    // Commander.
    real!(
        Commander,
        "MIS_TAKEOFF_ALT",
        2.5,
        [0.5, 100.0],
        "m",
        "Takeoff altitude above home when the request names none.",
        commander.takeoff_alt_m
    ),
    real!(
        Navigator,
        "MPC_TKO_SPEED",
        1.0,
        [0.1, 5.0],
        "m/s",
        "Climb speed of the takeoff (the jerk-limited climb's cruise).",
        navigator.takeoff_speed_mps
    ),
    real!(
        Navigator,
        "MPC_LAND_SPEED",
        0.7,
        [0.1, 3.0],
        "m/s",
        "Descent speed of landings, down to touchdown.",
        navigator.land_speed_mps
    ),
    real!(
        Commander,
        "COM_DISARM_LAND",
        2.0,
        [-1.0, 20.0],
        "s",
        "Disarm this long after touchdown (negative: never).",
        commander.disarm_land_s
    ),
    real!(
        Commander,
        "COM_DISARM_PRFLT",
        10.0,
        [-1.0, 60.0],
        "s",
        "Disarm when armed this long without taking off (negative: never).",
        commander.disarm_preflight_s
    ),
    real!(
        Commander,
        "NAV_MC_ALT_RAD",
        0.1,
        [0.01, 10.0],
        "m",
        "The takeoff is complete within this distance of its altitude.",
        commander.takeoff_acceptance_m
    ),
    // Navigator.
    real!(
        Navigator,
        "MPC_XY_CRUISE",
        1.0,
        [0.1, 5.0],
        "m/s",
        "Horizontal cruise speed of missions, goto and return.",
        navigator.cruise_speed_mps
    ),
    real!(
        Navigator,
        "MPC_Z_VEL_MAX_UP",
        1.0,
        [0.1, 5.0],
        "m/s",
        "Largest climb speed of automatic moves (goto, missions, return).",
        navigator.climb_speed_mps
    ),
    real!(
        Navigator,
        "MPC_ACC_HOR",
        0.5,
        [0.1, 10.0],
        "m/s²",
        "Largest horizontal acceleration of automatic moves.",
        navigator.acc_hor_mps2
    ),
    real!(
        Navigator,
        "NAV_ACC_RAD",
        0.2,
        [0.05, 50.0],
        "m",
        "Waypoint acceptance radius when the item names none.",
        navigator.acceptance_radius_m
    ),
    real!(
        Navigator,
        "RTL_RETURN_ALT",
        10.0,
        [0.5, 150.0],
        "m",
        "Altitude above home to climb to before returning.",
        navigator.rtl_return_alt_m
    ),
    real!(
        Navigator,
        "COM_OF_LOSS_T",
        0.5,
        [0.1, 60.0],
        "s",
        "Offboard setpoints older than this end offboard control.",
        navigator.offboard_timeout_s
    ),
    // Telemetry: kept in the store only (no config field).
    ParamDef {
        name: "ACO_WEIGHTS_HZ",
        group: ParamGroup::Telemetry,
        kind: ParamKind::Real,
        default: 2.0,
        min: 0.0,
        max: 50.0,
        unit: "Hz",
        restart: false,
        description: "Rate of the stream of the controller's adaptive weights (0: off).",
        binding: Binding::StoreOnly,
    },
    // The automatic moves' jerk-limited trajectories (appended: indices above stay as they were).
    real!(
        Navigator,
        "MPC_Z_VEL_MAX_DN",
        1.0,
        [0.1, 5.0],
        "m/s",
        "Largest descent speed of automatic moves (goto, missions, return).",
        navigator.descent_speed_mps
    ),
    real!(
        Navigator,
        "MPC_ACC_UP_MAX",
        1.0,
        [0.1, 10.0],
        "m/s²",
        "Largest upward acceleration of automatic moves and takeoffs.",
        navigator.acc_up_mps2
    ),
    real!(
        Navigator,
        "MPC_ACC_DOWN_MAX",
        1.0,
        [0.1, 10.0],
        "m/s²",
        "Largest downward acceleration of automatic moves and landings.",
        navigator.acc_down_mps2
    ),
    real!(
        Navigator,
        "MPC_JERK_AUTO",
        1.0,
        [0.2, 50.0],
        "m/s³",
        "Jerk limit of every automatic move.",
        navigator.jerk_mps3
    ),
    // Failsafes (appended).
    real!(
        Commander,
        "COM_DL_LOSS_T",
        10.0,
        [5.0, 300.0],
        "s",
        "The ground-station link is lost after this long without a GCS HEARTBEAT.",
        commander.datalink_loss_s
    ),
    whole!(
        Commander,
        "NAV_DLL_ACT",
        0.0,
        [0.0, 5.0],
        "",
        restart = false,
        "What the vehicle does when the ground-station link is lost: 0 nothing, 1 hold, 2 return, 3 land, 5 terminate.",
        commander.datalink_loss_action
    ),
    whole!(
        Commander,
        "COM_LOW_BAT_ACT",
        3.0,
        [0.0, 3.0],
        "",
        restart = false,
        "What the vehicle does at the battery's critical and emergency levels: 0 warn only, 2 land, 3 return at critical and land at emergency (PX4's default is 0).",
        commander.low_battery_action
    ),
    real!(
        Commander,
        "BAT_LOW_THR",
        0.15,
        [0.12, 0.5],
        "norm",
        "Battery low below this state of charge: a warning, and arming is refused.",
        commander.battery.low_thr
    ),
    real!(
        Commander,
        "BAT_CRIT_THR",
        0.07,
        [0.05, 0.5],
        "norm",
        "Battery critical below this state of charge: COM_LOW_BAT_ACT's first action.",
        commander.battery.crit_thr
    ),
    real!(
        Commander,
        "BAT_EMERGEN_THR",
        0.05,
        [0.03, 0.5],
        "norm",
        "Battery emergency below this state of charge: COM_LOW_BAT_ACT's last action.",
        commander.battery.emergen_thr
    ),
    whole!(
        Commander,
        "GF_ACTION",
        2.0,
        [0.0, 5.0],
        "",
        restart = false,
        "What the vehicle does on a geofence breach (predicted from its stopping distance): 0 none, 1 warning, 2 hold, 3 return, 4 terminate, 5 land.",
        commander.geofence.action
    ),
    real!(
        Commander,
        "GF_MAX_HOR_DIST",
        0.0,
        [0.0, 10000.0],
        "m",
        "Largest horizontal distance from home (0: no limit); setpoints beyond it are refused.",
        commander.geofence.max_hor_dist_m
    ),
    real!(
        Commander,
        "GF_MAX_VER_DIST",
        0.0,
        [0.0, 10000.0],
        "m",
        "Largest height above home (0: no limit); setpoints above it are refused.",
        commander.geofence.max_ver_dist_m
    ),
    // The onboard ULog: kept in the store only, read by the shell at each arming.
    ParamDef {
        name: "SDLOG_MODE",
        group: ParamGroup::Telemetry,
        kind: ParamKind::Integer,
        default: 0.0,
        min: -1.0,
        max: 0.0,
        unit: "",
        restart: false,
        description: "When the onboard ULog flight log is written: -1 never, 0 from arming until disarming (PX4's default; PX4's other modes are not offered). Read at each arming.",
        binding: Binding::StoreOnly,
    },
    // The competent CA (docs/controller.md §4.3); all off by default, the paper's CA.
    flag!(
        Mrac,
        "MRAC_FF",
        0.0,
        "Feed the reference's velocity, acceleration and jerk through the position reference models (0: the paper's CA).",
        control.mrac.feed_forward
    ),
    real!(
        Mrac,
        "MRAC_WI_ATT",
        0.0,
        [0.0, 50.0],
        "rad/s",
        "Pole of the attitude channels' integral of the model-following error (0: none, the paper's CA).",
        control.mrac.wi_att_radps
    ),
    real!(
        Mrac,
        "MRAC_WI_POS",
        0.0,
        [0.0, 20.0],
        "rad/s",
        "Pole of the position channels' integral of the model-following error (0: none, the paper's CA).",
        control.mrac.wi_pos_radps
    ),
    real!(
        Mrac,
        "MRAC_EMOD",
        0.0,
        [0.0, 10.0],
        "",
        "e-modification σ: adaptive parameters leak toward their initial values at Γσ times the error signal s in size (0: none).",
        control.mrac.e_mod_sigma
    ),
    flag!(
        Mrac,
        "MRAC_HEDGE",
        0.0,
        "Hedge each reference model by the demand the actuators could not give (0: the paper's CA).",
        control.mrac.hedging
    ),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// Every parameter's name at its `param_index`, as ground stations have cached them: a parameter
    /// moved, removed or inserted before the end changes an index and fails here.
    const INDEX_ORDER: [&str; 91] = [
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
    ];

    #[test]
    fn given_the_table_when_listed_then_every_parameter_keeps_its_param_index() {
        let names: Vec<&str> = PARAMS.iter().map(|d| d.name).collect();
        assert_eq!(names, INDEX_ORDER);
    }
}
