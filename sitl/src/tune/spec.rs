//! The tuning spec (`sitl tune SPEC.toml`, `docs/tuning.md`): the TOML as written, its parsing and
//! validation into a [`Tune`] (budget, seeds, optimizer, `[base]`, run sets with their costs, limits and
//! reports), checked whole before any run.

use std::collections::BTreeMap;
use std::path::Path;

use autopilot::core::control::{ControllerConfig, ControllerKind, LoopRates, TunableGain};
use serde::Deserialize;
use serde_json::Value;

use super::gains::{Gain, check_known, merge, parse_gain, table_name, with_table_defaults};
use crate::plant::{InitialState, Plant};
use crate::scenario::reference::ReferenceSpec;
use crate::scenario::runner;
use crate::scenario::{ReferenceMode, Scenario, ScenarioError};
use crate::sweep::{self, Param, table};

/// Why a tuning spec or a gain file could not be loaded, or a tuning could not run.
#[derive(Debug, thiserror::Error)]
pub enum TuneError {
    #[error("cannot read {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: {source}")]
    Parse { path: String, source: Box<toml::de::Error> },
    #[error("tuning spec: {0}")]
    Invalid(String),
    #[error("gain file {path}: {message}")]
    GainFile { path: String, message: String },
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
}

pub(super) fn invalid<T>(message: String) -> Result<T, TuneError> {
    Err(TuneError::Invalid(message))
}

/// A gain's search scale between its bounds: the one a controller declares its gains with.
pub use autopilot::core::control::GainScale as Scale;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GainFile {
    pub(super) name: String,
    #[serde(default)]
    pub(super) axes: Option<Vec<usize>>,
    pub(super) bounds: [f64; 2],
    #[serde(default)]
    pub(super) scale: Scale,
    #[serde(default)]
    pub(super) start: Option<f64>,
}

impl From<&TunableGain> for GainFile {
    fn from(g: &TunableGain) -> Self {
        Self {
            name: g.name.to_owned(),
            axes: (!g.axes.is_empty()).then(|| g.axes.to_vec()),
            bounds: g.bounds,
            scale: g.scale,
            start: None,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RunFile {
    #[serde(default)]
    name: Option<String>,
    scenario: String,
    #[serde(default)]
    plants: Vec<String>,
    #[serde(default = "first_seed")]
    seeds: Vec<u64>,
    #[serde(default)]
    speed_mps: Option<f64>,
    #[serde(default)]
    duration_s: Option<f64>,
    /// A track's reference mode, over the first of its scenario's `reference_modes`.
    #[serde(default)]
    mode: Option<ReferenceMode>,
    #[serde(default)]
    set: BTreeMap<String, f64>,
    #[serde(default)]
    cost: BTreeMap<String, f64>,
    #[serde(default)]
    limits: BTreeMap<String, f64>,
    #[serde(default)]
    report: Vec<String>,
}

fn first_seed() -> Vec<u64> {
    vec![1]
}

/// The optimizer's seed: one, or a list (one whole search each).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
enum SeedFile {
    One(u64),
    Many(Vec<u64>),
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct OptimizerFile {
    #[serde(default = "cma_es")]
    kind: String,
    #[serde(default = "default_sigma0")]
    sigma0: f64,
    #[serde(default)]
    population: Option<usize>,
}

impl Default for OptimizerFile {
    fn default() -> Self {
        Self { kind: cma_es(), sigma0: default_sigma0(), population: None }
    }
}

fn cma_es() -> String {
    "cma-es".to_owned()
}

fn default_sigma0() -> f64 {
    0.25
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    name: String,
    #[serde(default)]
    description: String,
    controller: ControllerKind,
    budget: usize,
    seed: SeedFile,
    #[serde(default)]
    rate_hz: Option<u32>,
    #[serde(default)]
    optimizer: OptimizerFile,
    /// Settings every candidate flies with, under its gains: a `[base.<table>]` of the spec's controller.
    #[serde(default)]
    base: Option<Value>,
    /// The gains to search; none: the ones the controller declares ([`ControllerType::gains`]).
    ///
    /// [`ControllerType::gains`]: autopilot::core::control::ControllerType::gains
    #[serde(default)]
    gain: Vec<GainFile>,
    train: Vec<RunFile>,
    #[serde(default)]
    guard: Vec<RunFile>,
    #[serde(default)]
    heldout: Vec<RunFile>,
}

/// The most evaluations one tuning may spend per seed.
pub const MAX_BUDGET: usize = 100_000;

/// The most optimizer seeds one tuning may list.
pub const MAX_SEEDS: usize = 100;

/// Training-cost metrics that are times to enter or stay in a band: they jump when an error grazes the
/// band (a gust peaking at 0.099 m "recovers" in 0 s, one at 0.101 m in seconds), so an optimizer
/// rewards grazing, not rejection. A cost takes the continuous metrics instead (IAE, ITAE, peak, RMS);
/// these stay allowed as guard limits.
pub const BANDED_METRICS: [&str; 7] = [
    "max_settling_s",
    "gust_recovery_onset_s",
    "gust_recovery_release_s",
    "gust_within_5cm_s",
    "gust_within_10cm_s",
    "gust_within_20cm_s",
    "saturation_s",
];

/// A set of runs: one scenario (with the spec's changes) flown on each plant with each seed.
#[derive(Debug, Clone)]
pub struct RunSet {
    pub name: String,
    pub scenario: Scenario,
    /// `None`: the scenario's own plant.
    pub plants: Vec<Option<String>>,
    pub seeds: Vec<u64>,
    pub mode: ReferenceMode,
    /// The scenario's metric columns ([`table::metric_columns`]).
    pub columns: Vec<String>,
    /// (column, weight) of the training cost.
    pub cost: Vec<(usize, f64)>,
    /// (column, upper limit): a run over it, or where its event never came, is unsafe.
    pub limits: Vec<(usize, f64)>,
    /// The columns the held-out report shows.
    pub report: Vec<usize>,
}

impl RunSet {
    /// (plant, seed) of every run, plant-major.
    #[must_use]
    pub fn runs(&self) -> Vec<(Option<String>, u64)> {
        self.plants.iter().flat_map(|p| self.seeds.iter().map(move |s| (p.clone(), *s))).collect()
    }

    pub(super) fn plant_label(&self, plant: Option<&str>) -> String {
        plant.unwrap_or(&self.scenario.plant).to_owned()
    }
}

/// A validated tuning spec.
#[derive(Debug, Clone)]
pub struct Tune {
    pub name: String,
    pub description: String,
    pub controller: ControllerKind,
    /// Evaluations per seed.
    pub budget: usize,
    /// The optimizer's seeds, one whole search each, in the spec's order (distinct).
    pub seeds: Vec<u64>,
    pub rates: LoopRates,
    pub sigma0: f64,
    pub population: Option<usize>,
    /// The configuration the gains are set in: the autopilot's defaults with the spec's `[base]` over them.
    pub base: ControllerConfig,
    /// The spec's `[base]` as written (`{"mrac": {"feed_forward": true}}`; empty without one): part of
    /// every candidate's overrides and of the result's `[controller]` block.
    pub base_overrides: Value,
    pub gains: Vec<Gain>,
    pub train: Vec<RunSet>,
    pub guards: Vec<RunSet>,
    pub heldout: Vec<RunSet>,
}

impl Tune {
    /// Loads and validates a spec; scenario files are relative to the spec's directory. Every gain, run
    /// set, metric name and plant is checked here, before any run.
    ///
    /// # Errors
    /// An unreadable or malformed spec (unknown keys included, named), or a value that cannot be used.
    pub fn load(path: &Path) -> Result<Self, TuneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| TuneError::Io { path: path.display().to_string(), source })?;
        Self::from_toml(&text, path.parent().unwrap_or(Path::new(".")), &path.display().to_string())
    }

    /// Parses and validates a spec from text; `dir` resolves scenario files, `origin` names the text in
    /// errors.
    ///
    /// # Errors
    /// As [`Tune::load`].
    pub fn from_toml(text: &str, dir: &Path, origin: &str) -> Result<Self, TuneError> {
        let spec: SpecFile =
            toml::from_str(text).map_err(|e| TuneError::Parse { path: origin.to_owned(), source: Box::new(e) })?;
        Self::new(spec, dir)
    }

    fn new(spec: SpecFile, dir: &Path) -> Result<Self, TuneError> {
        if spec.budget == 0 || spec.budget > MAX_BUDGET {
            return invalid(format!("budget = {} must be in 1..={MAX_BUDGET} evaluations", spec.budget));
        }
        let seeds = match &spec.seed {
            SeedFile::One(seed) => vec![*seed],
            SeedFile::Many(seeds) => seeds.clone(),
        };
        if seeds.is_empty() || seeds.len() > MAX_SEEDS {
            return invalid(format!("seed: give one seed or a list of 1 to {MAX_SEEDS}, got {}", seeds.len()));
        }
        if let Some(dup) = seeds.iter().enumerate().find(|(i, s)| seeds[..*i].contains(s)) {
            return invalid(format!("seed: {} is listed twice (each seed is one whole search)", dup.1));
        }
        if spec.optimizer.kind != "cma-es" {
            return invalid(format!("optimizer.kind = `{}`: the one optimizer is \"cma-es\"", spec.optimizer.kind));
        }
        let sigma0 = spec.optimizer.sigma0;
        if !(sigma0.is_finite() && sigma0 > 0.0 && sigma0 <= 1.0) {
            return invalid(format!("optimizer.sigma0 = {sigma0} must be in (0, 1] (a fraction of each gain's range)"));
        }
        if spec.optimizer.population.is_some_and(|p| !(2..=1000).contains(&p)) {
            return invalid("optimizer.population must be in 2..=1000".into());
        }
        let mut rates = LoopRates::default();
        if let Some(hz) = spec.rate_hz {
            rates = LoopRates { inner_hz: hz, position_hz: hz / 5 };
        }
        rates.validate().map_err(|e| TuneError::Invalid(format!("rate_hz: {e}")))?;
        let (base, base_overrides) = parse_base(spec.base.as_ref(), spec.controller, rates)?;
        let declared: Vec<GainFile> = spec.controller.ty().gains().iter().map(GainFile::from).collect();
        let gain_files = if spec.gain.is_empty() { &declared } else { &spec.gain };
        if gain_files.is_empty() {
            return invalid(format!(
                "no [[gain]], and {} declares no tunable gains: name at least one gain to tune",
                spec.controller
            ));
        }
        let mut gains = Vec::new();
        for g in gain_files {
            let gain = parse_gain(g, spec.controller, rates, &base)?;
            if gains.iter().any(|o: &Gain| o.path == gain.path && overlap(&o.axes, &gain.axes)) {
                return invalid(format!("[[gain]] {} is given twice", gain.label));
            }
            gains.push(gain);
        }
        if spec.train.is_empty() {
            return invalid("no [[train]] run set: the cost needs at least one".into());
        }
        let mut train = Vec::new();
        for (i, r) in spec.train.iter().enumerate() {
            let set = parse_run_set(r, dir, &format!("train[{i}]"), rates)?;
            if set.cost.is_empty() {
                return invalid(format!(
                    "train[{i}] ({}): give its cost, e.g. cost = {{ cross_track_rms_m = 1.0 }}",
                    set.name
                ));
            }
            train.push(set);
        }
        let mut guards = Vec::new();
        for (i, r) in spec.guard.iter().enumerate() {
            let key = format!("guard[{i}]");
            if !r.cost.is_empty() {
                return invalid(format!("{key}: a guard has limits, not a cost"));
            }
            guards.push(parse_run_set(r, dir, &key, rates)?);
        }
        let mut heldout = Vec::new();
        for (i, r) in spec.heldout.iter().enumerate() {
            let key = format!("heldout[{i}]");
            if !r.cost.is_empty() {
                return invalid(format!("{key}: a held-out set has limits and a report, not a cost"));
            }
            heldout.push(parse_run_set(r, dir, &key, rates)?);
        }
        Ok(Self {
            name: spec.name,
            description: spec.description,
            controller: spec.controller,
            budget: spec.budget,
            seeds,
            rates,
            sigma0,
            population: spec.optimizer.population,
            base,
            base_overrides,
            gains,
            train,
            guards,
            heldout,
        })
    }
}

/// Whether two axis selections of one field share an element.
fn overlap(a: &Option<Vec<usize>>, b: &Option<Vec<usize>>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => a.iter().any(|x| b.contains(x)),
        _ => true,
    }
}

/// The spec's `[base]`: one table, the controller's (`mrac` for CA), whose keys are all fields of its
/// configuration; returns the defaults with it merged in, and the block as written.
fn parse_base(
    base: Option<&Value>,
    controller: ControllerKind,
    rates: LoopRates,
) -> Result<(ControllerConfig, Value), TuneError> {
    let defaults_config = with_table_defaults(&ControllerConfig::default(), controller);
    let Some(base) = base else { return Ok((defaults_config, Value::Object(serde_json::Map::new()))) };
    let table = table_name(controller);
    let root = base.as_object().ok_or_else(|| TuneError::Invalid("[base] must be a table".into()))?;
    if let Some(key) = root.keys().find(|k| *k != table) {
        return invalid(format!("[base.{key}]: the base of a {controller} tuning is its [base.{table}] alone"));
    }
    let defaults = serde_json::to_value(&defaults_config).map_err(|e| TuneError::Invalid(e.to_string()))?;
    check_known(base, &defaults, "base").map_err(TuneError::Invalid)?;
    let mut config: ControllerConfig =
        serde_json::from_value(merge(&defaults, base)).map_err(|e| TuneError::Invalid(format!("[base]: {e}")))?;
    config.rates = rates;
    config.validate().map_err(|e| TuneError::Invalid(format!("[base]: {e}")))?;
    config.rates = ControllerConfig::default().rates;
    Ok((config, base.clone()))
}

fn parse_run_set(r: &RunFile, dir: &Path, key: &str, rates: LoopRates) -> Result<RunSet, TuneError> {
    let mut scenario = sweep::load_scenario(&r.scenario, dir).map_err(|e| TuneError::Invalid(format!("{key}: {e}")))?;
    let name = r.name.clone().unwrap_or_else(|| scenario.name.clone());
    let key = format!("{key} ({name})");
    if let Some(speed) = r.speed_mps {
        match &mut scenario.reference {
            ReferenceSpec::Track(track) if speed.is_finite() && speed > 0.0 => track.speed_mps = speed,
            ReferenceSpec::Track(_) => return invalid(format!("{key}: speed_mps = {speed} must be finite and > 0")),
            _ => return invalid(format!("{key}: speed_mps needs a track scenario")),
        }
    }
    // Any of a track's modes, whether or not its scenario lists it (`figure8` flies with the jerk too).
    let mode = match r.mode {
        None => scenario.reference_modes()[0],
        Some(m) if matches!(scenario.reference, ReferenceSpec::Track(_)) => m,
        Some(_) => return invalid(format!("{key}: mode needs a track scenario")),
    };
    if let Some(d) = r.duration_s {
        if !(d.is_finite() && d > 0.0 && d <= 3600.0) {
            return invalid(format!("{key}: duration_s = {d} must be in (0, 3600]"));
        }
        scenario.duration_s = d;
    }
    for (param_name, &v) in &r.set {
        let param = Param::parse(param_name).map_err(|e| TuneError::Invalid(format!("{key}: set: {e}")))?;
        if param == Param::Seed {
            return invalid(format!("{key}: set.seed: give the seeds with `seeds`"));
        }
        if !v.is_finite() || (param.is_integer() && (v.fract() != 0.0 || v < 0.0)) {
            return invalid(format!("{key}: set.{param_name} = {v} is not a usable value"));
        }
        if matches!(param, Param::GustAmplitudeMps | Param::GustAzimuthDeg) && scenario.wind.gust.is_none() {
            return invalid(format!("{key}: set.{param_name} needs a scenario with a [wind.gust]"));
        }
        sweep::apply(&mut scenario, param, v, None).map_err(|e| TuneError::Invalid(format!("{key}: {e}")))?;
    }
    // The changed scenario must still be one the scenario format accepts.
    if let Some(w) = scenario.metric_windows.gust_peak_s.or(scenario.metric_windows.gust_rms_s)
        && w[0] >= scenario.duration_s
    {
        return invalid(format!("{key}: duration_s = {} ends before its metric windows", scenario.duration_s));
    }
    if let Some(g) = &scenario.wind.gust
        && scenario.metrics.contains(&crate::scenario::MetricKind::Gust)
        && g.release_s >= scenario.duration_s
    {
        return invalid(format!("{key}: duration_s = {} ends before the gust's release", scenario.duration_s));
    }
    if r.seeds.is_empty() {
        return invalid(format!("{key}: seeds must name at least one seed"));
    }
    let plants: Vec<Option<String>> =
        if r.plants.is_empty() { vec![None] } else { r.plants.iter().cloned().map(Some).collect() };
    for plant in &plants {
        let config = runner::plant_config(&scenario, plant.as_deref())
            .map_err(|e| TuneError::Invalid(format!("{key}: plant: {e}")))?;
        Plant::new(config, &InitialState::default(), 1)
            .map_err(|e| TuneError::Invalid(format!("{key}: plant: {e}")))?;
    }
    scenario.state_noise().map_err(|e| TuneError::Invalid(format!("{key}: {e}")))?;
    let mut base = scenario.controller.clone();
    base.rates = rates;
    base.validate().map_err(|e| TuneError::Invalid(format!("{key}: its [controller]: {e}")))?;
    let columns = table::metric_columns(&scenario);
    let column = |metric: &str, what: &str| {
        columns.iter().position(|c| c == metric).ok_or_else(|| {
            TuneError::Invalid(format!(
                "{key}: {what} has unknown metric `{metric}` (this scenario's: {})",
                columns.join(", ")
            ))
        })
    };
    let mut cost = Vec::new();
    for (metric, &w) in &r.cost {
        if !(w.is_finite() && w > 0.0) {
            return invalid(format!("{key}: cost.{metric} = {w}: a weight must be finite and > 0"));
        }
        if BANDED_METRICS.contains(&metric.as_str()) {
            return invalid(format!(
                "{key}: cost.{metric}: a banded time jumps when an error grazes its band, so a cost takes a \
                 continuous metric (e.g. gust_iae_onset_m_s, steps_iae_m_s, gust_peak_m); keep {metric} as a limit"
            ));
        }
        cost.push((column(metric, "cost")?, w));
    }
    let mut limits = Vec::new();
    for (metric, &l) in &r.limits {
        if !l.is_finite() {
            return invalid(format!("{key}: limits.{metric} = {l} must be finite"));
        }
        limits.push((column(metric, "limits")?, l));
    }
    let report = if r.report.is_empty() {
        let skip = ["weights_at_bounds", "non_finite", "pwm_activity_us"];
        (0..columns.len())
            .filter(|&i| {
                !skip.contains(&columns[i].as_str()) && !table::THRUST_TO_WEIGHT.contains(&columns[i].as_str())
            })
            .collect()
    } else {
        r.report.iter().map(|m| column(m, "report")).collect::<Result<_, _>>()?
    };
    Ok(RunSet { name, mode, scenario, plants, seeds: r.seeds.clone(), columns, cost, limits, report })
}
