//! Python controllers in the lockstep runner: a callable `(input, reference) -> action` flown as a
//! [`Controller`], its action four PWM commands (µs) or collective thrust plus body rates (`ctbr`) through
//! a registered controller's rate loop; and the read-only `Input` and `Reference` it is called with.

use std::sync::{Arc, Mutex};

use autopilot::core::control::{
    Airframe, ControlInput, Controller, ControllerConfig, ControllerKind, ControllerType, HeldOutput, Reference,
    try_new_controller,
};
use nalgebra::Vector3;
use numpy::PyArray1;
use pyo3::exceptions::{PyKeyError, PyValueError};
use pyo3::prelude::*;

/// What a Python controller returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Action {
    /// Four rotor PWM commands (µs, rotors 1 right, 2 rear, 3 front, 4 left); the plant clamps them to
    /// 1000-2000 µs.
    Pwm,
    /// [collective thrust 0-1, p, q, r (FRD rad/s)], flown by the rate loop of a controller that has one;
    /// the collective is clipped to 0-1.
    Ctbr,
}

impl Action {
    pub(crate) fn parse(text: &str) -> PyResult<Self> {
        match text {
            "pwm" => Ok(Self::Pwm),
            "ctbr" => Ok(Self::Ctbr),
            other => Err(PyValueError::new_err(format!("action `{other}` is not one of: pwm, ctbr"))),
        }
    }
}

/// The error a Python controller raised (or caused), kept for the caller to raise once the tick ends.
pub(crate) type ErrorSlot = Arc<Mutex<Option<PyErr>>>;

/// The controller's view of the vehicle at one tick (NED/FRD, SI units), as numpy arrays.
#[pyclass(frozen, module = "aco_sim._native", name = "ControlInput")]
pub(crate) struct Input {
    /// Simulated time of the tick (s).
    #[pyo3(get)]
    t_s: f64,
    pos_ned_m: [f64; 3],
    vel_ned_mps: [f64; 3],
    euler_rad: [f64; 3],
    rate_frd_radps: [f64; 3],
    specific_force_frd_mps2: [f64; 3],
}

#[pymethods]
impl Input {
    #[getter]
    fn pos_ned_m<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.pos_ned_m)
    }
    #[getter]
    fn vel_ned_mps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.vel_ned_mps)
    }
    /// (roll, pitch, yaw), ZYX.
    #[getter]
    fn euler_rad<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.euler_rad)
    }
    #[getter]
    fn rate_frd_radps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.rate_frd_radps)
    }
    #[getter]
    fn specific_force_frd_mps2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.specific_force_frd_mps2)
    }
    fn __repr__(&self) -> String {
        format!("ControlInput(t_s={}, pos_ned_m={:?}, euler_rad={:?})", self.t_s, self.pos_ned_m, self.euler_rad)
    }
}

/// What the vehicle is asked to do at one tick, as numpy arrays (None for what the reference leaves unset).
#[pyclass(frozen, module = "aco_sim._native", name = "Reference")]
pub(crate) struct Ref {
    pos_ned_m: [f64; 3],
    vel_ned_mps: [f64; 3],
    acc_ned_mps2: [f64; 3],
    jerk_ned_mps3: [f64; 3],
    #[pyo3(get)]
    yaw_rad: f64,
    attitude_rad: Option<[f64; 3]>,
    /// Normalized collective thrust 0-1, when the reference sets one.
    #[pyo3(get)]
    collective_frac: Option<f64>,
    rate_frd_radps: Option<[f64; 3]>,
}

#[pymethods]
impl Ref {
    #[getter]
    fn pos_ned_m<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.pos_ned_m)
    }
    #[getter]
    fn vel_ned_mps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.vel_ned_mps)
    }
    #[getter]
    fn acc_ned_mps2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.acc_ned_mps2)
    }
    #[getter]
    fn jerk_ned_mps3<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.jerk_ned_mps3)
    }
    /// The attitude setpoint (roll, pitch, yaw) of an attitude reference, else None.
    #[getter]
    fn attitude_rad<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.attitude_rad.map(|a| PyArray1::from_slice(py, &a))
    }
    /// Body rates (FRD rad/s) of a rate reference, else None.
    #[getter]
    fn rate_frd_radps<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.rate_frd_radps.map(|a| PyArray1::from_slice(py, &a))
    }
    fn __repr__(&self) -> String {
        format!("Reference(pos_ned_m={:?}, yaw_rad={})", self.pos_ned_m, self.yaw_rad)
    }
}

impl Ref {
    pub(crate) fn of(r: &Reference) -> Self {
        Self {
            pos_ned_m: r.pos_ned_m.into(),
            vel_ned_mps: r.vel_ned_mps.into(),
            acc_ned_mps2: r.acc_ned_mps2.into(),
            jerk_ned_mps3: r.jerk_ned_mps3.into(),
            yaw_rad: r.yaw_rad,
            attitude_rad: r.attitude_rad.map(Into::into),
            collective_frac: r.collective_frac,
            rate_frd_radps: r.rate_frd_radps.map(Into::into),
        }
    }
}

impl Input {
    pub(crate) fn of(t_s: f64, i: &ControlInput) -> Self {
        Self {
            t_s,
            pos_ned_m: i.pos_ned_m.into(),
            vel_ned_mps: i.vel_ned_mps.into(),
            euler_rad: i.euler_rad.into(),
            rate_frd_radps: i.rate_frd_radps.into(),
            specific_force_frd_mps2: i.specific_force_frd_mps2.into(),
        }
    }
}

/// The type every Python controller reports as its kind (metrics say `python`); it is not registered,
/// so no name builds one: a Python controller is built from its callable.
struct PythonType;

impl ControllerType for PythonType {
    fn name(&self) -> &'static str {
        "python"
    }
    fn summary(&self) -> &'static str {
        "a Python callable (input, reference) -> action, flown by aco_sim"
    }
    fn default_table(&self) -> toml::Table {
        toml::Table::new()
    }
    fn validate(&self, _config: &ControllerConfig) -> Result<(), autopilot::core::control::ConfigError> {
        Ok(())
    }
    fn build(&self, _config: &ControllerConfig) -> Result<Box<dyn Controller>, autopilot::core::control::ConfigError> {
        Err(autopilot::core::control::ConfigError::Table {
            table: "python".into(),
            message: "a Python controller is built from its callable (aco_sim.run_scenario(..., controller=fn))".into(),
        })
    }
}

static PYTHON: PythonType = PythonType;

/// A Python callable flown as a controller.
pub(crate) struct PyController {
    callable: Py<PyAny>,
    action: Action,
    /// The rate loop that flies a `ctbr` action.
    rate_loop: Option<Box<dyn Controller>>,
    held: HeldOutput,
    dt_s: f64,
    tick: u64,
    error: ErrorSlot,
}

impl PyController {
    /// A controller calling `callable` each tick. A `ctbr` action needs `rate_controller`, a registered
    /// controller with a rate loop, built from `config`.
    pub(crate) fn new(
        callable: Py<PyAny>,
        action: Action,
        rate_controller: &str,
        config: &ControllerConfig,
        error: ErrorSlot,
    ) -> PyResult<Self> {
        let rate_loop = match action {
            Action::Pwm => None,
            Action::Ctbr => {
                let kind: ControllerKind =
                    rate_controller.parse().map_err(|e: autopilot::core::control::ParseControllerKindError| {
                        PyKeyError::new_err(e.to_string())
                    })?;
                if !kind.flies_rates() {
                    return Err(PyValueError::new_err(format!(
                        "the ctbr action needs a rate loop, and controller {kind} has none"
                    )));
                }
                Some(try_new_controller(kind, config).map_err(|e| PyValueError::new_err(e.to_string()))?)
            }
        };
        Ok(Self {
            callable,
            action,
            rate_loop,
            held: HeldOutput::hover(&Airframe::default()),
            dt_s: config.rates.inner_dt_s(),
            tick: 0,
            error,
        })
    }

    /// The callable's action at this tick, checked: four finite numbers.
    fn call(&self, py: Python<'_>, t_s: f64, input: &ControlInput, reference: &Reference) -> PyResult<[f64; 4]> {
        let out = self.callable.call1(py, (Input::of(t_s, input), Ref::of(reference)))?;
        let values: Vec<f64> = out.extract(py).map_err(|_| {
            PyValueError::new_err(format!(
                "the controller returned {} at t = {t_s} s; expected a sequence of 4 numbers",
                out.bind(py).get_type().name().map_or_else(|_| "?".into(), |n| n.to_string())
            ))
        })?;
        let what = match self.action {
            Action::Pwm => "pwm_us",
            Action::Ctbr => "[collective, p, q, r]",
        };
        let action: [f64; 4] = values.as_slice().try_into().map_err(|_| {
            PyValueError::new_err(format!(
                "the controller returned {} values at t = {t_s} s; expected 4 ({what})",
                values.len()
            ))
        })?;
        if let Some(i) = action.iter().position(|v| !v.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "the controller returned {} in component {i} at t = {t_s} s: actions must be finite",
                action[i]
            )));
        }
        Ok(action)
    }
}

impl Controller for PyController {
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4] {
        let t_s = self.tick as f64 * self.dt_s;
        self.tick += 1;
        let mut slot = self.error.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if slot.is_some() {
            return self.held.pwm_us;
        }
        match Python::attach(|py| self.call(py, t_s, input, reference)) {
            Ok(action) => match (self.action, self.rate_loop.as_mut()) {
                (Action::Ctbr, Some(rate_loop)) => {
                    let rates = Reference::rates(
                        Vector3::new(action[1], action[2], action[3]),
                        action[0].clamp(0.0, 1.0),
                        reference.yaw_rad,
                    );
                    self.held.pwm_us = rate_loop.update(input, &rates);
                }
                _ => self.held.pwm_us = action,
            },
            Err(e) => *slot = Some(e),
        }
        self.held.pwm_us
    }

    fn reconfigure(&mut self, config: &ControllerConfig) {
        if let Some(rate_loop) = self.rate_loop.as_mut() {
            rate_loop.reconfigure(config);
        }
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::of(&PYTHON)
    }

    fn telemetry(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }

    fn weights_at_bounds(&self) -> bool {
        self.rate_loop.as_ref().is_some_and(|c| c.weights_at_bounds())
    }

    fn attitude_setpoint_rad(&self) -> Vector3<f64> {
        Vector3::zeros()
    }
}
