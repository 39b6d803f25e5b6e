//! `VecEnv`: the batched Gymnasium core (`sitl::gym`) for Python. Every call takes and returns whole
//! batches as numpy arrays, and steps all environments in Rust, across the cores, with the GIL released:
//! no Python runs per environment. `aco_sim.envs` wraps it in Gymnasium's `Env` and `VectorEnv`.

use std::collections::BTreeMap;

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyKeyError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sitl::gym::{self, ActionMode, Distribution, EnvConfig, GymError, Observe, Param, Task, TrackPath};

use crate::guard;
use crate::sim::parse_kind;

/// A gym error as the Python exception a caller expects: an unknown name is a `KeyError`, an ended
/// environment a `RuntimeError`, the rest `ValueError`.
fn to_py(e: GymError) -> PyErr {
    match e {
        GymError::UnknownName { .. } => PyKeyError::new_err(e.to_string()),
        GymError::Ended { .. } | GymError::Reset { .. } => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// The `randomize` argument, {sweep parameter: {"uniform" | "scale": [lo, hi], "values" | "choice": [...]}}
/// (the sweep's `[vary]` table), through Python's `json` and the sweep's own parser.
fn randomize(py: Python<'_>, table: &Bound<'_, PyDict>) -> PyResult<Vec<(Param, Distribution)>> {
    let text: String = py.import("json")?.call_method1("dumps", (table,))?.extract()?;
    let parsed: BTreeMap<String, Distribution> = serde_json::from_str(&text).map_err(|e| {
        PyValueError::new_err(format!("randomize: {e} (expected e.g. {{\"mass_kg\": {{\"scale\": [0.9, 1.1]}}}})"))
    })?;
    parsed
        .into_iter()
        .map(|(name, d)| {
            Param::parse(&name).map(|p| (p, d)).map_err(|e| PyKeyError::new_err(format!("randomize: {e}")))
        })
        .collect()
}

/// N environments of one task, stepped together.
#[pyclass(unsendable, module = "aco_sim._native")]
pub(crate) struct VecEnv {
    inner: gym::VecEnv,
    obs: Vec<f32>,
}

#[pymethods]
impl VecEnv {
    #[new]
    #[pyo3(signature = (task = "hover", *, num_envs = 1, autoreset = true, action = "motors", observe = "truth",
        controller = "aco", policy_hz = None, episode_s = None, track_path = None, randomize = None,
        randomize_start = None, scenario = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        task: &str,
        num_envs: usize,
        autoreset: bool,
        action: &str,
        observe: &str,
        controller: &str,
        policy_hz: Option<u32>,
        episode_s: Option<f64>,
        track_path: Option<&str>,
        randomize: Option<&Bound<'_, PyDict>>,
        randomize_start: Option<bool>,
        scenario: Option<&str>,
    ) -> PyResult<Self> {
        guard("VecEnv()", || {
            let task: Task = task.parse().map_err(to_py)?;
            let action: ActionMode = action.parse().map_err(to_py)?;
            let mut config = EnvConfig::new(task, action);
            config.observe = observe.parse::<Observe>().map_err(to_py)?;
            config.controller = parse_kind(controller)?;
            if let Some(hz) = policy_hz {
                config.policy_hz = hz;
            }
            if let Some(s) = episode_s {
                config.episode_s = s;
            }
            if let Some(p) = track_path {
                config.track_path = p.parse::<TrackPath>().map_err(to_py)?;
            }
            if let Some(table) = randomize {
                config.randomize = self::randomize(py, table)?;
            }
            if let Some(r) = randomize_start {
                config.randomize_start = r;
            }
            if let Some(name) = scenario {
                config.scenario = Some(crate::load_scenario(name)?);
            }
            config.validate().map_err(to_py)?;
            let inner = py.detach(|| gym::VecEnv::new(config, num_envs, autoreset)).map_err(to_py)?;
            let obs = vec![0.0; num_envs * inner.config().obs_dim()];
            Ok(Self { inner, obs })
        })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.inner.num_envs()
    }

    #[getter]
    fn obs_dim(&self) -> usize {
        self.inner.config().obs_dim()
    }

    #[getter]
    fn action_dim(&self) -> usize {
        self.inner.config().action_dim()
    }

    #[getter]
    fn action_low(&self) -> Vec<f32> {
        self.inner.config().action_low().to_vec()
    }

    #[getter]
    fn action_high(&self) -> Vec<f32> {
        self.inner.config().action_high().to_vec()
    }

    #[getter]
    fn obs_names(&self) -> Vec<&'static str> {
        self.inner.config().obs_names()
    }

    /// Resets every environment; environment i's first episode draws from (seed, i) only. Returns the
    /// observations, float32 (num_envs, obs_dim).
    fn reset<'py>(&mut self, py: Python<'py>, seed: u64) -> PyResult<Bound<'py, PyArray2<f32>>> {
        guard("VecEnv.reset", || {
            let (inner, obs) = (&mut self.inner, &mut self.obs);
            py.detach(|| inner.reset(seed, obs)).map_err(to_py)?;
            self.observations(py)
        })
    }

    /// One policy step of every environment. `actions`: float32 (num_envs, 4), C-contiguous. Returns
    /// (observations, rewards, terminated, truncated, reset_now).
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
    )> {
        guard("VecEnv.step", || {
            let n = self.inner.num_envs();
            let a = actions.as_slice().map_err(|_| {
                PyValueError::new_err("actions must be a C-contiguous float32 array (numpy.ascontiguousarray)")
            })?;
            let (mut reward, mut terminated, mut truncated, mut reset_now) =
                (vec![0.0f32; n], vec![false; n], vec![false; n], vec![false; n]);
            let (inner, obs) = (&mut self.inner, &mut self.obs);
            py.detach(|| inner.step(a, obs, &mut reward, &mut terminated, &mut truncated, &mut reset_now))
                .map_err(to_py)?;
            Ok((
                self.observations(py)?,
                PyArray1::from_vec(py, reward),
                PyArray1::from_vec(py, terminated),
                PyArray1::from_vec(py, truncated),
                PyArray1::from_vec(py, reset_now),
            ))
        })
    }

    /// Marks environments as ended (a Python termination function's verdict): they reset at the next step.
    fn set_ended(&mut self, ended: PyReadonlyArray1<'_, bool>) -> PyResult<()> {
        let e = ended.as_slice().map_err(|_| PyValueError::new_err("ended must be a contiguous bool array"))?;
        self.inner.set_ended(e).map_err(to_py)
    }

    /// Time in the current episode (s), per environment.
    fn episode_time_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.episode_time_s())
    }

    /// Episodes since the last reset, per environment.
    fn episode_index<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.inner.episode_index())
    }

    /// Environment i's true state and reference: a dict of float64 arrays.
    fn truth<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Bound<'py, PyDict>> {
        if i >= self.inner.num_envs() {
            return Err(PyValueError::new_err(format!(
                "env {i} does not exist (num_envs = {})",
                self.inner.num_envs()
            )));
        }
        let t = self.inner.truth(i);
        let out = PyDict::new(py);
        out.set_item("time_s", t.time_s)?;
        out.set_item("pos_ned_m", PyArray1::from_slice(py, &t.pos_ned_m))?;
        out.set_item("vel_ned_mps", PyArray1::from_slice(py, &t.vel_ned_mps))?;
        out.set_item("q_ned_frd", PyArray1::from_slice(py, &t.q_ned_frd))?;
        out.set_item("rate_frd_radps", PyArray1::from_slice(py, &t.rate_frd_radps))?;
        out.set_item("ref_pos_ned_m", PyArray1::from_slice(py, &t.ref_pos_ned_m))?;
        out.set_item("ref_vel_ned_mps", PyArray1::from_slice(py, &t.ref_vel_ned_mps))?;
        Ok(out)
    }

    /// Memory of one environment: (its struct's bytes, its heap's bytes, estimated).
    fn env_bytes(&self) -> (usize, usize) {
        self.inner.env_bytes()
    }
}

impl VecEnv {
    fn observations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let d = self.inner.config().obs_dim();
        PyArray1::from_slice(py, &self.obs).reshape([self.inner.num_envs(), d])
    }
}
