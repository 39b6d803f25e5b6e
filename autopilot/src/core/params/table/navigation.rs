//! The parameter table's navigator sections: the automatic modes and their jerk-limited trajectories.

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// Navigator.
pub(super) const NAVIGATOR: &[ParamDef] = &[
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
];

/// The automatic moves' jerk-limited trajectories (appended: indices above stay as they were).
pub(super) const TRAJECTORIES: &[ParamDef] = &[
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
];
