//! Parameters by name from Python: SIM_ parameters go to the plant's SIM_ service, as a ground station's
//! PARAM_SET on the SIM_ port would; controller parameters (the vehicle's table, e.g. `ACO_KP_ETA`,
//! `MPC_XY_P`) are checked against their declared range and applied to the run's controller
//! configuration. Anything else is refused, and a refused value changes nothing.

use autopilot::core::config::VehicleConfig;
use autopilot::core::control::ControllerConfig;
use autopilot::core::params::{Binding, PARAMS};
use pyo3::exceptions::{PyKeyError, PyValueError};
use pyo3::prelude::*;

/// `config` with the controller parameter `name` set to `value`.
///
/// # Errors
/// `KeyError` for a name the vehicle's table does not have; `ValueError` for a value out of its range or a
/// parameter that does not set the controller configuration (a navigator or commander parameter).
pub(crate) fn with_controller_param(config: &ControllerConfig, name: &str, value: f64) -> PyResult<ControllerConfig> {
    let def = PARAMS.iter().find(|d| d.name == name).ok_or_else(|| {
        PyKeyError::new_err(format!(
            "no parameter `{name}`: SIM_ parameters and the vehicle's controller parameters (docs/parameters.md) \
             can be set"
        ))
    })?;
    def.check(value as f32).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let Binding::Config { set, .. } = def.binding else {
        return Err(PyValueError::new_err(format!("{name} is held by the vehicle only; it sets no controller value")));
    };
    let before = VehicleConfig { control: config.clone(), ..VehicleConfig::default() };
    let mut after = before.clone();
    set(&mut after, value);
    let mut rest = after.clone();
    rest.control = before.control.clone();
    if rest != before {
        return Err(PyValueError::new_err(format!(
            "{name} is not a controller parameter (it sets the vehicle's {}); only SIM_ and controller parameters \
             apply to a lockstep run",
            def.group.title()
        )));
    }
    after.control.validate().map_err(|e| PyValueError::new_err(format!("{name} = {value}: {e}")))?;
    Ok(after.control)
}
