//! The parameter table's manual-control sections: the radio's calibration and map (RCn_*, RC_MAP_*), the
//! pilot's input (source, loss, gestures, the mode switch, the loss failsafe) and the manual modes' stick
//! shaping and limits.

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// One channel's five calibration parameters (PX4's RCn_MIN, _MAX, _TRIM, _REV, _DZ).
macro_rules! rc_channel {
    ($n:literal, $i:literal) => {
        [
            real!(
                Radio,
                concat!("RC", $n, "_MIN"),
                1000.0,
                [800.0, 1500.0],
                "us",
                "Channel's lowest PWM (calibration).",
                manual.rc.channels[$i].min_us
            ),
            real!(
                Radio,
                concat!("RC", $n, "_MAX"),
                2000.0,
                [1500.0, 2200.0],
                "us",
                "Channel's highest PWM (calibration).",
                manual.rc.channels[$i].max_us
            ),
            real!(
                Radio,
                concat!("RC", $n, "_TRIM"),
                1500.0,
                [800.0, 2200.0],
                "us",
                "Channel's centre PWM (calibration).",
                manual.rc.channels[$i].trim_us
            ),
            real!(
                Radio,
                concat!("RC", $n, "_REV"),
                1.0,
                [-1.0, 1.0],
                "",
                "Channel direction: 1 normal, -1 reversed.",
                manual.rc.channels[$i].rev
            ),
            real!(
                Radio,
                concat!("RC", $n, "_DZ"),
                10.0,
                [0.0, 100.0],
                "us",
                "Dead zone about the centre PWM.",
                manual.rc.channels[$i].dz_us
            ),
        ]
    };
}

/// The 18 channels' calibration, channel by channel.
const fn channels() -> [ParamDef; 90] {
    let per: [[ParamDef; 5]; 18] = [
        rc_channel!(1, 0),
        rc_channel!(2, 1),
        rc_channel!(3, 2),
        rc_channel!(4, 3),
        rc_channel!(5, 4),
        rc_channel!(6, 5),
        rc_channel!(7, 6),
        rc_channel!(8, 7),
        rc_channel!(9, 8),
        rc_channel!(10, 9),
        rc_channel!(11, 10),
        rc_channel!(12, 11),
        rc_channel!(13, 12),
        rc_channel!(14, 13),
        rc_channel!(15, 14),
        rc_channel!(16, 15),
        rc_channel!(17, 16),
        rc_channel!(18, 17),
    ];
    let mut out = [per[0][0]; 90];
    let mut i = 0;
    while i < 90 {
        out[i] = per[i / 5][i % 5];
        i += 1;
    }
    out
}

static RC_CHANNELS: [ParamDef; 90] = channels();

/// The radio's channel calibration (appended).
pub(super) const RADIO_CALIBRATION: &[ParamDef] = &RC_CHANNELS;

/// A COM_FLTMODEn parameter: a PX4 mode number for one slot of the mode switch (-1 none).
macro_rules! fltmode {
    ($n:literal, $i:literal) => {
        ParamDef {
            name: concat!("COM_FLTMODE", $n),
            group: ParamGroup::Radio,
            kind: ParamKind::Integer,
            default: -1.0,
            min: -1.0,
            max: 11.0,
            unit: "",
            restart: false,
            description: concat!(
                "Mode of the mode switch's slot ",
                $n,
                ": -1 none, 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold, 5 Return, 6 Acro, 7 Offboard, 8 Stabilized, 10 Takeoff, 11 Land."
            ),
            binding: Binding::Config {
                get: |c| f64::from(c.manual.fltmodes[$i]),
                set: |c, v| c.manual.fltmodes[$i] = v as i32,
            },
        }
    };
}

/// The radio's map and the pilot's input (appended).
pub(super) const RADIO: &[ParamDef] = &[
    whole!(
        Radio,
        "RC_MAP_ROLL",
        1.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the roll stick (0 none).",
        manual.rc.map.roll
    ),
    whole!(
        Radio,
        "RC_MAP_PITCH",
        2.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the pitch stick (0 none).",
        manual.rc.map.pitch
    ),
    whole!(
        Radio,
        "RC_MAP_YAW",
        4.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the yaw stick (0 none).",
        manual.rc.map.yaw
    ),
    whole!(
        Radio,
        "RC_MAP_THROTTLE",
        3.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the throttle stick (0 none).",
        manual.rc.map.throttle
    ),
    whole!(
        Radio,
        "RC_MAP_FLTMODE",
        0.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the six-slot mode switch (0 none).",
        manual.rc.map.fltmode
    ),
    whole!(
        Radio,
        "RC_MAP_KILL_SW",
        0.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the kill switch (0 none): on stops the motors at once.",
        manual.rc.map.kill_sw
    ),
    whole!(
        Radio,
        "RC_MAP_ARM_SW",
        0.0,
        [0.0, 18.0],
        "",
        restart = false,
        "Channel of the arm switch (0 none); mapped, it turns the arming gesture off.",
        manual.rc.map.arm_sw
    ),
    whole!(
        Radio,
        "COM_RC_IN_MODE",
        3.0,
        [0.0, 4.0],
        "",
        restart = false,
        "Manual control source: 0 radio only, 1 joystick (MANUAL_CONTROL) only, 2 either with fallback, 3 the first seen, kept, 4 none.",
        manual.in_mode
    ),
    real!(
        Radio,
        "COM_RC_LOSS_T",
        0.5,
        [0.1, 35.0],
        "s",
        "Manual control is lost after this long without input.",
        manual.loss_s
    ),
    real!(
        Radio,
        "COM_RC_ARM_HYST",
        1.0,
        [0.1, 5.0],
        "s",
        "How long an arming or disarming stick gesture is held.",
        manual.arm_hyst_s
    ),
    flag!(
        Radio,
        "MAN_ARM_GESTURE",
        1.0,
        "Arm with throttle low and yaw right, disarm (landed) with throttle low and yaw left, in manual modes.",
        manual.arm_gesture
    ),
    fltmode!("1", 0),
    fltmode!("2", 1),
    fltmode!("3", 2),
    fltmode!("4", 3),
    fltmode!("5", 4),
    fltmode!("6", 5),
    whole!(
        Radio,
        "NAV_RCL_ACT",
        2.0,
        [0.0, 5.0],
        "",
        restart = false,
        "What the vehicle does when manual control is lost in the air: 0 nothing, 1 hold, 2 return, 3 land, 5 terminate.",
        commander.rc_loss_action
    ),
    whole!(
        Radio,
        "COM_RCL_EXCEPT",
        0.0,
        [0.0, 7.0],
        "",
        restart = false,
        "Modes where manual-control loss is ignored (bits): 1 mission, 2 hold, 4 offboard.",
        commander.rc_loss_except
    ),
];

/// The manual modes' stick shaping and limits (appended).
pub(super) const MANUAL_FLIGHT: &[ParamDef] = &[
    real!(
        Navigator,
        "MPC_MAN_TILT_MAX",
        20.0,
        [1.0, 28.0],
        "deg",
        "Largest tilt the sticks ask for in Stabilized and Altitude (at most the controllers' 0.5 rad).",
        navigator.manual.tilt_max_deg
    ),
    real!(
        Navigator,
        "MPC_MAN_Y_MAX",
        60.0,
        [1.0, 85.0],
        "deg/s",
        "Yaw rate at full yaw stick.",
        navigator.manual.yaw_rate_max_degps
    ),
    real!(
        Navigator,
        "MPC_MANTHR_MIN",
        0.08,
        [0.0, 0.4],
        "norm",
        "Thrust at throttle stick 0 in Stabilized.",
        navigator.manual.thr_min
    ),
    real!(
        Navigator,
        "MPC_THR_HOVER",
        0.46,
        [0.1, 0.8],
        "norm",
        "Thrust at throttle stick centre in Stabilized (the nominal airframe hovers at 0.461).",
        navigator.manual.thr_hover
    ),
    real!(
        Navigator,
        "MPC_VEL_MANUAL",
        2.0,
        [0.1, 3.0],
        "m/s",
        "Horizontal speed at full stick in Position (at most ACO_VEL_MAX_NE's default).",
        navigator.manual.vel_manual_mps
    ),
    real!(
        Navigator,
        "MPC_ACC_HOR_MAX",
        2.0,
        [0.1, 5.0],
        "m/s²",
        "Horizontal acceleration limit of Position's stick velocity.",
        navigator.manual.acc_hor_max_mps2
    ),
    real!(
        Navigator,
        "MPC_JERK_MAX",
        4.0,
        [0.5, 50.0],
        "m/s³",
        "Jerk limit of the manual modes' velocity changes.",
        navigator.manual.jerk_max_mps3
    ),
    real!(
        Navigator,
        "MPC_HOLD_DZ",
        0.1,
        [0.0, 0.5],
        "norm",
        "Stick dead zone about centre (hold).",
        navigator.manual.hold_dz
    ),
    real!(
        Navigator,
        "MPC_XY_MAN_EXPO",
        0.6,
        [0.0, 0.99],
        "norm",
        "Expo of the roll and pitch sticks in Position.",
        navigator.manual.xy_expo
    ),
    real!(
        Navigator,
        "MPC_Z_MAN_EXPO",
        0.6,
        [0.0, 0.99],
        "norm",
        "Expo of the throttle stick in Altitude and Position.",
        navigator.manual.z_expo
    ),
    real!(Navigator, "MPC_YAW_EXPO", 0.6, [0.0, 0.99], "norm", "Expo of the yaw stick.", navigator.manual.yaw_expo),
];

/// Acro's stick rates and expo (appended).
pub(super) const ACRO: &[ParamDef] = &[
    real!(
        Navigator,
        "MC_ACRO_R_MAX",
        180.0,
        [10.0, 200.0],
        "deg/s",
        "Acro: roll rate at full roll stick (at most the controllers' 3.5 rad/s rate limit).",
        navigator.manual.acro_roll_max_degps
    ),
    real!(
        Navigator,
        "MC_ACRO_P_MAX",
        180.0,
        [10.0, 200.0],
        "deg/s",
        "Acro: pitch rate at full pitch stick (at most the controllers' 3.5 rad/s rate limit).",
        navigator.manual.acro_pitch_max_degps
    ),
    real!(
        Navigator,
        "MC_ACRO_Y_MAX",
        80.0,
        [10.0, 85.0],
        "deg/s",
        "Acro: yaw rate at full yaw stick (at most the controllers' 1.5 rad/s yaw rate limit).",
        navigator.manual.acro_yaw_max_degps
    ),
    real!(
        Navigator,
        "MC_ACRO_EXPO",
        0.69,
        [0.0, 0.99],
        "",
        "Acro: expo of the roll and pitch sticks, (1 - e) x + e x³ (PX4's super-expo is not applied).",
        navigator.manual.acro_expo
    ),
    real!(
        Navigator,
        "MC_ACRO_EXPO_Y",
        0.69,
        [0.0, 0.99],
        "",
        "Acro: expo of the yaw stick.",
        navigator.manual.acro_yaw_expo
    ),
];
