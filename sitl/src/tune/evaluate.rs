//! Evaluation: candidates and gain sets flown on the spec's run sets (in parallel, combined in index
//! order), their training costs, the guards' verdicts and penalised costs, and the held-out report.

use std::collections::BTreeMap;

use autopilot::core::control::LoopRates;
use rayon::prelude::*;

use super::gains::{GainSet, with_gains};
use super::spec::{RunSet, Tune};
use crate::scenario::runner::RunOptions;
use crate::sweep;

/// The penalised cost of an unsafe candidate starts here, above any safe cost the optimizer should meet.
pub const UNSAFE_COST: f64 = 1e6;

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

impl Tune {
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

/// A violation ("set plant seed N: metric = v > limit") as its guard ("set: metric"): the set name, then
/// the metric's name (the first word after the colon when it names a metric column, else the reason
/// itself, e.g. "adaptive weights at their bounds").
pub(super) fn guard_of(violation: &str) -> String {
    let (run, why) = violation.split_once(": ").unwrap_or((violation, ""));
    let set = run.split(' ').next().unwrap_or(run);
    let first = why.split([' ', '=']).next().unwrap_or(why);
    let metric = if first.contains('_') { first } else { why.split(':').next().unwrap_or(why) };
    format!("{set}: {metric}")
}

/// One gain set's held-out results: per set its report metrics, the mean over the runs and the worst run
/// (`None` where some run's event never came), and every broken guard.
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
    /// Per report metric, the mean over the set's runs.
    pub mean: BTreeMap<String, Option<f64>>,
    /// Per report metric, the worst of the set's runs: the largest value, or the smallest for a metric
    /// where more is better ([`more_is_better`]).
    pub worst: BTreeMap<String, Option<f64>>,
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
                let (mut mean, mut worst) = (BTreeMap::new(), BTreeMap::new());
                for (k, &i) in set.report.iter().enumerate() {
                    let name = &set.columns[i];
                    let (m, w) = mean_and_worst(name, rows.iter().map(|r| r.2[k]).collect());
                    mean.insert(name.clone(), m);
                    worst.insert(name.clone(), w);
                }
                sets.push(HeldOutSet { name: set.name.clone(), runs: rows.len(), mean, worst, rows });
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

/// A metric's mean over runs and its worst run; both `None` when there is no run or some run's event never
/// came (an absent value is the worst, and has no mean).
#[must_use]
pub fn mean_and_worst(metric: &str, values: Option<Vec<f64>>) -> (Option<f64>, Option<f64>) {
    match values {
        Some(v) if !v.is_empty() => {
            let pick = if more_is_better(metric) { f64::min } else { f64::max };
            (Some(v.iter().sum::<f64>() / v.len() as f64), v.iter().copied().reduce(pick))
        }
        _ => (None, None),
    }
}

/// Whether more of a metric is better (the time spent within a band, the thrust-to-weight ratios): its
/// worst run is then the smallest value. Every other report metric (errors, overshoot, settling and
/// recovery times, integrals) is worse when larger.
#[must_use]
pub fn more_is_better(metric: &str) -> bool {
    metric.contains("_within_") || metric.starts_with("thrust_to_weight")
}
