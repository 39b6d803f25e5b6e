//! The vehicle's configuration: everything a [`crate::core::vehicle::Vehicle`] is built from (the
//! controller and its gains, the estimator, the commander's and the navigator's parameters, the system
//! id, an airborne start), as the TOML `[vehicle]` table and the parameter table describe it. In: values
//! from a file, the defaults or the parameters. Out: [`VehicleConfig::validate`], which checks every part,
//! loop rates and cross-field rules included, so a value is refused when it is set, never first found bad
//! at a restart.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::core::commander::{self, CommanderConfig};
use crate::core::control::{self, ControllerConfig, ControllerKind};
use crate::core::estimator::{self, EstimatorConfig};
use crate::core::manual::{ManualConfig, input::ManualConfigError};
use crate::core::navigator::{self, NavigatorConfig};

/// Everything the vehicle is built from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleConfig {
    /// MAVLink system id (N+1 for instance N).
    pub sysid: u8,
    pub controller: ControllerKind,
    pub control: ControllerConfig,
    pub estimator: EstimatorConfig,
    pub commander: CommanderConfig,
    pub navigator: NavigatorConfig,
    /// The pilot's input: the radio's map and calibration, the source, loss, gestures, the mode switch.
    pub manual: ManualConfig,
    /// Start armed and holding a point instead of disarmed on the ground (experiments that begin in the
    /// air, as the paper's do: `sitl run --scenario`); home is then the ground below that point.
    pub start_airborne: Option<AirborneStart>,
}

/// Where an airborne start holds (NED m about the estimator's origin, yaw rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AirborneStart {
    pub hold_ned_m: [f64; 3],
    #[serde(default)]
    pub yaw_rad: f64,
}

impl Default for VehicleConfig {
    fn default() -> Self {
        Self {
            sysid: 1,
            controller: ControllerKind::ACO,
            control: ControllerConfig::default(),
            estimator: EstimatorConfig::default(),
            commander: CommanderConfig::default(),
            navigator: NavigatorConfig::default(),
            manual: ManualConfig::default(),
            start_airborne: None,
        }
    }
}

/// Why a [`VehicleConfig`] is unusable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VehicleError {
    #[error("vehicle config: sysid must be 1..=255")]
    Sysid,
    #[error("vehicle config: start_airborne hold_ned_m and yaw_rad must be finite")]
    StartAirborne,
    #[error(transparent)]
    Controller(#[from] control::ConfigError),
    #[error(transparent)]
    Estimator(#[from] estimator::ConfigError),
    #[error(transparent)]
    Commander(#[from] commander::ConfigError),
    #[error(transparent)]
    Navigator(#[from] navigator::ConfigError),
    #[error(transparent)]
    Manual(#[from] ManualConfigError),
}

impl VehicleConfig {
    /// Checks every part of the configuration.
    ///
    /// # Errors
    /// [`VehicleError`] naming the first unusable part.
    pub fn validate(&self) -> Result<(), VehicleError> {
        if self.sysid == 0 {
            return Err(VehicleError::Sysid);
        }
        self.control.validate()?;
        self.estimator.validate()?;
        self.commander.validate()?;
        self.navigator.validate()?;
        self.manual.validate()?;
        if let Some(start) = self.start_airborne
            && !(start.hold_ned_m.iter().all(|x| x.is_finite()) && start.yaw_rad.is_finite())
        {
            return Err(VehicleError::StartAirborne);
        }
        Ok(())
    }
}
