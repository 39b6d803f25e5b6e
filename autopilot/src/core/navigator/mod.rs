//! The navigator: what the vehicle flies in the automatic modes. In: the commander's auto state, the
//! estimate, home, the mission and the latest offboard setpoint. Out: a position reference with velocity
//! and acceleration feed-forward for the controller.

use serde::{Deserialize, Serialize};

/// The navigator's parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NavigatorConfig {
    /// Horizontal cruise speed of missions, goto and return (m/s; MPC_XY_CRUISE).
    pub cruise_speed_mps: f64,
    /// Vertical speed of altitude changes between items (m/s; MPC_Z_VEL_MAX_UP).
    pub climb_speed_mps: f64,
    /// Acceleration of the path's speed profile (m/s²; MPC_ACC_HOR).
    pub accel_mps2: f64,
    /// Waypoint acceptance radius when the item names none (m; NAV_ACC_RAD).
    pub acceptance_radius_m: f64,
    /// Altitude above home to climb to before returning (m; RTL_RETURN_ALT).
    pub rtl_return_alt_m: f64,
    /// Offboard setpoints older than this end offboard control (s; COM_OF_LOSS_T).
    pub offboard_timeout_s: f64,
}

impl Default for NavigatorConfig {
    fn default() -> Self {
        Self {
            cruise_speed_mps: 1.0,
            climb_speed_mps: 1.0,
            accel_mps2: 1.0,
            acceptance_radius_m: 0.2,
            rtl_return_alt_m: 3.0,
            offboard_timeout_s: 0.5,
        }
    }
}
