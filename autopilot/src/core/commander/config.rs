//! The commander's parameters (PX4 names in the field docs) and their validation: every value is checked
//! when it is set, so a configuration that would not fly is refused with the field that stops it.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::failsafe::{self, FailsafeAction};
use super::failure_detector::FailureDetectorConfig;
use super::land_detector::LandDetectorConfig;
use crate::core::battery::{BatteryConfig, BatteryWarning};
use crate::core::plan::geofence::GeofenceConfig;

/// The commander's parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommanderConfig {
    /// Takeoff altitude above home when the request names none (m; MIS_TAKEOFF_ALT).
    pub takeoff_alt_m: f64,
    /// Disarm this long after touchdown (s; COM_DISARM_LAND; negative: never).
    pub disarm_land_s: f64,
    /// Disarm when armed this long without taking off (s; COM_DISARM_PRFLT; negative: never).
    pub disarm_preflight_s: f64,
    /// The takeoff is complete within this distance of its altitude (m).
    pub takeoff_acceptance_m: f64,
    /// The ground-station link is lost after this long without a GCS HEARTBEAT (s; COM_DL_LOSS_T).
    pub datalink_loss_s: f64,
    /// What the vehicle does when it is (PX4's NAV_DLL_ACT: 0 nothing, 1 hold, 2 return, 3 land, 5
    /// terminate; see [`FailsafeAction::from_px4`]).
    pub datalink_loss_action: u32,
    /// What the vehicle does when manual control is lost (PX4's NAV_RCL_ACT: 0 nothing, 1 hold, 2 return,
    /// 3 land, 5 terminate).
    pub rc_loss_action: u32,
    /// The modes manual-control loss leaves alone (PX4's COM_RCL_EXCEPT bits: 1 mission, 2 hold, 4
    /// offboard).
    pub rc_loss_except: u32,
    /// What the vehicle does at the battery's critical and emergency levels (PX4's COM_LOW_BAT_ACT: 0
    /// warn only, 2 land, 3 return at critical and land at emergency; see
    /// [`failsafe::low_battery_action`]).
    pub low_battery_action: u32,
    /// The battery thresholds (BAT_LOW_THR, BAT_CRIT_THR, BAT_EMERGEN_THR).
    pub battery: BatteryConfig,
    /// The geofence's action and distance limits (GF_ACTION, GF_MAX_HOR_DIST, GF_MAX_VER_DIST).
    pub geofence: GeofenceConfig,
    pub land_detector: LandDetectorConfig,
    /// How long the estimate may have no valid position in the air before the vehicle lands (s;
    /// COM_POS_FS_DELAY).
    pub position_loss_delay_s: f64,
    /// The attitude failure detector (FD_FAIL_R, FD_FAIL_P, FD_FAIL_R_TTRI, FD_FAIL_P_TTRI, FD_ACT).
    pub failure_detector: FailureDetectorConfig,
}

impl Default for CommanderConfig {
    fn default() -> Self {
        Self {
            takeoff_alt_m: 2.5,
            disarm_land_s: 2.0,
            disarm_preflight_s: 10.0,
            takeoff_acceptance_m: 0.1,
            datalink_loss_s: 10.0,
            datalink_loss_action: 0,
            rc_loss_action: 2,
            rc_loss_except: 0,
            low_battery_action: 3,
            battery: BatteryConfig::default(),
            geofence: GeofenceConfig::default(),
            land_detector: LandDetectorConfig::default(),
            position_loss_delay_s: 1.0,
            failure_detector: FailureDetectorConfig::default(),
        }
    }
}

/// The rule the battery thresholds follow.
pub(super) const BATTERY_ORDER: &str = "0 < BAT_EMERGEN_THR < BAT_CRIT_THR < BAT_LOW_THR < 1";

/// A configuration value out of range.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("commander config: {field} = {value} must be {must}")]
pub struct ConfigError {
    pub field: &'static str,
    pub value: f64,
    pub must: &'static str,
}

impl CommanderConfig {
    /// # Errors
    /// [`ConfigError`] naming the first field out of range (non-finite, or not positive where it must be).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let ld = &self.land_detector;
        let positive = [
            ("takeoff_alt_m", self.takeoff_alt_m),
            ("takeoff_acceptance_m", self.takeoff_acceptance_m),
            ("datalink_loss_s", self.datalink_loss_s),
            ("land_detector.max_vel_d_mps", ld.max_vel_d_mps),
            ("land_detector.max_vel_ne_mps", ld.max_vel_ne_mps),
            ("land_detector.ground_height_m", ld.ground_height_m),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError { field, value, must: "finite and positive" });
            }
        }
        let finite = [
            ("disarm_land_s", self.disarm_land_s),
            ("disarm_preflight_s", self.disarm_preflight_s),
            ("land_detector.dwell_s", ld.dwell_s),
        ];
        for (field, value) in finite {
            if !value.is_finite() {
                return Err(ConfigError { field, value, must: "finite" });
            }
        }
        if self.battery.validate().is_err() {
            return Err(ConfigError { field: "battery", value: self.battery.low_thr, must: BATTERY_ORDER });
        }
        if failsafe::low_battery_action(self.low_battery_action, BatteryWarning::Emergency).is_err() {
            return Err(ConfigError {
                field: "low_battery_action",
                value: f64::from(self.low_battery_action),
                must: "0 (warn), 2 land or 3 return then land",
            });
        }
        let gf = &self.geofence;
        for (field, value) in
            [("geofence.max_hor_dist_m", gf.max_hor_dist_m), ("geofence.max_ver_dist_m", gf.max_ver_dist_m)]
        {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConfigError { field, value, must: "finite and >= 0 (0: no limit)" });
            }
        }
        if failsafe::geofence_action(gf.action).is_err() {
            return Err(ConfigError {
                field: "geofence.action",
                value: f64::from(gf.action),
                must: "0 none, 1 warning, 2 hold, 3 return, 4 terminate or 5 land",
            });
        }
        if let Err(n) = FailsafeAction::from_px4(self.datalink_loss_action) {
            return Err(ConfigError {
                field: "datalink_loss_action",
                value: f64::from(n),
                must: "0 (off), 1 hold, 2 return, 3 land or 5 terminate",
            });
        }
        if let Err(n) = FailsafeAction::from_px4(self.rc_loss_action) {
            return Err(ConfigError {
                field: "rc_loss_action",
                value: f64::from(n),
                must: "0 (off), 1 hold, 2 return, 3 land or 5 terminate",
            });
        }
        let fd = &self.failure_detector;
        for (field, value, lo, hi, must) in [
            ("position_loss_delay_s", self.position_loss_delay_s, 0.0, 100.0, "in 0..100 s"),
            ("failure_detector.roll_max_deg", fd.roll_max_deg, 0.0, 180.0, "in 0..180 deg (0: off)"),
            ("failure_detector.pitch_max_deg", fd.pitch_max_deg, 0.0, 180.0, "in 0..180 deg (0: off)"),
            ("failure_detector.roll_trigger_s", fd.roll_trigger_s, 0.02, 5.0, "in 0.02..5 s"),
            ("failure_detector.pitch_trigger_s", fd.pitch_trigger_s, 0.02, 5.0, "in 0.02..5 s"),
        ] {
            if !(value.is_finite() && (lo..=hi).contains(&value)) {
                return Err(ConfigError { field, value, must });
            }
        }
        if failsafe::attitude_failure_action(fd.action).is_err() {
            return Err(ConfigError {
                field: "failure_detector.action",
                value: f64::from(fd.action),
                must: "0 (only said), 1 land or 2 terminate",
            });
        }
        if self.rc_loss_except > 7 {
            return Err(ConfigError {
                field: "rc_loss_except",
                value: f64::from(self.rc_loss_except),
                must: "a sum of 1 (mission), 2 (hold), 4 (offboard)",
            });
        }
        Ok(())
    }
}
