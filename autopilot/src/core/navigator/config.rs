//! The navigator's parameters (PX4's MPC_*, NAV_*, RTL_* and COM_OF_LOSS_T names in the field docs) and
//! their validation.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The navigator's parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NavigatorConfig {
    /// Horizontal cruise speed of missions, goto and return (m/s; MPC_XY_CRUISE).
    pub cruise_speed_mps: f64,
    /// Largest climb speed of automatic moves (m/s; MPC_Z_VEL_MAX_UP).
    pub climb_speed_mps: f64,
    /// Largest descent speed of automatic moves (m/s; MPC_Z_VEL_MAX_DN).
    pub descent_speed_mps: f64,
    /// Climb speed of takeoffs (m/s; MPC_TKO_SPEED).
    pub takeoff_speed_mps: f64,
    /// Descent speed of landings (m/s; MPC_LAND_SPEED).
    pub land_speed_mps: f64,
    /// Horizontal acceleration limit (m/s²; MPC_ACC_HOR).
    pub acc_hor_mps2: f64,
    /// Upward acceleration limit (m/s²; MPC_ACC_UP_MAX).
    pub acc_up_mps2: f64,
    /// Downward acceleration limit (m/s²; MPC_ACC_DOWN_MAX).
    pub acc_down_mps2: f64,
    /// Jerk limit of every automatic move (m/s³; MPC_JERK_AUTO).
    pub jerk_mps3: f64,
    /// Waypoint acceptance radius when the item names none (m; NAV_ACC_RAD).
    pub acceptance_radius_m: f64,
    /// Altitude above home to climb to before returning (m; RTL_RETURN_ALT).
    pub rtl_return_alt_m: f64,
    /// Offboard setpoints older than this end offboard control (s; COM_OF_LOSS_T).
    pub offboard_timeout_s: f64,
    /// How far below the ground the landing reference goes (m): bounds the push into the ground.
    pub land_below_ground_m: f64,
    /// The manual modes' stick shaping and limits (MPC_MAN_*, MPC_VEL_MANUAL, ...).
    pub manual: super::ManualFlightConfig,
}

impl Default for NavigatorConfig {
    fn default() -> Self {
        Self {
            cruise_speed_mps: 1.0,
            climb_speed_mps: 1.0,
            descent_speed_mps: 1.0,
            takeoff_speed_mps: 1.0,
            land_speed_mps: 0.7,
            acc_hor_mps2: 0.5,
            acc_up_mps2: 1.0,
            acc_down_mps2: 1.0,
            jerk_mps3: 1.0,
            acceptance_radius_m: 0.2,
            rtl_return_alt_m: 10.0,
            offboard_timeout_s: 0.5,
            land_below_ground_m: 0.5,
            manual: super::ManualFlightConfig::default(),
        }
    }
}

/// A navigator parameter out of range.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("navigator config: {field} = {value} must be finite and {must}")]
pub struct ConfigError {
    pub field: &'static str,
    pub value: f64,
    pub must: &'static str,
}

impl NavigatorConfig {
    /// # Errors
    /// [`ConfigError`] naming the first field that is not finite and positive (non-negative for the
    /// return altitude and the offboard timeout).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = [
            ("cruise_speed_mps", self.cruise_speed_mps),
            ("climb_speed_mps", self.climb_speed_mps),
            ("descent_speed_mps", self.descent_speed_mps),
            ("takeoff_speed_mps", self.takeoff_speed_mps),
            ("land_speed_mps", self.land_speed_mps),
            ("acc_hor_mps2", self.acc_hor_mps2),
            ("acc_up_mps2", self.acc_up_mps2),
            ("acc_down_mps2", self.acc_down_mps2),
            ("jerk_mps3", self.jerk_mps3),
            ("acceptance_radius_m", self.acceptance_radius_m),
            ("land_below_ground_m", self.land_below_ground_m),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError { field, value, must: "positive" });
            }
        }
        for (field, value) in
            [("rtl_return_alt_m", self.rtl_return_alt_m), ("offboard_timeout_s", self.offboard_timeout_s)]
        {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConfigError { field, value, must: "not negative" });
            }
        }
        if let Some((field, value, must)) = self.manual.invalid() {
            return Err(ConfigError { field, value, must });
        }
        Ok(())
    }
}
