//! The parameter table's commander sections: arming, take-off and landing, the failsafes, and the motor test.

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// Commander.
pub(super) const COMMANDER: &[ParamDef] = &[
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
];

/// Failsafes (appended).
pub(super) const FAILSAFES: &[ParamDef] = &[
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
];

/// The motor test: kept in the store only, read when a motor test is asked for.
pub(super) const MOTOR_TEST: &[ParamDef] = &[ParamDef {
    name: "COM_MOT_TEST_EN",
    group: ParamGroup::Commander,
    kind: ParamKind::Boolean,
    default: 1.0,
    min: 0.0,
    max: 1.0,
    unit: "0/1",
    restart: false,
    description: "Whether a ground station may spin a motor while disarmed (MAV_CMD_ACTUATOR_TEST, MAV_CMD_DO_MOTOR_TEST; at most 3 s per command); 0 refuses them (\"Motor test denied: disabled\").",
    binding: Binding::StoreOnly,
}];

/// Faults: failure injection (kept in the store only, read when an injection comes), the position-loss
/// failsafe's delay and the attitude failure detector.
pub(super) const FAULTS: &[ParamDef] = &[
    ParamDef {
        name: "SYS_FAILURE_EN",
        group: ParamGroup::Commander,
        kind: ParamKind::Boolean,
        default: 0.0,
        min: 0.0,
        max: 1.0,
        unit: "0/1",
        restart: false,
        description: "Whether a ground station may inject failures (MAV_CMD_INJECT_FAILURE, forwarded to the plant); 0 answers DENIED, as PX4.",
        binding: Binding::StoreOnly,
    },
    real!(
        Commander,
        "COM_POS_FS_DELAY",
        1.0,
        [0.0, 100.0],
        "s",
        "How long the estimate may have no valid position in the air, in a mode that flies to positions, before the vehicle lands (flown level, PX4's Descend).",
        commander.position_loss_delay_s
    ),
    real!(
        Commander,
        "FD_FAIL_R",
        60.0,
        [0.0, 180.0],
        "deg",
        "Attitude failure detector: roll beyond which the attitude has failed (0: off).",
        commander.failure_detector.roll_max_deg
    ),
    real!(
        Commander,
        "FD_FAIL_P",
        60.0,
        [0.0, 180.0],
        "deg",
        "Attitude failure detector: pitch beyond which the attitude has failed (0: off).",
        commander.failure_detector.pitch_max_deg
    ),
    real!(
        Commander,
        "FD_FAIL_R_TTRI",
        0.3,
        [0.02, 5.0],
        "s",
        "How long the roll must stay beyond FD_FAIL_R before the detector fires.",
        commander.failure_detector.roll_trigger_s
    ),
    real!(
        Commander,
        "FD_FAIL_P_TTRI",
        0.3,
        [0.02, 5.0],
        "s",
        "How long the pitch must stay beyond FD_FAIL_P before the detector fires.",
        commander.failure_detector.pitch_trigger_s
    ),
    whole!(
        Commander,
        "FD_ACT",
        2.0,
        [0.0, 2.0],
        "",
        restart = false,
        "What the vehicle does when the attitude failure detector fires in the air: 0 only said, 1 land, 2 terminate (motors off). PX4 chooses by CBRK_FLIGHTTERM.",
        commander.failure_detector.action
    ),
];
