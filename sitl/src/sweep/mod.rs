//! Monte Carlo and grid sweeps of one scenario (`sitl sweep SPEC.toml`): a spec of distributions and
//! grids over airframe values, wind, sensor noise, seeds and controllers; every run in-process in
//! lockstep across all cores (rayon); one row per run, a per-controller robustness summary and plots.
//!
//! A sweep is a list of *cases* (one draw of every varied value) and each case is run once per
//! controller, so the controllers meet exactly the same plants, winds and noise (a paired comparison).
//! Case `c` is grid point `c / samples` and random draw `c % samples`; its random values come from
//! ChaCha8 stream `c` of the sweep seed, so any subset of the runs (a shard) reproduces exactly. Run
//! `r = c * controllers + k` is case `c` with the k-th controller. The format is documented in
//! `docs/sweeps.md`.

pub mod table;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use autopilot::core::control::{ControllerKind, LoopRates};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use crate::plant::rotor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US, lift_from_pwm_n};
use crate::plant::wind::GaussMarkovConfig;
use crate::plant::{InitialState, Plant, TurbulenceConfig};
use crate::scenario::runner::{self, RunOptions};
use crate::scenario::{ReferenceMode, Scenario, ScenarioError, StateNoiseKind};
pub use table::{Row, Summary};

/// Why a sweep could not be loaded or run.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("cannot read sweep spec {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("sweep spec {path}: {source}")]
    Parse { path: String, source: Box<toml::de::Error> },
    #[error("sweep spec: {0}")]
    Invalid(String),
    #[error("sweep case {case}: {source}")]
    Case { case: u64, source: ScenarioError },
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("{0}")]
    Table(String),
}

/// How one varied value is chosen per case.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum Distribution {
    /// Uniform between the two values.
    Uniform([f64; 2]),
    /// The scenario's own value times a factor uniform between the two values (e.g. `[0.85, 1.15]`).
    Scale([f64; 2]),
    /// A grid axis: every case runs at each of these values (the cases are the grid's product).
    Values(Vec<f64>),
    /// One of these values, picked at random per case.
    Choice(Vec<f64>),
}

/// What a sweep can vary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Param {
    MassKg,
    InertiaKgm2,
    ThrustScale,
    MotorTauS,
    DisturbanceRollNm,
    DisturbancePitchNm,
    DisturbanceYawNm,
    DragCdaM2,
    WindSpeedMps,
    WindAzimuthDeg,
    Beaufort,
    GustAmplitudeMps,
    GustAzimuthDeg,
    TurbulenceScale,
    StateNoiseScale,
    Seed,
    Mot1Eff,
    Mot2Eff,
    Mot3Eff,
    Mot4Eff,
}

impl Param {
    /// Every parameter with its name in a spec's `[vary]` table and in the rows' header.
    pub const ALL: [(Self, &'static str); 20] = [
        (Self::MassKg, "mass_kg"),
        (Self::InertiaKgm2, "inertia_kgm2"),
        (Self::ThrustScale, "thrust_scale"),
        (Self::MotorTauS, "motor_tau_s"),
        (Self::DisturbanceRollNm, "disturbance_roll_nm"),
        (Self::DisturbancePitchNm, "disturbance_pitch_nm"),
        (Self::DisturbanceYawNm, "disturbance_yaw_nm"),
        (Self::DragCdaM2, "drag_cda_m2"),
        (Self::WindSpeedMps, "wind_speed_mps"),
        (Self::WindAzimuthDeg, "wind_azimuth_deg"),
        (Self::Beaufort, "beaufort"),
        (Self::GustAmplitudeMps, "gust_amplitude_mps"),
        (Self::GustAzimuthDeg, "gust_azimuth_deg"),
        (Self::TurbulenceScale, "turbulence_scale"),
        (Self::StateNoiseScale, "state_noise_scale"),
        (Self::Seed, "seed"),
        (Self::Mot1Eff, "mot1_eff"),
        (Self::Mot2Eff, "mot2_eff"),
        (Self::Mot3Eff, "mot3_eff"),
        (Self::Mot4Eff, "mot4_eff"),
    ];

    /// The rotor (array index) a `motN_eff` sets.
    fn rotor(self) -> Option<usize> {
        match self {
            Self::Mot1Eff => Some(0),
            Self::Mot2Eff => Some(1),
            Self::Mot3Eff => Some(2),
            Self::Mot4Eff => Some(3),
            _ => None,
        }
    }

    /// The parameter named `name` in a `[vary]` table.
    ///
    /// # Errors
    /// An unknown name, listing the known ones.
    pub fn parse(name: &str) -> Result<Self, SweepError> {
        Self::ALL.iter().find(|(_, n)| *n == name).map(|(p, _)| *p).ok_or_else(|| {
            let known: Vec<&str> = Self::ALL.iter().map(|(_, n)| *n).collect();
            SweepError::Invalid(format!("[vary] has unknown key `{name}` (known: {})", known.join(", ")))
        })
    }

    /// The name in a spec and in the rows' header.
    #[must_use]
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(p, _)| *p == self).map_or("?", |(_, n)| n)
    }

    /// Whole numbers only (a seed, a Beaufort force).
    pub(crate) fn is_integer(self) -> bool {
        matches!(self, Self::Beaufort | Self::Seed)
    }

    /// The scenario's own value, which `scale` multiplies; `None` where a factor means nothing.
    fn nominal(self, scenario: &Scenario, plant: Option<&str>) -> Result<Option<f64>, ScenarioError> {
        let airframe = runner::plant_config(scenario, plant)?.airframe;
        let wind = &scenario.wind;
        Ok(match self {
            Self::MassKg => Some(airframe.mass_kg),
            // One factor for the three axes: the inertia's shape is kept.
            Self::InertiaKgm2 => Some(1.0),
            Self::ThrustScale => Some(airframe.thrust_scale),
            Self::MotorTauS => Some(airframe.motor_tau_s),
            Self::DisturbanceRollNm => Some(airframe.disturbance_torque_frd_nm[0]),
            Self::DisturbancePitchNm => Some(airframe.disturbance_torque_frd_nm[1]),
            Self::DisturbanceYawNm => Some(airframe.disturbance_torque_frd_nm[2]),
            Self::DragCdaM2 => Some(airframe.drag_cda_m2),
            Self::WindSpeedMps => Some(horizontal_norm(wind.steady_ned_mps)),
            Self::GustAmplitudeMps => wind.gust.as_ref().and_then(|g| g.amplitude_mps),
            Self::TurbulenceScale => Some(1.0),
            Self::StateNoiseScale => Some(scenario.state_noise_scale),
            Self::Mot1Eff | Self::Mot2Eff | Self::Mot3Eff | Self::Mot4Eff => {
                let rotor = self.rotor().unwrap_or(0);
                let key = MOT_EFF_PARAMS[rotor];
                Some(
                    scenario
                        .events
                        .iter()
                        .find_map(|e| e.set.get(key).copied())
                        .unwrap_or(airframe.rotor_health[rotor]),
                )
            }
            Self::WindAzimuthDeg | Self::Beaufort | Self::GustAzimuthDeg | Self::Seed => None,
        })
    }
}

fn horizontal_norm(v: [f64; 3]) -> f64 {
    v[0].hypot(v[1])
}

/// A unit horizontal NED direction from an azimuth (degrees clockwise from north, the way it blows).
fn azimuth_ned(azimuth_deg: f64) -> [f64; 3] {
    let a = azimuth_deg.to_radians();
    [a.cos(), a.sin(), 0.0]
}

/// The spec as written in its TOML file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    name: String,
    #[serde(default)]
    description: String,
    /// A built-in scenario's name, or a scenario file (relative to the spec's directory).
    scenario: String,
    /// Default: the scenario's own list.
    #[serde(default)]
    controllers: Vec<ControllerKind>,
    /// Airframe preset over the scenario's.
    #[serde(default)]
    plant: Option<String>,
    /// Random draws per grid point.
    #[serde(default = "one")]
    samples: u64,
    seed: u64,
    #[serde(default)]
    vary: BTreeMap<String, Distribution>,
    /// Upper bounds per metric column: the summary gives the fraction of runs at or under each.
    #[serde(default)]
    bounds: BTreeMap<String, f64>,
    /// Inner loop rate (Hz); default the autopilot's.
    #[serde(default)]
    rate_hz: Option<u32>,
}

fn one() -> u64 {
    1
}

/// The SIM_ parameter of each rotor's efficiency (`motN_eff` sets it in a scenario's `[[event]]`s).
const MOT_EFF_PARAMS: [&str; 4] = ["SIM_MOT1_EFF", "SIM_MOT2_EFF", "SIM_MOT3_EFF", "SIM_MOT4_EFF"];

/// The most runs one sweep may have.
pub const MAX_RUNS: u64 = 10_000_000;

/// A validated sweep: the scenario, what varies and how, and the run count.
#[derive(Debug, Clone)]
pub struct Sweep {
    pub name: String,
    pub description: String,
    pub scenario: Scenario,
    pub plant: Option<String>,
    pub controllers: Vec<ControllerKind>,
    pub samples: u64,
    pub seed: u64,
    /// In the order of [`Param::ALL`] (the rows' column order).
    pub vary: Vec<(Param, Distribution)>,
    pub bounds: BTreeMap<String, f64>,
    pub rates: LoopRates,
    pub mode: ReferenceMode,
}

/// One case: every varied value, and the scenario they make.
#[derive(Debug, Clone)]
pub struct Case {
    pub index: u64,
    /// The plant and noise seed.
    pub seed: u64,
    /// The varied values in the sweep's `vary` order.
    pub values: Vec<f64>,
    pub scenario: Scenario,
}

impl Sweep {
    /// Loads and validates a spec; `scenario_override` replaces the spec's scenario (a file path).
    /// Every case is built and its plant resolved here, so a value no plant can have fails before the
    /// first run.
    ///
    /// # Errors
    /// An unreadable or malformed spec (unknown keys included), a scenario that does not load, or a
    /// distribution, bound or case that cannot run.
    pub fn load(path: &Path, scenario_override: Option<&Path>) -> Result<Self, SweepError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| SweepError::Io { path: path.display().to_string(), source })?;
        let spec: SpecFile = toml::from_str(&text)
            .map_err(|e| SweepError::Parse { path: path.display().to_string(), source: Box::new(e) })?;
        let scenario = match scenario_override {
            Some(file) => Scenario::load(&file.to_string_lossy())?,
            None => load_scenario(&spec.scenario, path.parent().unwrap_or(Path::new(".")))?,
        };
        Self::new(spec, scenario)
    }

    /// Parses and validates a spec from TOML text with its scenario already loaded.
    ///
    /// # Errors
    /// As [`Sweep::load`].
    pub fn from_toml(text: &str, scenario: Scenario) -> Result<Self, SweepError> {
        let spec: SpecFile =
            toml::from_str(text).map_err(|e| SweepError::Parse { path: "<text>".into(), source: Box::new(e) })?;
        Self::new(spec, scenario)
    }

    fn new(spec: SpecFile, scenario: Scenario) -> Result<Self, SweepError> {
        let invalid = |m: String| Err(SweepError::Invalid(m));
        let mut vary = Vec::new();
        for (name, dist) in spec.vary {
            vary.push((Param::parse(&name)?, dist));
        }
        vary.sort_by_key(|(p, _)| *p);
        let plant = spec.plant;
        for (param, dist) in &vary {
            let name = param.name();
            let values: Vec<f64> = match dist {
                Distribution::Uniform(r) | Distribution::Scale(r) => {
                    if !(r[0].is_finite() && r[1].is_finite() && r[0] <= r[1]) {
                        return invalid(format!("{name}: the range {r:?} must be finite and ascending"));
                    }
                    r.to_vec()
                }
                Distribution::Values(v) | Distribution::Choice(v) => {
                    if v.is_empty() || v.iter().any(|x| !x.is_finite()) {
                        return invalid(format!("{name}: the list must hold at least one finite value"));
                    }
                    v.clone()
                }
            };
            if param.is_integer() {
                if !matches!(dist, Distribution::Values(_) | Distribution::Choice(_)) {
                    return invalid(format!("{name} takes `values` or `choice` (whole numbers)"));
                }
                if values.iter().any(|v| v.fract() != 0.0 || *v < 0.0 || *v > 9.007_199_254_740_992e15) {
                    return invalid(format!("{name}: {values:?} must be whole numbers >= 0"));
                }
            }
            if matches!(dist, Distribution::Scale(_)) && param.nominal(&scenario, plant.as_deref())?.is_none() {
                return invalid(format!("{name} has no scenario value for `scale` to multiply: use `uniform`"));
            }
            let has_gust = scenario.wind.gust.is_some();
            if matches!(param, Param::GustAmplitudeMps | Param::GustAzimuthDeg) && !has_gust {
                return invalid(format!("{name} needs a scenario with a [wind.gust]"));
            }
            if *param == Param::StateNoiseScale && scenario.state_noise == StateNoiseKind::None {
                return invalid(format!(
                    "{name} scales the paper's sensor noise; this scenario has state_noise = \"none\""
                ));
            }
            if *param == Param::TurbulenceScale && matches!(scenario.wind.turbulence, Some(TurbulenceConfig::Dryden(_)))
            {
                return invalid(format!("{name} scales Gauss-Markov turbulence; this scenario's is Dryden"));
            }
        }
        let varies = |p: Param| vary.iter().any(|(q, _)| *q == p);
        if varies(Param::Beaufort) && varies(Param::GustAmplitudeMps) {
            return invalid("vary either beaufort or gust_amplitude_mps: both set the gust's amplitude".into());
        }
        if varies(Param::Beaufort) && (varies(Param::WindSpeedMps)) && scenario.wind.gust.is_none() {
            return invalid("vary either beaufort or wind_speed_mps: without a gust both set the steady wind".into());
        }
        if spec.samples == 0 {
            return invalid("samples must be at least 1".into());
        }
        let controllers = if spec.controllers.is_empty() { scenario.controllers.clone() } else { spec.controllers };
        let mut rates = LoopRates::default();
        if let Some(hz) = spec.rate_hz {
            rates = LoopRates { inner_hz: hz, position_hz: hz / 5 };
        }
        rates.validate().map_err(|e| SweepError::Invalid(format!("rate_hz: {e}")))?;
        let mode = scenario.reference_modes()[0];
        let sweep = Self {
            name: spec.name,
            description: spec.description,
            scenario,
            plant,
            controllers,
            samples: spec.samples,
            seed: spec.seed,
            vary,
            bounds: spec.bounds,
            rates,
            mode,
        };
        let total = sweep.cases().checked_mul(sweep.controllers.len() as u64);
        if total.is_none_or(|t| t > MAX_RUNS) {
            return invalid(format!("the sweep has more than {MAX_RUNS} runs"));
        }
        let columns = table::metric_columns(&sweep.scenario);
        for key in sweep.bounds.keys() {
            if !columns.iter().any(|c| c == key) {
                return invalid(format!(
                    "[bounds] has unknown metric `{key}` (this scenario's: {})",
                    columns.join(", ")
                ));
            }
        }
        for case in 0..sweep.cases() {
            let case = sweep.case(case)?;
            let config = runner::plant_config(&case.scenario, sweep.plant.as_deref())
                .map_err(|source| SweepError::Case { case: case.index, source })?;
            Plant::new(config, &InitialState::default(), case.seed)
                .map_err(|e| SweepError::Case { case: case.index, source: e.into() })?;
            case.scenario.state_noise().map_err(|source| SweepError::Case { case: case.index, source })?;
        }
        Ok(sweep)
    }

    fn grid(&self) -> Vec<&[f64]> {
        self.vary
            .iter()
            .filter_map(|(_, d)| if let Distribution::Values(v) = d { Some(v.as_slice()) } else { None })
            .collect()
    }

    /// The number of cases: grid points times samples.
    #[must_use]
    pub fn cases(&self) -> u64 {
        self.grid().iter().try_fold(self.samples, |n, axis| n.checked_mul(axis.len() as u64)).unwrap_or(u64::MAX)
    }

    /// The number of runs: cases times controllers.
    #[must_use]
    pub fn runs(&self) -> u64 {
        self.cases() * self.controllers.len() as u64
    }

    /// The names of the varied values, in column order.
    #[must_use]
    pub fn param_names(&self) -> Vec<&'static str> {
        self.vary.iter().map(|(p, _)| p.name()).collect()
    }

    /// Case `index`: its values, drawn from ChaCha8 stream `index` of the sweep seed, and its scenario.
    ///
    /// # Errors
    /// A scenario value that cannot be read (an unknown preset).
    pub fn case(&self, index: u64) -> Result<Case, SweepError> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(index);
        // Grid position: the last grid axis varies fastest.
        let mut grid_index = index / self.samples;
        let mut grid_values = Vec::new();
        for axis in self.grid().iter().rev() {
            let n = axis.len() as u64;
            grid_values.push(axis[(grid_index % n) as usize]);
            grid_index /= n;
        }
        grid_values.reverse();
        let mut grid_values = grid_values.into_iter();
        let seed_draw: u64 = rng.random();
        let mut values = Vec::new();
        for (param, dist) in &self.vary {
            let v = match dist {
                Distribution::Uniform([lo, hi]) => lo + (hi - lo) * rng.random::<f64>(),
                Distribution::Scale([lo, hi]) => {
                    let nominal = param.nominal(&self.scenario, self.plant.as_deref())?.unwrap_or(1.0);
                    nominal * (lo + (hi - lo) * rng.random::<f64>())
                }
                Distribution::Values(_) => grid_values.next().unwrap_or(f64::NAN),
                Distribution::Choice(v) => v[rng.random_range(0..v.len())],
            };
            values.push(v);
        }
        let mut scenario = self.scenario.clone();
        let mut seed = seed_draw;
        for ((param, _), &v) in self.vary.iter().zip(&values) {
            apply(&mut scenario, *param, v, self.plant.as_deref())
                .map_err(|source| SweepError::Case { case: index, source })?;
            if *param == Param::Seed {
                seed = v as u64;
            }
        }
        Ok(Case { index, seed, values, scenario })
    }

    /// Run `run`: its case and controller.
    ///
    /// # Errors
    /// As [`Sweep::case`], and a run that cannot start.
    pub fn run(&self, run: u64) -> Result<Row, SweepError> {
        let k = self.controllers.len() as u64;
        let case = self.case(run / k)?;
        let controller = self.controllers[(run % k) as usize];
        let opts = RunOptions {
            controller,
            plant: self.plant.clone(),
            seed: case.seed,
            rates: self.rates,
            mode: self.mode,
            trace_hz: 1,
        };
        let metrics =
            run_metric_values(&case.scenario, &opts).map_err(|source| SweepError::Case { case: case.index, source })?;
        Ok(Row { run, case: case.index, controller, seed: case.seed, params: case.values, metrics })
    }

    /// The metric column names of this sweep's rows.
    #[must_use]
    pub fn metric_columns(&self) -> Vec<String> {
        table::metric_columns(&self.scenario)
    }
}

/// Runs `scenario` once with `opts` and returns the run's metrics in [`table::metric_columns`] order (the
/// values of one sweep row; `sitl tune` scores its candidates on the same values).
///
/// # Errors
/// A run that cannot start (a bad plant or rate).
pub fn run_metric_values(scenario: &Scenario, opts: &RunOptions) -> Result<Vec<Option<f64>>, ScenarioError> {
    let out = runner::run(scenario, opts)?;
    metric_values_of(scenario, opts, &out.metrics)
}

/// A finished run's metrics in [`table::metric_columns`] order (a run flown by any controller, e.g. one
/// built outside the registry).
///
/// # Errors
/// A bad plant preset or override.
pub fn metric_values_of(
    scenario: &Scenario,
    opts: &RunOptions,
    metrics: &runner::RunMetrics,
) -> Result<Vec<Option<f64>>, ScenarioError> {
    let airframe = runner::plant_config(scenario, opts.plant.as_deref())?.airframe;
    let weight_n = airframe.mass_kg * airframe.gravity_mps2;
    let thrust_to_weight = [MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US].map(|pwm_us| {
        airframe.rotor_health.iter().map(|h| h * lift_from_pwm_n(pwm_us)).sum::<f64>() * airframe.thrust_scale
            / weight_n
    });
    Ok(table::metric_values(scenario, thrust_to_weight, metrics))
}

/// A scenario named in a spec: a built-in, or a file relative to the spec's directory.
pub(crate) fn load_scenario(name: &str, spec_dir: &Path) -> Result<Scenario, ScenarioError> {
    if crate::scenario::BUILT_INS.iter().any(|(n, _)| *n == name) {
        return Scenario::load(name);
    }
    let path: PathBuf = spec_dir.join(name);
    Scenario::load(&path.to_string_lossy())
}

/// Sets one varied value on a scenario.
pub(crate) fn apply(scenario: &mut Scenario, param: Param, v: f64, plant: Option<&str>) -> Result<(), ScenarioError> {
    if param == Param::StateNoiseScale {
        scenario.state_noise_scale = v;
        return Ok(());
    }
    if let Some(rotor) = param.rotor() {
        // The rotor's efficiency after the fault: in every [[event]] that sets it, or else from the start.
        let key = MOT_EFF_PARAMS[rotor];
        let mut in_events = false;
        for event in &mut scenario.events {
            if let Some(value) = event.set.get_mut(key) {
                *value = v;
                in_events = true;
            }
        }
        if !in_events {
            let mut health = runner::plant_config(scenario, plant)?.airframe.rotor_health;
            health[rotor] = v;
            scenario.airframe.rotor_health = Some(health);
        }
        // The value reaches the plant through the event's validation or the airframe's.
        scenario.sim_events()?;
        runner::plant_config(scenario, plant)?;
        return Ok(());
    }
    let resolved = runner::plant_config(scenario, plant)?.airframe;
    let a = &mut scenario.airframe;
    let wind = &mut scenario.wind;
    let mut torque = resolved.disturbance_torque_frd_nm;
    match param {
        Param::MassKg => a.mass_kg = Some(v),
        Param::InertiaKgm2 => a.inertia_kgm2 = Some((resolved.inertia_kgm2 * v).into()),
        Param::ThrustScale => a.thrust_scale = Some(v),
        Param::MotorTauS => a.motor_tau_s = Some(v),
        Param::DisturbanceRollNm | Param::DisturbancePitchNm | Param::DisturbanceYawNm => {
            let axis = match param {
                Param::DisturbanceRollNm => 0,
                Param::DisturbancePitchNm => 1,
                _ => 2,
            };
            torque[axis] = v;
            a.disturbance_torque_frd_nm = Some(torque.into());
        }
        Param::DragCdaM2 => a.drag_cda_m2 = Some(v),
        Param::WindSpeedMps => {
            let s = wind.steady_ned_mps;
            let norm = horizontal_norm(s);
            let dir = if norm > 0.0 { [s[0] / norm, s[1] / norm, 0.0] } else { [0.0, 1.0, 0.0] };
            wind.steady_ned_mps = [dir[0] * v, dir[1] * v, s[2]];
        }
        Param::WindAzimuthDeg => {
            let s = wind.steady_ned_mps;
            let speed = horizontal_norm(s);
            let d = azimuth_ned(v);
            wind.steady_ned_mps = [d[0] * speed, d[1] * speed, s[2]];
        }
        Param::Beaufort => {
            wind.beaufort = Some(v as u8);
            if let Some(g) = &mut wind.gust {
                g.amplitude_mps = None;
            }
        }
        Param::GustAmplitudeMps => {
            if let Some(g) = &mut wind.gust {
                g.amplitude_mps = Some(v);
            }
        }
        Param::GustAzimuthDeg => {
            if let Some(g) = &mut wind.gust {
                g.direction_ned = azimuth_ned(v);
            }
        }
        Param::TurbulenceScale => {
            let scale_with_gust = wind.gust.is_some();
            let base = match &wind.turbulence {
                Some(TurbulenceConfig::GaussMarkov(c)) => c.clone(),
                _ => GaussMarkovConfig { scale_with_gust, ..GaussMarkovConfig::default() },
            };
            let sigma_mps = base.sigma_mps.map(|s| s * v);
            wind.turbulence = Some(TurbulenceConfig::GaussMarkov(GaussMarkovConfig { sigma_mps, ..base }));
        }
        Param::StateNoiseScale | Param::Seed | Param::Mot1Eff | Param::Mot2Eff | Param::Mot3Eff | Param::Mot4Eff => {}
    }
    Ok(())
}

/// `K/N` (1-based K): the shard that runs every N-th run from run K-1.
///
/// # Errors
/// Text that is not `K/N` with 1 <= K <= N.
pub fn parse_shard(text: &str) -> Result<(u64, u64), String> {
    let (k, n) = text.split_once('/').ok_or_else(|| format!("shard `{text}` is not K/N (e.g. 2/3)"))?;
    let (k, n): (u64, u64) = (
        k.trim().parse().map_err(|_| format!("shard `{text}`: K is not a whole number"))?,
        n.trim().parse().map_err(|_| format!("shard `{text}`: N is not a whole number"))?,
    );
    if n == 0 || k == 0 || k > n {
        return Err(format!("shard `{text}` needs 1 <= K <= N"));
    }
    Ok((k, n))
}

/// The runs of shard K/N: every N-th run from run K-1.
#[must_use]
pub fn shard_runs(total: u64, (k, n): (u64, u64)) -> Vec<u64> {
    (k - 1..total).step_by(usize::try_from(n).unwrap_or(usize::MAX)).collect()
}

#[cfg(test)]
mod tests;
