//! Gain tuning with guarded costs (`sitl tune SPEC.toml`): one controller, the gains to tune with their
//! bounds and scale, a training set of scenario runs with a weighted cost on their metrics, guard runs
//! whose limits a result must keep (overshoot, settling, weights at bounds, non-finite values), a CMA-ES
//! ([`cmaes`]) with a budget of evaluations and one or more seeds (a whole search per seed, each with the
//! whole budget, so a result's spread over seeds shows how much of it is luck), and a held-out set to
//! report on. The result is the best safe evaluation of any seed; a tuning in which no evaluation kept
//! every guard has no result ("no safe gains in N evaluations", with the guards that limited it), and
//! writes no gains to fly.
//!
//! Every evaluation flies its runs in-process in lockstep (the sweep's runner and metric columns,
//! [`crate::sweep::run_metric_values`]); a generation's candidates times their runs are flown in parallel
//! (rayon) and combined in index order, and all randomness is the optimizer's ChaCha8 from the spec's
//! seed, so the same spec gives the same trace bit for bit on any number of threads. Candidate gains are
//! rounded to f32, the precision of the autopilot's parameters, so the `[controller]` block and the
//! parameter file written for a result describe the same controller. The format is documented in
//! `docs/tuning.md`.

pub mod cmaes;
pub mod output;

use std::collections::BTreeMap;
use std::path::Path;

use autopilot::core::config::VehicleConfig;
use autopilot::core::control::{ControllerConfig, ControllerKind, LoopRates};
use autopilot::core::params::{Binding, PARAMS, ParamStore};
use rayon::prelude::*;
use serde::Deserialize;
use serde_json::Value;

use crate::plant::{InitialState, Plant};
use crate::scenario::reference::ReferenceSpec;
use crate::scenario::runner::{self, RunOptions};
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

fn invalid<T>(message: String) -> Result<T, TuneError> {
    Err(TuneError::Invalid(message))
}

/// A gain's search scale between its bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scale {
    /// Evenly in the value.
    #[default]
    Linear,
    /// Evenly in the logarithm (the bounds must be > 0): for gains spanning decades.
    Log,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct GainFile {
    name: String,
    #[serde(default)]
    axes: Option<Vec<usize>>,
    bounds: [f64; 2],
    #[serde(default)]
    scale: Scale,
    #[serde(default)]
    start: Option<f64>,
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

/// The penalised cost of an unsafe candidate starts here, above any safe cost the optimizer should meet.
pub const UNSAFE_COST: f64 = 1e6;

/// One gain under tuning.
#[derive(Debug, Clone, PartialEq)]
pub struct Gain {
    /// As written: `aco.kp_pos_per_s`, or with its axes `pid.k_rate_per_s[0,1]`.
    pub label: String,
    /// The `[controller]` path: `["aco", "kp_pos_per_s"]`.
    pub path: Vec<String>,
    /// The elements of an array field that take the value (`None`: a number field).
    pub axes: Option<Vec<usize>>,
    pub bounds: [f64; 2],
    pub scale: Scale,
    /// The start of the search: the spec's `start`, else the autopilot's default.
    pub start: f64,
    /// The autopilot parameters that carry this gain (empty: none does).
    pub params: Vec<&'static str>,
}

impl Gain {
    /// The gain at unit coordinate `x` in `[0, 1]`, rounded to f32.
    #[must_use]
    pub fn value_at(&self, x: f64) -> f64 {
        let [lo, hi] = self.bounds;
        let v = match self.scale {
            Scale::Linear => lo + x * (hi - lo),
            Scale::Log => (lo.ln() + x * (hi.ln() - lo.ln())).exp(),
        };
        f64::from(v.clamp(lo, hi) as f32)
    }

    /// The unit coordinate of value `v` (the inverse of [`Gain::value_at`] before rounding).
    #[must_use]
    pub fn unit_of(&self, v: f64) -> f64 {
        let [lo, hi] = self.bounds;
        match self.scale {
            Scale::Linear => (v - lo) / (hi - lo),
            Scale::Log => (v.ln() - lo.ln()) / (hi.ln() - lo.ln()),
        }
    }
}

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

    fn plant_label(&self, plant: Option<&str>) -> String {
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

/// What one candidate scored: its training cost, its guards' verdict and the cost the optimizer ranks.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The weighted training cost (mean over each set's runs, summed over sets).
    pub cost: f64,
    /// Every violated guard, as "set plant seed: why"; empty when safe.
    pub violations: Vec<String>,
    /// `cost` when safe, else [`UNSAFE_COST`] plus a measure of how far the guards are broken.
    pub penalised: f64,
}

impl Verdict {
    #[must_use]
    pub fn safe(&self) -> bool {
        self.violations.is_empty()
    }
}

/// The controller's `[controller]` table name.
#[must_use]
pub fn table_name(kind: ControllerKind) -> &'static str {
    match kind {
        ControllerKind::Aco => "aco",
        ControllerKind::Ca => "mrac",
        ControllerKind::Pid => "pid",
    }
}

/// The value at `path` of a JSON tree.
fn at<'a>(root: &'a Value, path: &[String]) -> Option<&'a Value> {
    path.iter().try_fold(root, |v, key| v.get(key))
}

fn at_mut<'a>(root: &'a mut Value, path: &[String]) -> Option<&'a mut Value> {
    path.iter().try_fold(root, |v, key| v.get_mut(key))
}

/// Sets a gain's value in a configuration's JSON tree.
fn set_gain(root: &mut Value, gain: &Gain, value: f64) -> Result<(), String> {
    let field = at_mut(root, &gain.path).ok_or_else(|| format!("{}: no such field", gain.label))?;
    match (&gain.axes, field) {
        (None, field @ Value::Number(_)) => *field = Value::from(value),
        (Some(axes), Value::Array(items)) => {
            for &a in axes {
                let item = items.get_mut(a).ok_or_else(|| format!("{}: no axis {a}", gain.label))?;
                *item = Value::from(value);
            }
        }
        _ => return Err(format!("{}: not a number field", gain.label)),
    }
    Ok(())
}

/// `config` with `values` (one per gain) set.
///
/// # Errors
/// A gain whose field is missing (not for a validated spec).
pub fn with_gains(config: &ControllerConfig, gains: &[Gain], values: &[f64]) -> Result<ControllerConfig, String> {
    let mut tree = serde_json::to_value(config).map_err(|e| e.to_string())?;
    for (gain, &v) in gains.iter().zip(values) {
        set_gain(&mut tree, gain, v)?;
    }
    serde_json::from_value(tree).map_err(|e| e.to_string())
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
        if spec.gain.is_empty() {
            return invalid("no [[gain]]: name at least one gain to tune".into());
        }
        let mut gains = Vec::new();
        for g in &spec.gain {
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

    /// The start point's gains.
    #[must_use]
    pub fn start(&self) -> Vec<f64> {
        self.gains.iter().map(|g| g.start).collect()
    }

    /// The gains of a unit point; the start point's own coordinates give the start values exactly.
    #[must_use]
    pub fn gains_at(&self, x: &[f64]) -> Vec<f64> {
        self.gains
            .iter()
            .zip(x)
            .map(|(g, &xi)| if xi.to_bits() == g.unit_of(g.start).to_bits() { g.start } else { g.value_at(xi) })
            .collect()
    }

    /// Scores each candidate (one gain vector each) on the training and guard sets, every run of every
    /// candidate in parallel on `pool`, combined in index order.
    #[must_use]
    pub fn evaluate(&self, candidates: &[Vec<f64>], pool: &rayon::ThreadPool) -> Vec<Verdict> {
        let sets: Vec<&RunSet> = self.train.iter().chain(&self.guards).collect();
        let mut jobs = Vec::new();
        for c in 0..candidates.len() {
            for (s, set) in sets.iter().enumerate() {
                for (plant, seed) in set.runs() {
                    jobs.push((c, s, plant, seed));
                }
            }
        }
        let configs: Vec<Result<GainSet, String>> = candidates
            .iter()
            .map(|values| {
                let config = with_gains(&self.base, &self.gains, values)?;
                GainSet::from_config(self.controller, &config, &self.gains, &self.base_overrides)
            })
            .collect();
        let results: Vec<Result<Vec<Option<f64>>, String>> = pool.install(|| {
            jobs.par_iter()
                .map(|(c, s, plant, seed)| match &configs[*c] {
                    Ok(gains) => fly(sets[*s], gains, plant.as_deref(), *seed, self.rates),
                    Err(e) => Err(e.clone()),
                })
                .collect()
        });
        let mut verdicts = Vec::with_capacity(candidates.len());
        let mut next = 0;
        for _ in candidates {
            let mut cost = 0.0;
            let mut violations = Vec::new();
            let mut excess = 0.0;
            for (s, set) in sets.iter().enumerate() {
                let mut set_cost = 0.0;
                let runs = set.runs();
                for (plant, seed) in &runs {
                    let label = format!("{} {} seed {seed}", set.name, set.plant_label(plant.as_deref()));
                    match &results[next] {
                        Ok(values) => {
                            if s < self.train.len() {
                                set_cost += run_cost(set, values);
                            }
                            for (why, amount) in check(set, values) {
                                violations.push(format!("{label}: {why}"));
                                excess += amount;
                            }
                        }
                        Err(e) => {
                            set_cost = f64::INFINITY;
                            violations.push(format!("{label}: cannot fly: {e}"));
                            excess += 1000.0;
                        }
                    }
                    next += 1;
                }
                cost += set_cost / runs.len() as f64;
            }
            if !cost.is_finite() && violations.is_empty() {
                violations.push("the training cost is not finite".into());
                excess += 1000.0;
            }
            let penalised = if violations.is_empty() { cost } else { UNSAFE_COST * (1.0 + excess) };
            verdicts.push(Verdict { cost, violations, penalised });
        }
        verdicts
    }

    /// Tunes: for each seed, the start point, then CMA-ES generations until the budget is spent.
    /// `progress` is told the number of evaluations done (over all seeds) after each generation.
    #[must_use]
    pub fn run(&self, pool: &rayon::ThreadPool, mut progress: impl FnMut(usize)) -> Tuning {
        let mut done = 0;
        let outcomes = self
            .seeds
            .iter()
            .map(|&seed| {
                let outcome = self.run_seed(seed, pool, |n| progress(done + n));
                done += outcome.evaluations.len();
                outcome
            })
            .collect();
        Tuning { outcomes }
    }

    /// One whole search from `seed`.
    fn run_seed(&self, seed: u64, pool: &rayon::ThreadPool, mut progress: impl FnMut(usize)) -> Outcome {
        let x0: Vec<f64> = self.gains.iter().map(|g| g.unit_of(g.start)).collect();
        let settings =
            cmaes::Settings { x0, sigma0: self.sigma0, population: self.population, budget: self.budget, seed };
        let mut verdicts: Vec<Verdict> = Vec::new();
        let trace = cmaes::minimize(&settings, |points| {
            let candidates: Vec<Vec<f64>> = points.iter().map(|x| self.gains_at(x)).collect();
            let scored = self.evaluate(&candidates, pool);
            let costs = scored.iter().map(|v| v.penalised).collect();
            verdicts.extend(scored);
            progress(verdicts.len());
            costs
        });
        let evaluations: Vec<Evaluated> = trace
            .into_iter()
            .zip(verdicts)
            .map(|(e, verdict)| Evaluated {
                index: e.index,
                generation: e.generation,
                gains: self.gains_at(&e.x),
                verdict,
            })
            .collect();
        // The best safe evaluation (lowest cost, then lowest index); if none is safe, the least unsafe.
        let rank = |e: &&Evaluated| (!e.verdict.safe(), e.verdict.penalised);
        let best = evaluations
            .iter()
            .min_by(|a, b| {
                let (ka, kb) = (rank(a), rank(b));
                ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1)).then(a.index.cmp(&b.index))
            })
            .map_or(0, |e| e.index);
        Outcome { seed, evaluations, best }
    }

    /// The `[controller]` block of gain values: the controller's table with every tuned field (an array
    /// field whole, its untuned axes at the autopilot's defaults), as TOML.
    ///
    /// # Errors
    /// Values that do not make a configuration (not for values from [`Tune::run`]).
    pub fn controller_block(&self, values: &[f64]) -> Result<String, String> {
        let config = with_gains(&self.base, &self.gains, values)?;
        let tree = serde_json::to_value(&config).map_err(|e| e.to_string())?;
        // The spec's [base] first, so the block flies the controller that was tuned.
        let mut table = match serde_json::from_value::<toml::Value>(self.base_overrides.clone()) {
            Ok(toml::Value::Table(t)) => t,
            Ok(_) | Err(_) => toml::map::Map::new(),
        };
        for gain in &self.gains {
            let Some(value) = at(&tree, &gain.path) else { continue };
            let value: toml::Value = serde_json::from_value(value.clone()).map_err(|e| e.to_string())?;
            let mut node = &mut table;
            for key in &gain.path[..gain.path.len() - 1] {
                let entry = node.entry(key.clone()).or_insert_with(|| toml::Value::Table(toml::map::Map::new()));
                let toml::Value::Table(inner) = entry else { return Err(format!("{}: not a table", gain.label)) };
                node = inner;
            }
            node.insert(gain.path[gain.path.len() - 1].clone(), value);
        }
        let mut root = toml::map::Map::new();
        root.insert("controller".into(), toml::Value::Table(table));
        toml::to_string(&toml::Value::Table(root)).map_err(|e| e.to_string())
    }

    /// The autopilot parameter file of gain values: `NAME<TAB>VALUE` for every parameter that differs from
    /// its default (the autopilot's `params.txt` format), after a comment naming any gain no parameter
    /// carries.
    ///
    /// # Errors
    /// As [`Tune::controller_block`].
    pub fn param_file(&self, values: &[f64], header: &str) -> Result<String, String> {
        let control = with_gains(&self.base, &self.gains, values)?;
        let vehicle = VehicleConfig { controller: self.controller, control, ..VehicleConfig::default() };
        let store = ParamStore::from_config(&vehicle);
        let mut out = String::new();
        for line in header.lines() {
            out.push_str("# ");
            out.push_str(line);
            out.push('\n');
        }
        let missing: Vec<&str> = self.gains.iter().filter(|g| g.params.is_empty()).map(|g| g.label.as_str()).collect();
        if !missing.is_empty() {
            out.push_str(&format!(
                "# No parameter carries {}: set them in the [controller] block (controller.toml).\n",
                missing.join(", ")
            ));
        }
        out.push_str(&store.to_text());
        Ok(out)
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
    let Some(base) = base else { return Ok((ControllerConfig::default(), Value::Object(serde_json::Map::new()))) };
    let table = table_name(controller);
    let root = base.as_object().ok_or_else(|| TuneError::Invalid("[base] must be a table".into()))?;
    if let Some(key) = root.keys().find(|k| *k != table) {
        return invalid(format!("[base.{key}]: the base of a {controller} tuning is its [base.{table}] alone"));
    }
    let defaults = serde_json::to_value(ControllerConfig::default()).map_err(|e| TuneError::Invalid(e.to_string()))?;
    check_known(base, &defaults, "base").map_err(TuneError::Invalid)?;
    let mut config: ControllerConfig =
        serde_json::from_value(merge(&defaults, base)).map_err(|e| TuneError::Invalid(format!("[base]: {e}")))?;
    config.rates = rates;
    config.validate().map_err(|e| TuneError::Invalid(format!("[base]: {e}")))?;
    config.rates = ControllerConfig::default().rates;
    Ok((config, base.clone()))
}

fn parse_gain(
    g: &GainFile,
    controller: ControllerKind,
    rates: LoopRates,
    base: &ControllerConfig,
) -> Result<Gain, TuneError> {
    let table = table_name(controller);
    let label = match &g.axes {
        Some(axes) => {
            format!("{}[{}]", g.name, axes.iter().map(ToString::to_string).collect::<Vec<_>>().join(","))
        }
        None => g.name.clone(),
    };
    let path: Vec<String> = g.name.split('.').map(str::to_owned).collect();
    if path.first().map(String::as_str) != Some(table) {
        return invalid(format!(
            "gain `{}`: a {controller} gain is under `{table}.` (as in the scenario's [controller.{table}])",
            g.name
        ));
    }
    let defaults = serde_json::to_value(base).map_err(|e| TuneError::Invalid(e.to_string()))?;
    let default = match (at(&defaults, &path), &g.axes) {
        (Some(Value::Number(n)), None) => n.as_f64(),
        (Some(Value::Array(items)), Some(axes)) => {
            if axes.is_empty() {
                return invalid(format!("gain `{label}`: axes must name at least one element"));
            }
            if let Some(a) = axes.iter().find(|&&a| a >= items.len()) {
                return invalid(format!("gain `{label}`: axis {a} is out of 0..{}", items.len()));
            }
            items[axes[0]].as_f64()
        }
        (Some(Value::Array(items)), None) => {
            return invalid(format!(
                "gain `{}` is an array of {}: say which elements take the value, e.g. axes = [0, 1]",
                g.name,
                items.len()
            ));
        }
        (Some(Value::Number(_)), Some(_)) => {
            return invalid(format!("gain `{}` is a number, not an array: drop `axes`", g.name));
        }
        (Some(_), _) => None,
        (None, _) => {
            let fields = at(&defaults, &path[..1]).and_then(Value::as_object).map(|o| {
                o.iter().filter(|(_, v)| v.is_number() || v.is_array()).map(|(k, _)| k.as_str()).collect::<Vec<_>>()
            });
            return invalid(format!(
                "unknown gain `{}` (the {table} fields: {})",
                g.name,
                fields.unwrap_or_default().join(", ")
            ));
        }
    };
    let Some(default) = default else {
        return invalid(format!("gain `{}` is not a number field", g.name));
    };
    let [lo, hi] = g.bounds;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return invalid(format!("gain `{label}`: bounds {:?} must be finite and ascending", g.bounds));
    }
    if g.scale == Scale::Log && lo <= 0.0 {
        return invalid(format!("gain `{label}`: a log scale needs bounds > 0, got {:?}", g.bounds));
    }
    let start = g.start.unwrap_or(default);
    if !(lo..=hi).contains(&start) {
        return invalid(format!(
            "gain `{label}`: the start {start}{} is outside its bounds {:?}",
            if g.start.is_some() { "" } else { " (the autopilot's default, or the spec's [base])" },
            g.bounds
        ));
    }
    let mut gain = Gain {
        label: label.clone(),
        path,
        axes: g.axes.clone(),
        bounds: g.bounds,
        scale: g.scale,
        start,
        params: vec![],
    };
    // Every value the search can take must make a configuration the controller accepts.
    for v in [lo, hi, start] {
        let mut config = with_gains(base, std::slice::from_ref(&gain), &[v]).map_err(TuneError::Invalid)?;
        config.rates = rates;
        if let Err(e) = config.validate() {
            return invalid(format!("gain `{label}` = {v} (within its bounds) makes no controller: {e}"));
        }
    }
    gain.params = carrying_params(&gain)?;
    Ok(gain)
}

/// The parameters that carry a gain: those whose value moves when the gain does; each must take every
/// value within the gain's bounds.
fn carrying_params(gain: &Gain) -> Result<Vec<&'static str>, TuneError> {
    let base = VehicleConfig::default();
    let [lo, hi] = gain.bounds;
    // A value other than the start, within the bounds, to see which parameters move with the gain.
    let probe = if gain.start < hi { 0.5 * (gain.start + hi) } else { 0.5 * (lo + gain.start) };
    let control = with_gains(&base.control, std::slice::from_ref(gain), &[probe]).map_err(TuneError::Invalid)?;
    let moved = VehicleConfig { control, ..base.clone() };
    let mut names = Vec::new();
    for d in PARAMS {
        let Binding::Config { get, .. } = d.binding else { continue };
        if get(&base).to_bits() == get(&moved).to_bits() {
            continue;
        }
        if (lo as f32) < d.min || (hi as f32) > d.max {
            return invalid(format!(
                "gain `{}`: bounds {:?} leave the range of its parameter {} [{}, {}]",
                gain.label, gain.bounds, d.name, d.min, d.max
            ));
        }
        names.push(d.name);
    }
    Ok(names)
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

/// One set of gains to fly: the controller and its configuration overrides (a JSON tree merged over each
/// scenario's `[controller]`).
#[derive(Debug, Clone, PartialEq)]
pub struct GainSet {
    pub label: String,
    pub controller: ControllerKind,
    /// The `[controller]` overrides as a JSON object (`{"aco": {"kp_pos_per_s": 0.8}}`).
    pub overrides: Value,
}

impl GainSet {
    /// The gains of a tuned candidate as overrides, over the spec's `[base]`.
    fn from_config(
        controller: ControllerKind,
        config: &ControllerConfig,
        gains: &[Gain],
        base: &Value,
    ) -> Result<Self, String> {
        let tree = serde_json::to_value(config).map_err(|e| e.to_string())?;
        let mut overrides = base.clone();
        for gain in gains {
            let value = at(&tree, &gain.path).cloned().ok_or_else(|| format!("{}: no such field", gain.label))?;
            let mut node = &mut overrides;
            for key in &gain.path[..gain.path.len() - 1] {
                node = node
                    .as_object_mut()
                    .ok_or("not a table")?
                    .entry(key.clone())
                    .or_insert_with(|| Value::Object(serde_json::Map::new()));
            }
            node.as_object_mut().ok_or("not a table")?.insert(gain.path[gain.path.len() - 1].clone(), value);
        }
        Ok(Self { label: String::new(), controller, overrides })
    }

    /// The autopilot's defaults of `controller`.
    #[must_use]
    pub fn defaults(controller: ControllerKind) -> Self {
        Self { label: format!("{controller} (defaults)"), controller, overrides: Value::Object(serde_json::Map::new()) }
    }

    /// A gain file: a `[controller]` block with exactly one controller's table (`aco`, `mrac` for CA, or
    /// `pid`), whose keys must all be fields of that controller's configuration.
    ///
    /// # Errors
    /// An unreadable or malformed file, none or several controller tables, or an unknown key (named).
    pub fn from_toml(text: &str, label: &str) -> Result<Self, TuneError> {
        let err = |message: String| TuneError::GainFile { path: label.to_owned(), message };
        let value: toml::Value = toml::from_str(text).map_err(|e| err(e.to_string()))?;
        let json: Value = serde_json::to_value(&value).map_err(|e| err(e.to_string()))?;
        let root = json.as_object().ok_or_else(|| err("not a table".into()))?;
        if let Some(key) = root.keys().find(|k| *k != "controller") {
            return Err(err(format!("unknown key `{key}`: a gain file holds one [controller] block")));
        }
        let block =
            root.get("controller").and_then(Value::as_object).ok_or_else(|| err("no [controller] block".into()))?;
        let kinds: Vec<ControllerKind> =
            ControllerKind::ALL.into_iter().filter(|k| block.contains_key(table_name(*k))).collect();
        let [controller] = kinds[..] else {
            return Err(err(
                "the [controller] block must hold exactly one of [controller.aco], [controller.mrac] (CA), \
                            [controller.pid]"
                    .into(),
            ));
        };
        let defaults = serde_json::to_value(ControllerConfig::default()).map_err(|e| err(e.to_string()))?;
        check_known(&Value::Object(block.clone()), &defaults, "controller").map_err(err)?;
        let config = merge(&defaults, &Value::Object(block.clone()));
        let config: ControllerConfig = serde_json::from_value(config).map_err(|e| err(e.to_string()))?;
        config.validate().map_err(|e| err(e.to_string()))?;
        Ok(Self { label: label.to_owned(), controller, overrides: Value::Object(block.clone()) })
    }

    /// The configuration of a scenario's run: its `[controller]` with these overrides and `rates`.
    ///
    /// # Errors
    /// Overrides that make no configuration the controller accepts.
    pub fn config(&self, scenario: &Scenario, rates: LoopRates) -> Result<ControllerConfig, String> {
        let base = serde_json::to_value(&scenario.controller).map_err(|e| e.to_string())?;
        let mut config: ControllerConfig =
            serde_json::from_value(merge(&base, &self.overrides)).map_err(|e| e.to_string())?;
        config.rates = rates;
        config.validate().map_err(|e| e.to_string())?;
        Ok(config)
    }
}

/// Every key of `value` must be in `known` (recursively into tables), else the error names its path.
fn check_known(value: &Value, known: &Value, path: &str) -> Result<(), String> {
    if let (Some(v), Some(k)) = (value.as_object(), known.as_object()) {
        for (key, inner) in v {
            let Some(known_inner) = k.get(key) else {
                return Err(format!("unknown key `{path}.{key}`"));
            };
            check_known(inner, known_inner, &format!("{path}.{key}"))?;
        }
    }
    Ok(())
}

/// `over` merged into `base`: tables key by key, anything else replaced.
fn merge(base: &Value, over: &Value) -> Value {
    match (base, over) {
        (Value::Object(b), Value::Object(o)) => {
            let mut out = b.clone();
            for (k, v) in o {
                let merged = out.get(k).map_or_else(|| v.clone(), |bv| merge(bv, v));
                out.insert(k.clone(), merged);
            }
            Value::Object(out)
        }
        (_, o) => o.clone(),
    }
}

/// Flies one run of a set with a gain set: the metric values of its row.
fn fly(
    set: &RunSet,
    gains: &GainSet,
    plant: Option<&str>,
    seed: u64,
    rates: LoopRates,
) -> Result<Vec<Option<f64>>, String> {
    let mut scenario = set.scenario.clone();
    scenario.controller = gains.config(&scenario, rates)?;
    let opts = RunOptions {
        controller: gains.controller,
        plant: plant.map(str::to_owned),
        seed,
        rates,
        mode: set.mode,
        trace_hz: 1,
    };
    sweep::run_metric_values(&scenario, &opts).map_err(|e| e.to_string())
}

/// A run's weighted cost; an event that never came counts as the whole run's duration.
fn run_cost(set: &RunSet, values: &[Option<f64>]) -> f64 {
    set.cost.iter().map(|&(i, w)| w * values[i].unwrap_or(set.scenario.duration_s)).sum()
}

/// The guards a run breaks, each with a measure of how far: non-finite values, LMS weights at their
/// bounds, and each limit (exceeded, or its event never came).
fn check(set: &RunSet, values: &[Option<f64>]) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    let flag = |name: &str| set.columns.iter().position(|c| c == name).and_then(|i| values[i]) == Some(1.0);
    if flag("non_finite") {
        out.push(("non-finite state or PWM".to_owned(), 1000.0));
    }
    if flag("weights_at_bounds") {
        out.push(("adaptive weights at their bounds".to_owned(), 10.0));
    }
    for &(i, limit) in &set.limits {
        let metric = &set.columns[i];
        match values[i] {
            None => out.push((format!("{metric} never (limit {limit})"), 10.0)),
            Some(v) if !v.is_finite() => out.push((format!("{metric} = {v} (limit {limit})"), 1000.0)),
            Some(v) if v > limit => {
                let excess = (v - limit) / limit.abs().max(1e-9);
                out.push((format!("{metric} = {v:.3} > {limit}"), 1.0 + excess.min(1000.0)));
            }
            Some(_) => {}
        }
    }
    out
}

/// One evaluation of a tuning: its place in the search, its gains and its verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluated {
    pub index: usize,
    pub generation: usize,
    pub gains: Vec<f64>,
    pub verdict: Verdict,
}

/// One seed's finished search.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The optimizer's seed.
    pub seed: u64,
    pub evaluations: Vec<Evaluated>,
    /// The index of this search's best: its best safe evaluation, or its least unsafe if none is safe.
    pub best: usize,
}

impl Outcome {
    /// This search's best: its best safe evaluation, or its least unsafe if none is safe.
    #[must_use]
    pub fn result(&self) -> &Evaluated {
        &self.evaluations[self.best]
    }

    /// The start point's evaluation (the autopilot's defaults unless the spec gives starts).
    #[must_use]
    pub fn start(&self) -> &Evaluated {
        &self.evaluations[0]
    }

    /// The lowest training cost among the safe evaluations up to each evaluation (`None` until the first
    /// safe one): the search's convergence curve.
    #[must_use]
    pub fn best_safe_cost_so_far(&self) -> Vec<Option<f64>> {
        let mut best: Option<f64> = None;
        self.evaluations
            .iter()
            .map(|e| {
                if e.verdict.safe() {
                    best = Some(best.map_or(e.verdict.cost, |b| b.min(e.verdict.cost)));
                }
                best
            })
            .collect()
    }
}

/// A finished tuning: one search per seed, in the spec's seed order.
#[derive(Debug, Clone, PartialEq)]
pub struct Tuning {
    pub outcomes: Vec<Outcome>,
}

/// A guard and how many of a tuning's evaluations broke it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Limiting {
    /// The guard as "set: metric" (plant and seed dropped, so one guard counts once per evaluation).
    pub guard: String,
    /// Evaluations that broke it, and all evaluations.
    pub broken_by: usize,
    pub of: usize,
}

impl Tuning {
    /// Every evaluation of every seed.
    #[must_use]
    pub fn evaluations(&self) -> usize {
        self.outcomes.iter().map(|o| o.evaluations.len()).sum()
    }

    /// The result: the best safe evaluation of any seed (lowest cost, then the earlier seed), with its
    /// search; `None` when no evaluation kept every guard.
    #[must_use]
    pub fn result(&self) -> Option<(&Outcome, &Evaluated)> {
        self.outcomes
            .iter()
            .map(|o| (o, o.result()))
            .filter(|(_, e)| e.verdict.safe())
            .min_by(|a, b| a.1.verdict.cost.total_cmp(&b.1.verdict.cost))
    }

    /// The least unsafe evaluation of any seed (for a tuning without a result: what came closest).
    #[must_use]
    pub fn least_unsafe(&self) -> (&Outcome, &Evaluated) {
        self.outcomes
            .iter()
            .map(|o| (o, o.result()))
            .min_by(|a, b| a.1.verdict.penalised.total_cmp(&b.1.verdict.penalised))
            .expect("a tuning has at least one seed")
    }

    /// The start point (the same gains in every search; the first seed's evaluation).
    #[must_use]
    pub fn start(&self) -> &Evaluated {
        self.outcomes[0].start()
    }

    /// For each training and guard set of `tune`, how many evaluations kept every limit of it (on every
    /// plant and seed) and the first that did: a set no evaluation kept is one this controller may not be
    /// able to keep at all, and a comparison should say so or change it.
    #[must_use]
    pub fn sets_kept(&self, tune: &Tune) -> Vec<SetKept> {
        tune.train
            .iter()
            .chain(&tune.guards)
            .map(|set| {
                let prefix = format!("{} ", set.name);
                let mut kept = self
                    .outcomes
                    .iter()
                    .flat_map(|o| o.evaluations.iter().map(move |e| (o.seed, e)))
                    .filter(|(_, e)| !e.verdict.violations.iter().any(|v| v.starts_with(&prefix)));
                let first = kept.next().map(|(seed, e)| (seed, e.index));
                SetKept {
                    set: set.name.clone(),
                    kept_by: usize::from(first.is_some()) + kept.count(),
                    of: self.evaluations(),
                    first,
                }
            })
            .collect()
    }

    /// The guards broken by the most evaluations, most first (ties by name), at most `n`.
    #[must_use]
    pub fn limiting(&self, n: usize) -> Vec<Limiting> {
        let mut counts: BTreeMap<String, usize> = BTreeMap::new();
        for e in self.outcomes.iter().flat_map(|o| &o.evaluations) {
            let mut guards: Vec<String> = e.verdict.violations.iter().map(|v| guard_of(v)).collect();
            guards.sort();
            guards.dedup();
            for g in guards {
                *counts.entry(g).or_default() += 1;
            }
        }
        let mut ranked: Vec<(String, usize)> = counts.into_iter().collect();
        ranked.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let of = self.evaluations();
        ranked.into_iter().take(n).map(|(guard, broken_by)| Limiting { guard, broken_by, of }).collect()
    }
}

/// A training or guard set and the evaluations that kept all its limits.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SetKept {
    pub set: String,
    pub kept_by: usize,
    pub of: usize,
    /// The first evaluation (seed, index) that kept it.
    pub first: Option<(u64, usize)>,
}

/// A violation ("set plant seed N: metric = v > limit") as its guard ("set: metric"): the set name, then
/// the metric's name (the first word after the colon when it names a metric column, else the reason
/// itself, e.g. "adaptive weights at their bounds").
fn guard_of(violation: &str) -> String {
    let (run, why) = violation.split_once(": ").unwrap_or((violation, ""));
    let set = run.split(' ').next().unwrap_or(run);
    let first = why.split([' ', '=']).next().unwrap_or(why);
    let metric = if first.contains('_') { first } else { why.split(':').next().unwrap_or(why) };
    format!("{set}: {metric}")
}

/// One gain set's held-out results: per set its report metrics (means over the runs; `None` where some
/// run's event never came) and every broken guard.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct HeldOut {
    pub gains: String,
    pub controller: String,
    pub safe: bool,
    pub violations: Vec<String>,
    pub sets: Vec<HeldOutSet>,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct HeldOutSet {
    pub name: String,
    pub runs: usize,
    pub metrics: BTreeMap<String, Option<f64>>,
    /// Every run's row: (plant, seed, metric values in `metrics`' report order).
    #[serde(skip)]
    pub rows: Vec<(String, u64, Vec<Option<f64>>)>,
}

impl Tune {
    /// Flies every gain set on the held-out sets (all runs in parallel on `pool`, combined in order).
    #[must_use]
    pub fn evaluate_heldout(&self, gain_sets: &[GainSet], pool: &rayon::ThreadPool) -> Vec<HeldOut> {
        let mut jobs = Vec::new();
        for g in 0..gain_sets.len() {
            for (s, set) in self.heldout.iter().enumerate() {
                for (plant, seed) in set.runs() {
                    jobs.push((g, s, plant, seed));
                }
            }
        }
        let results: Vec<Result<Vec<Option<f64>>, String>> = pool.install(|| {
            jobs.par_iter()
                .map(|(g, s, plant, seed)| fly(&self.heldout[*s], &gain_sets[*g], plant.as_deref(), *seed, self.rates))
                .collect()
        });
        let mut out = Vec::new();
        let mut next = 0;
        for gains in gain_sets {
            let mut violations = Vec::new();
            let mut sets = Vec::new();
            for set in &self.heldout {
                let mut rows = Vec::new();
                for (plant, seed) in set.runs() {
                    let plant_label = set.plant_label(plant.as_deref());
                    let label = format!("{} {plant_label} seed {seed}", set.name);
                    match &results[next] {
                        Ok(values) => {
                            violations.extend(check(set, values).into_iter().map(|(why, _)| format!("{label}: {why}")));
                            rows.push((plant_label, seed, set.report.iter().map(|&i| values[i]).collect::<Vec<_>>()));
                        }
                        Err(e) => violations.push(format!("{label}: cannot fly: {e}")),
                    }
                    next += 1;
                }
                let metrics = set
                    .report
                    .iter()
                    .enumerate()
                    .map(|(k, &i)| {
                        let values: Option<Vec<f64>> = rows.iter().map(|r| r.2[k]).collect();
                        let mean = values.filter(|v| !v.is_empty()).map(|v| v.iter().sum::<f64>() / v.len() as f64);
                        (set.columns[i].clone(), mean)
                    })
                    .collect();
                sets.push(HeldOutSet { name: set.name.clone(), runs: rows.len(), metrics, rows });
            }
            out.push(HeldOut {
                gains: gains.label.clone(),
                controller: gains.controller.to_string(),
                safe: violations.is_empty(),
                violations,
                sets,
            });
        }
        out
    }
}

#[cfg(test)]
mod tests;
