//! `aco_sim._native`: the lockstep simulator (`Sim`), Python controllers in the runner, and the batched
//! Gymnasium core (`VecEnv`), exposed to Python by PyO3. The pure-Python package `aco_sim` wraps it.
//!
//! Errors are Python exceptions, never aborts: bad input is a `ValueError` (or `KeyError` for an unknown
//! name) raised before anything changes, and a panic inside Rust is caught at the boundary and raised as
//! a `RuntimeError` naming the call that failed ([`guard`]).

mod control;
mod env;
mod example_pd;
mod params;
mod sim;

use std::panic::{AssertUnwindSafe, catch_unwind};

use autopilot::core::control::{ControllerType, registry};
use pyo3::exceptions::{PyKeyError, PyRuntimeError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sitl::scenario::{BUILT_INS, Scenario};

/// Runs `f`, turning a Rust panic into a Python `RuntimeError` that names `what` and the panic's message.
pub(crate) fn guard<T>(what: &str, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => {
            let message = payload
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| payload.downcast_ref::<&str>().copied())
                .unwrap_or("(no message)");
            Err(PyRuntimeError::new_err(format!("aco_sim: {what} panicked inside Rust: {message}")))
        }
    }
}

/// A scenario by built-in name or TOML file path, with the CLI's parser; an unknown one is a `KeyError`
/// listing the built-ins.
pub(crate) fn load_scenario(name: &str) -> PyResult<Scenario> {
    Scenario::load(name).map_err(|e| match e {
        sitl::scenario::ScenarioError::NotFound(_) => PyKeyError::new_err(e.to_string()),
        e => pyo3::exceptions::PyValueError::new_err(e.to_string()),
    })
}

/// The built-in scenarios: name -> description.
#[pyfunction]
fn scenarios(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for (name, _) in BUILT_INS {
        let s = load_scenario(name)?;
        out.set_item(*name, s.description.split_whitespace().collect::<Vec<_>>().join(" "))?;
    }
    Ok(out)
}

/// The registered controllers: name -> {"summary", "table", "flies_rates"}.
#[pyfunction]
fn controllers(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for kind in registry::all() {
        let d = PyDict::new(py);
        d.set_item("summary", kind.ty().summary())?;
        d.set_item("table", kind.table())?;
        d.set_item("flies_rates", kind.flies_rates())?;
        out.set_item(kind.as_str(), d)?;
    }
    Ok(out)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The Rust twin of the quick start's Python PD law, by name (`controller="example_pd"`).
    if registry::find(example_pd::EXAMPLE_PD.name()).is_err() {
        registry::register(&example_pd::EXAMPLE_PD).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    }
    m.add_function(wrap_pyfunction!(scenarios, m)?)?;
    m.add_function(wrap_pyfunction!(controllers, m)?)?;
    m.add_class::<sim::Sim>()?;
    m.add_class::<control::Input>()?;
    m.add_class::<control::Ref>()?;
    m.add_class::<env::VecEnv>()?;
    m.add_function(wrap_pyfunction!(sim::sweep_native, m)?)?;
    m.add_function(wrap_pyfunction!(panic_for_test, m)?)?;
    Ok(())
}

/// Panics on purpose, inside [`guard`]: the test that a Rust panic reaches Python as a `RuntimeError`.
#[pyfunction]
fn panic_for_test() -> PyResult<()> {
    guard("panic_for_test", || panic!("a panic on purpose"))
}
