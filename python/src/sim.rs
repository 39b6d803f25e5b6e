//! `Sim`: one lockstep run of a scenario (the runner `sitl scenario` uses), stepped from Python tick by
//! tick or run to its end, with its state, metrics and trace as numpy; and the sweep with a Python
//! controller.

use std::sync::{Arc, Mutex};

use autopilot::core::control::{ControllerKind, LoopRates, ParseControllerKindError};
use numpy::PyArray1;
use pyo3::exceptions::{PyKeyError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sitl::scenario::runner::{RunOptions, RunOutput, Runner, Trace};
use sitl::scenario::{ReferenceMode, Scenario};
use sitl::sim_params::SIM_PARAMS;
use sitl::sweep::Sweep;

use crate::control::{Action, ErrorSlot, PyController};
use crate::{guard, load_scenario, params};

/// Loop rates from the CLI's options: position rate default inner / 5.
fn loop_rates(rate_hz: u32, position_hz: Option<u32>) -> PyResult<LoopRates> {
    let rates = LoopRates { inner_hz: rate_hz, position_hz: position_hz.unwrap_or(rate_hz / 5) };
    rates.validate().map_err(|e| PyValueError::new_err(format!("loop rates: {e}")))?;
    Ok(rates)
}

fn parse_mode(scenario: &Scenario, mode: Option<&str>) -> PyResult<ReferenceMode> {
    match mode {
        None => Ok(scenario.reference_modes()[0]),
        Some(m) => serde_json::from_value(serde_json::Value::String(m.to_owned())).map_err(|_| {
            PyValueError::new_err(format!("mode `{m}` is not one of: feed-forward, position-only, feed-forward-jerk"))
        }),
    }
}

pub(crate) fn parse_kind(name: &str) -> PyResult<ControllerKind> {
    name.parse().map_err(|e: ParseControllerKindError| PyKeyError::new_err(e.to_string()))
}

/// A JSON value as Python objects (through Python's own `json`, so a dict equals `json.loads` of the CLI's line).
fn json_to_py<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A trace as {column: float64 array}.
fn trace_to_py<'py>(py: Python<'py>, trace: &Trace) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (i, name) in trace.columns.iter().enumerate() {
        let column: Vec<f64> = trace.rows.iter().map(|r| r[i]).collect();
        out.set_item(name, PyArray1::from_vec(py, column))?;
    }
    Ok(out)
}

fn vec3<'py>(py: Python<'py>, v: &nalgebra::Vector3<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

/// The controller of a run: a registered name, or a Python callable (with its error slot).
enum Flown {
    Named(ControllerKind),
    Python(Py<PyAny>),
}

fn flown(controller: &Bound<'_, PyAny>) -> PyResult<Flown> {
    if let Ok(name) = controller.extract::<String>() {
        return Ok(Flown::Named(parse_kind(&name)?));
    }
    if controller.is_callable() {
        return Ok(Flown::Python(controller.clone().unbind()));
    }
    Err(PyValueError::new_err(
        "controller must be a registered name (aco_sim.controllers()) or a callable (input, reference) -> action",
    ))
}

/// Builds a runner for `scenario` flown by `controller`.
fn runner(
    scenario: &Scenario,
    controller: &Flown,
    opts: &RunOptions,
    action: Action,
    rate_controller: &str,
    error: &ErrorSlot,
) -> PyResult<Runner> {
    let to_py = |e: sitl::scenario::ScenarioError| PyValueError::new_err(e.to_string());
    match controller {
        Flown::Named(kind) => Runner::new(scenario, &RunOptions { controller: *kind, ..opts.clone() }).map_err(to_py),
        Flown::Python(callable) => {
            let config = Runner::controller_config(scenario, opts).map_err(to_py)?;
            let c = PyController::new(
                Python::attach(|py| callable.clone_ref(py)),
                action,
                rate_controller,
                &config,
                Arc::clone(error),
            )?;
            Runner::with_controller(scenario, opts, Box::new(c), "python").map_err(to_py)
        }
    }
}

/// Raises the error a Python controller left, if any.
fn take_error(error: &ErrorSlot) -> PyResult<()> {
    match error.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// One lockstep run: plant + controller on simulated time, bit-reproducible for a seed.
#[pyclass(unsendable, module = "aco_sim._native")]
pub(crate) struct Sim {
    runner: Option<Runner>,
    output: Option<RunOutput>,
    error: ErrorSlot,
    python: bool,
}

#[pymethods]
impl Sim {
    #[new]
    #[pyo3(signature = (scenario, controller = None, plant = None, seed = 1, mode = None, rate_hz = 500,
        position_hz = None, trace_hz = 50, action = "pwm", rate_controller = "aco"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scenario: &str,
        controller: Option<&Bound<'_, PyAny>>,
        plant: Option<String>,
        seed: u64,
        mode: Option<&str>,
        rate_hz: u32,
        position_hz: Option<u32>,
        trace_hz: u32,
        action: &str,
        rate_controller: &str,
    ) -> PyResult<Self> {
        guard("Sim()", || {
            let scenario = load_scenario(scenario)?;
            let action = Action::parse(action)?;
            let default = pyo3::types::PyString::new(py, "aco");
            let controller = flown(controller.unwrap_or(default.as_any()))?;
            let opts = RunOptions {
                controller: ControllerKind::ACO,
                plant,
                seed,
                rates: loop_rates(rate_hz, position_hz)?,
                mode: parse_mode(&scenario, mode)?,
                trace_hz,
            };
            let error: ErrorSlot = Arc::new(Mutex::new(None));
            let python = matches!(controller, Flown::Python(_));
            let runner = runner(&scenario, &controller, &opts, action, rate_controller, &error)?;
            Ok(Self { runner: Some(runner), output: None, error, python })
        })
    }

    /// Simulated time (s).
    #[getter]
    fn time_s(&self) -> f64 {
        self.runner.as_ref().map_or_else(|| self.output.as_ref().map_or(0.0, |o| o.metrics.sim_s), Runner::time_s)
    }

    /// (ticks run, ticks in the run).
    #[getter]
    fn ticks(&self) -> (u64, u64) {
        match (&self.runner, &self.output) {
            (Some(r), _) => r.ticks(),
            (None, Some(o)) => {
                let n = (o.metrics.sim_s * f64::from(o.metrics.rate_hz)).round() as u64;
                (n, n)
            }
            (None, None) => (0, 0),
        }
    }

    /// Advances `n` control ticks; returns how many ran (fewer at the run's end).
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<u64> {
        guard("Sim.step", || {
            let python = self.python;
            let runner = self.runner.as_mut().ok_or_else(|| {
                PyRuntimeError::new_err("the run has finished (run() was called); make a new Sim to fly again")
            })?;
            if runner.ticks().0 >= runner.ticks().1 && n > 0 {
                return Err(PyRuntimeError::new_err(format!(
                    "the run is over: all {} ticks have run; call run() for its metrics",
                    runner.ticks().1
                )));
            }
            let mut done = 0;
            if python {
                while done < n && runner.step() {
                    done += 1;
                    take_error(&self.error)?;
                }
            } else {
                done = py.detach(|| {
                    let mut done = 0;
                    while done < n && runner.step() {
                        done += 1;
                    }
                    done
                });
            }
            Ok(done)
        })
    }

    /// Runs the remaining ticks and returns the metrics, as `sitl scenario --json` prints them.
    fn run<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        guard("Sim.run", || {
            if self.output.is_none() {
                let remaining = self.runner.as_ref().map_or(0, |r| r.ticks().1 - r.ticks().0);
                if remaining > 0 {
                    self.step(py, remaining)?;
                }
                let runner = self.runner.take().ok_or_else(|| PyRuntimeError::new_err("no run"))?;
                self.output = Some(runner.finish().map_err(|e| PyValueError::new_err(e.to_string()))?);
            }
            let output = self.output.as_ref().ok_or_else(|| PyRuntimeError::new_err("no output"))?;
            json_to_py(py, &output.metrics)
        })
    }

    /// The metrics of the finished run (None before `run()`).
    #[getter]
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.output.as_ref().map(|o| json_to_py(py, &o.metrics)).transpose()
    }

    /// The trace so far: {column: array}, the CSV's columns, decimated to `trace_hz`.
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        match (&self.runner, &self.output) {
            (_, Some(o)) => trace_to_py(py, &o.trace),
            (Some(r), None) => trace_to_py(py, r.trace()),
            (None, None) => Ok(PyDict::new(py)),
        }
    }

    /// The state now: truth (the plant's), estimate (what the controller saw at the last tick), reference
    /// (of the last tick) and the PWM commanded; None before the first tick and after `run()`.
    #[getter]
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(s) = self.runner.as_ref().and_then(Runner::state) else { return Ok(None) };
        let out = PyDict::new(py);
        out.set_item("t_s", self.time_s())?;
        let truth = PyDict::new(py);
        truth.set_item("pos_ned_m", vec3(py, &s.truth.pos_ned_m))?;
        truth.set_item("vel_ned_mps", vec3(py, &s.truth.vel_ned_mps))?;
        truth.set_item("euler_rad", vec3(py, &s.truth.euler_rad))?;
        let q = s.truth.q_ned_frd;
        truth.set_item("q_ned_frd", PyArray1::from_slice(py, &[q.w, q.i, q.j, q.k]))?;
        truth.set_item("rate_frd_radps", vec3(py, &s.truth.rate_frd_radps))?;
        truth.set_item("wind_ned_mps", vec3(py, &s.truth.wind_ned_mps))?;
        truth.set_item("rotor_lift_n", PyArray1::from_slice(py, &s.truth.rotor_lift_n))?;
        out.set_item("truth", truth)?;
        let seen = PyDict::new(py);
        seen.set_item("pos_ned_m", vec3(py, &s.seen.pos_ned_m))?;
        seen.set_item("vel_ned_mps", vec3(py, &s.seen.vel_ned_mps))?;
        seen.set_item("euler_rad", vec3(py, &s.seen.euler_rad))?;
        seen.set_item("rate_frd_radps", vec3(py, &s.seen.rate_frd_radps))?;
        seen.set_item("specific_force_frd_mps2", vec3(py, &s.seen.specific_force_frd_mps2))?;
        out.set_item("estimate", seen)?;
        let r = PyDict::new(py);
        r.set_item("pos_ned_m", vec3(py, &s.reference.pos_ned_m))?;
        r.set_item("vel_ned_mps", vec3(py, &s.reference.vel_ned_mps))?;
        r.set_item("acc_ned_mps2", vec3(py, &s.reference.acc_ned_mps2))?;
        r.set_item("yaw_rad", s.reference.yaw_rad)?;
        r.set_item("attitude_rad", s.reference.attitude_rad.map(|a| vec3(py, &a)))?;
        r.set_item("rate_frd_radps", s.reference.rate_frd_radps.map(|a| vec3(py, &a)))?;
        out.set_item("reference", r)?;
        out.set_item("pwm_us", PyArray1::from_slice(py, &s.pwm_us))?;
        Ok(Some(out))
    }

    /// Sets a SIM_ parameter (the plant's, at once) or a controller parameter (from the next tick).
    fn set_param(&mut self, name: &str, value: f64) -> PyResult<()> {
        guard("Sim.set_param", || {
            let runner = self
                .runner
                .as_mut()
                .ok_or_else(|| PyRuntimeError::new_err("the run has finished; parameters can no longer change"))?;
            if name.starts_with("SIM_") {
                if !SIM_PARAMS.iter().any(|d| d.name == name) {
                    return Err(PyKeyError::new_err(format!(
                        "unknown parameter {name} (the SIM_ table: docs/faults.md)"
                    )));
                }
                return runner.set_sim_param(name, value as f32).map_err(PyValueError::new_err);
            }
            let config = params::with_controller_param(runner.controller_config_in_use(), name, value)?;
            runner.reconfigure_controller(config).map_err(|e| PyValueError::new_err(e.to_string()))
        })
    }
}

/// A sweep file flown by a Python controller (or registered names): one row per (case, controller),
/// as columns {name: array}; the columns are `sitl sweep`'s.
#[pyfunction]
#[pyo3(signature = (path, controller, action = "pwm", rate_controller = "aco"))]
pub(crate) fn sweep_native<'py>(
    py: Python<'py>,
    path: &str,
    controller: &Bound<'py, PyAny>,
    action: &str,
    rate_controller: &str,
) -> PyResult<Bound<'py, PyDict>> {
    guard("sweep", || {
        let sweep = Sweep::load(std::path::Path::new(path), None).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let action = Action::parse(action)?;
        let flown = flown(controller)?;
        let error: ErrorSlot = Arc::new(Mutex::new(None));
        let params = sweep.param_names();
        let metrics = sweep.metric_columns();
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for case_index in 0..sweep.cases() {
            let case = sweep.case(case_index).map_err(|e| PyValueError::new_err(e.to_string()))?;
            let opts = RunOptions {
                controller: ControllerKind::ACO,
                plant: sweep.plant.clone(),
                seed: case.seed,
                rates: sweep.rates,
                mode: sweep.mode,
                trace_hz: 1,
            };
            let mut r = runner(&case.scenario, &flown, &opts, action, rate_controller, &error)?;
            while r.step() {
                take_error(&error)?;
            }
            let out = r.finish().map_err(|e| PyValueError::new_err(e.to_string()))?;
            let values = sitl::sweep::metric_values_of(&case.scenario, &opts, &out.metrics)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            let mut row = vec![case.index as f64, case.seed as f64];
            row.extend(&case.values);
            row.extend(values.iter().map(|v| v.unwrap_or(f64::NAN)));
            rows.push(row);
        }
        let names: Vec<String> = ["case".to_owned(), "seed".to_owned()]
            .into_iter()
            .chain(params.iter().map(|p| (*p).to_owned()))
            .chain(metrics)
            .collect();
        let out = PyDict::new(py);
        for (i, name) in names.iter().enumerate() {
            out.set_item(name, PyArray1::from_vec(py, rows.iter().map(|r| r[i]).collect()))?;
        }
        Ok(out)
    })
}
