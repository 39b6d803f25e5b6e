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
//!
//! The spec and its validation are `spec`, the gain vector and gain sets `gains`, the costs, guards and
//! held-out runs `evaluate`; this module is the optimizer loop and what a tuning found (`output` writes it).

pub mod cmaes;
mod evaluate;
mod gains;
pub mod output;
mod spec;

pub use evaluate::{HeldOut, HeldOutSet, UNSAFE_COST, Verdict};
pub use gains::{Gain, GainSet, table_name, with_gains};
pub use spec::{BANDED_METRICS, MAX_BUDGET, MAX_SEEDS, RunSet, Scale, Tune, TuneError};

use std::collections::BTreeMap;

use evaluate::guard_of;

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

impl Tune {
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
}

#[cfg(test)]
mod tests;
