//! What `sitl tune` writes: the optimizer's trace (CSV, every seed), the result as a `[controller]` block
//! and as an autopilot parameter file (only when some evaluation was safe: otherwise the least unsafe
//! gains go to `least-unsafe.toml`, for inspection, never to be flown as "tuned"), a result summary
//! (JSON), the convergence curves (SVG and PNG), and the held-out report (table, JSON, CSV). Every
//! number is the shortest decimal that reads back as the same float, so the files of two runs of one spec
//! compare byte for byte; every file is written to a temporary file and renamed into place.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{Evaluated, HeldOut, Limiting, Outcome, SetKept, Tune, TuneError, Tuning};
use crate::scenario::plot;

/// A float as its shortest round-trip decimal.
#[must_use]
pub fn short(v: f64) -> String {
    format!("{v}")
}

/// A CSV cell: quoted when it holds a comma, a quote or a line break.
fn csv_cell(text: &str) -> String {
    if text.contains([',', '"', '\n']) { format!("\"{}\"", text.replace('"', "\"\"")) } else { text.to_owned() }
}

/// The trace: one row per evaluation of every seed,
/// `seed,evaluation,generation,<gains>,cost,penalised_cost,safe,violations` (violations joined by `; `,
/// empty when safe).
#[must_use]
pub fn trace_csv(tune: &Tune, tuning: &Tuning) -> String {
    let mut out = String::from("seed,evaluation,generation");
    for g in &tune.gains {
        out.push(',');
        out.push_str(&csv_cell(&g.label));
    }
    out.push_str(",cost,penalised_cost,safe,violations\n");
    for (seed, e) in tuning.outcomes.iter().flat_map(|o| o.evaluations.iter().map(|e| (o.seed, e))) {
        let _ = write!(out, "{seed},{},{}", e.index, e.generation);
        for v in &e.gains {
            let _ = write!(out, ",{}", short(*v));
        }
        let v = &e.verdict;
        let _ = writeln!(
            out,
            ",{},{},{},{}",
            short(v.cost),
            short(v.penalised),
            u8::from(v.safe()),
            csv_cell(&v.violations.join("; "))
        );
    }
    out
}

/// The result summary (`result.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub name: String,
    pub controller: String,
    /// The optimizer's seeds, one whole search each.
    pub seeds: Vec<u64>,
    /// Evaluations per seed.
    pub budget: usize,
    /// Evaluations over every seed.
    pub evaluations: usize,
    /// "tuned" when some evaluation kept every guard, else "no safe gains in N evaluations".
    pub verdict: String,
    pub gains: Vec<String>,
    pub start: Point,
    /// The best safe evaluation of any seed; `None`: no safe gains.
    pub result: Option<Point>,
    /// Without a result: the least unsafe evaluation (not a tuning result; never to be flown as one).
    pub least_unsafe: Option<Point>,
    /// Each seed's search: its best safe cost (`None`: none safe) and when it was found.
    pub per_seed: Vec<SeedSummary>,
    /// The best safe costs of the seeds that found one: least, median, greatest.
    pub spread: Option<[f64; 3]>,
    /// The guards broken by the most evaluations.
    pub limiting: Vec<Limiting>,
    /// Per training and guard set, the evaluations that kept all its limits (a set none kept may be
    /// beyond this controller).
    pub sets_kept: Vec<SetKept>,
}

/// One evaluation in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct Point {
    pub seed: u64,
    pub evaluation: usize,
    pub gains: Vec<f64>,
    pub cost: f64,
    pub safe: bool,
    pub violations: Vec<String>,
}

/// One seed's search in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct SeedSummary {
    pub seed: u64,
    pub best_safe_cost: Option<f64>,
    pub best_evaluation: usize,
    pub safe_evaluations: usize,
}

fn point(seed: u64, e: &Evaluated) -> Point {
    Point {
        seed,
        evaluation: e.index,
        gains: e.gains.clone(),
        cost: e.verdict.cost,
        safe: e.verdict.safe(),
        violations: e.verdict.violations.clone(),
    }
}

/// "no safe gains in N evaluations".
#[must_use]
pub fn no_safe_gains(evaluations: usize) -> String {
    format!("no safe gains in {evaluations} evaluations")
}

impl Summary {
    #[must_use]
    pub fn of(tune: &Tune, tuning: &Tuning) -> Self {
        let result = tuning.result().map(|(o, e)| point(o.seed, e));
        let least_unsafe = result.is_none().then(|| {
            let (o, e) = tuning.least_unsafe();
            point(o.seed, e)
        });
        let per_seed: Vec<SeedSummary> = tuning
            .outcomes
            .iter()
            .map(|o: &Outcome| SeedSummary {
                seed: o.seed,
                best_safe_cost: o.result().verdict.safe().then_some(o.result().verdict.cost),
                best_evaluation: o.best,
                safe_evaluations: o.evaluations.iter().filter(|e| e.verdict.safe()).count(),
            })
            .collect();
        let mut costs: Vec<f64> = per_seed.iter().filter_map(|s| s.best_safe_cost).collect();
        costs.sort_by(f64::total_cmp);
        let spread = (!costs.is_empty()).then(|| [costs[0], costs[(costs.len() - 1) / 2], costs[costs.len() - 1]]);
        let evaluations = tuning.evaluations();
        Self {
            name: tune.name.clone(),
            controller: tune.controller.to_string(),
            seeds: tune.seeds.clone(),
            budget: tune.budget,
            evaluations,
            verdict: if result.is_some() { "tuned".to_owned() } else { no_safe_gains(evaluations) },
            gains: tune.gains.iter().map(|g| g.label.clone()).collect(),
            start: point(tuning.outcomes[0].seed, tuning.start()),
            result,
            least_unsafe,
            per_seed,
            spread,
            limiting: tuning.limiting(3),
            sets_kept: tuning.sets_kept(tune),
        }
    }

    /// The lines printed at the end of a tuning.
    #[must_use]
    pub fn text(&self) -> String {
        let seeds: Vec<String> = self.seeds.iter().map(u64::to_string).collect();
        let mut s = format!(
            "{} ({}): {} evaluations ({} per seed, seed{} {}): {}\n",
            self.name,
            self.controller,
            self.evaluations,
            self.budget,
            if self.seeds.len() == 1 { "" } else { "s" },
            seeds.join(", "),
            self.verdict
        );
        let mut points = vec![("start", &self.start)];
        points.extend(self.result.iter().map(|p| ("result", p)));
        points.extend(self.least_unsafe.iter().map(|p| ("least unsafe", p)));
        for (label, p) in points {
            let _ = writeln!(
                s,
                "  {label:12} seed {} evaluation {:>4}: cost {:.6}  {}",
                p.seed,
                p.evaluation,
                p.cost,
                if p.safe { "safe".to_owned() } else { format!("UNSAFE ({} guards broken)", p.violations.len()) }
            );
            let gains: Vec<String> =
                self.gains.iter().zip(&p.gains).map(|(g, v)| format!("{g} = {}", short(*v))).collect();
            let _ = writeln!(s, "    {}", gains.join(", "));
            for v in p.violations.iter().take(5) {
                let _ = writeln!(s, "    unsafe: {v}");
            }
            if p.violations.len() > 5 {
                let _ = writeln!(s, "    ... and {} more", p.violations.len() - 5);
            }
        }
        for seed in &self.per_seed {
            let best = seed.best_safe_cost.map_or_else(|| "none safe".to_owned(), |c| format!("best safe cost {c:.6}"));
            let _ = writeln!(
                s,
                "  seed {}: {best} ({} of {} evaluations safe)",
                seed.seed, seed.safe_evaluations, self.budget
            );
        }
        if let Some([lo, mid, hi]) = self.spread {
            let _ = writeln!(
                s,
                "  spread of the seeds' best safe costs: {lo:.6} / {mid:.6} / {hi:.6} (least / median / greatest)"
            );
        }
        for l in &self.limiting {
            let _ = writeln!(s, "  limiting: {} broken by {} of {} evaluations", l.guard, l.broken_by, l.of);
        }
        for k in &self.sets_kept {
            let first = k.first.map_or_else(String::new, |(seed, i)| format!(", first seed {seed} evaluation {i}"));
            let _ = writeln!(s, "  set {} kept by {} of {} evaluations{first}", k.set, k.kept_by, k.of);
        }
        s
    }
}

/// The held-out report as a table: per gain set and held-out set its report metrics, each the mean over
/// the set's runs with the worst run beside it, then the verdict.
#[must_use]
pub fn heldout_table(results: &[HeldOut]) -> String {
    let mut s = String::new();
    for r in results {
        let _ = writeln!(s, "{} [{}]: {}", r.gains, r.controller, if r.safe { "safe" } else { "UNSAFE" });
        for set in &r.sets {
            let value = |v: &Option<f64>| v.map_or_else(|| "never".to_owned(), |v| format!("{v:.4}"));
            let metrics: Vec<String> =
                set.mean.iter().map(|(m, v)| format!("{m} {} (worst {})", value(v), value(&set.worst[m]))).collect();
            let _ = writeln!(s, "  {:28} {}", set.name, metrics.join("  "));
        }
        for v in &r.violations {
            let _ = writeln!(s, "  unsafe: {v}");
        }
    }
    s
}

/// The held-out rows as CSV, long form: `gains,controller,set,plant,seed,metric,value` (an empty value:
/// the event never came), one row per run and report metric.
#[must_use]
pub fn heldout_csv(tune: &Tune, results: &[HeldOut]) -> String {
    let mut out = String::from("gains,controller,set,plant,seed,metric,value\n");
    for r in results {
        for (set, spec) in r.sets.iter().zip(&tune.heldout) {
            for (plant, seed, values) in &set.rows {
                for (&i, v) in spec.report.iter().zip(values) {
                    let _ = writeln!(
                        out,
                        "{},{},{},{},{seed},{},{}",
                        csv_cell(&r.gains),
                        r.controller,
                        csv_cell(&set.name),
                        csv_cell(plant),
                        spec.columns[i],
                        v.map_or_else(String::new, short)
                    );
                }
            }
        }
    }
    out
}

/// Writes via a temporary file and a rename, so a reader never sees a half-written file.
///
/// # Errors
/// The file system's.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), TuneError> {
    autopilot::runtime::persist::write_file_atomically(path, bytes)
        .map_err(|source| TuneError::Io { path: path.display().to_string(), source })
}

/// The convergence figure of a tuning (`path` PNG and its `.svg`): per seed, the best safe training cost
/// found so far against the evaluation, on a log10 scale; a seed with no safe evaluation draws nothing
/// and says so in the legend.
///
/// # Errors
/// A drawing failure (e.g. the directory is not writable).
pub fn convergence_figure(path: &Path, tune: &Tune, tuning: &Tuning) -> Result<(), TuneError> {
    let curves: Vec<(String, Vec<(f64, f64)>)> = tuning
        .outcomes
        .iter()
        .map(|o| {
            let points: Vec<(f64, f64)> = o
                .best_safe_cost_so_far()
                .into_iter()
                .enumerate()
                .filter_map(|(i, c)| c.filter(|c| *c > 0.0).map(|c| (i as f64, c.log10())))
                .collect();
            let label =
                if points.is_empty() { format!("seed {} (none safe)", o.seed) } else { format!("seed {}", o.seed) };
            (label, points)
        })
        .collect();
    let verdict = if tuning.result().is_some() { "tuned".to_owned() } else { no_safe_gains(tuning.evaluations()) };
    let title = format!("sitl tune {} ({}): best safe training cost so far, {verdict}", tune.name, tune.controller);
    plot::convergence(path, &title, "evaluation", "log10 best safe training cost", &curves)
        .map_err(|e| TuneError::Invalid(format!("{}: {e}", path.display())))
}

/// Writes a tuning's files into `dir`: `trace.csv`, `result.json`, `convergence.svg` and `.png`, and
/// either `controller.toml` and `params.txt` (the result) or, with no safe gains, `least-unsafe.toml`
/// (any `controller.toml` and `params.txt` of an earlier tuning there are removed, so nothing stale is
/// flown as tuned). Returns the paths written.
///
/// # Errors
/// The file system's, or gains that make no configuration (not for a tuning from [`Tune::run`]).
pub fn write_tuning(dir: &Path, tune: &Tune, tuning: &Tuning) -> Result<Vec<PathBuf>, TuneError> {
    std::fs::create_dir_all(dir).map_err(|source| TuneError::Io { path: dir.display().to_string(), source })?;
    let n = tuning.evaluations();
    let seeds: Vec<String> = tune.seeds.iter().map(u64::to_string).collect();
    let header = |seed: u64, e: &Evaluated, verdict: &str| {
        format!(
            "sitl tune {name}: {controller}, seed {seed} evaluation {index} ({n} evaluations over seeds {seeds}), \
             training cost {cost} (start: {start}), {verdict}",
            name = tune.name,
            controller = tune.controller,
            index = e.index,
            seeds = seeds.join(", "),
            cost = short(e.verdict.cost),
            start = short(tuning.start().verdict.cost),
        )
    };
    let invalid = |e: String| TuneError::Invalid(e);
    let mut files = vec![
        ("trace.csv", trace_csv(tune, tuning)),
        (
            "result.json",
            serde_json::to_string_pretty(&Summary::of(tune, tuning)).map_err(|e| invalid(e.to_string()))? + "\n",
        ),
    ];
    let stale: &[&str] = if let Some((o, e)) = tuning.result() {
        let header = header(o.seed, e, "safe on every guard");
        files.push(("controller.toml", format!("# {header}\n{}", tune.controller_block(&e.gains).map_err(invalid)?)));
        files.push(("params.txt", tune.param_file(&e.gains, &header).map_err(invalid)?));
        &["least-unsafe.toml"]
    } else {
        let (o, e) = tuning.least_unsafe();
        let header = header(o.seed, e, &format!("{}: the least unsafe, NOT a tuning result", no_safe_gains(n)));
        files.push(("least-unsafe.toml", format!("# {header}\n{}", tune.controller_block(&e.gains).map_err(invalid)?)));
        &["controller.toml", "params.txt"]
    };
    for name in stale {
        match std::fs::remove_file(dir.join(name)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(TuneError::Io { path: dir.join(name).display().to_string(), source: e });
            }
            _ => {}
        }
    }
    let mut written = Vec::new();
    for (name, text) in files {
        let path = dir.join(name);
        write_atomically(&path, text.as_bytes())?;
        written.push(path);
    }
    let figure = dir.join("convergence.png");
    convergence_figure(&figure, tune, tuning)?;
    written.extend([figure.with_extension("svg"), figure]);
    Ok(written)
}

/// Writes the held-out report into `dir`: `heldout.json`, `heldout.csv`, `heldout.txt` (the table).
///
/// # Errors
/// The file system's.
pub fn write_heldout(dir: &Path, tune: &Tune, results: &[HeldOut]) -> Result<Vec<PathBuf>, TuneError> {
    std::fs::create_dir_all(dir).map_err(|source| TuneError::Io { path: dir.display().to_string(), source })?;
    let json = serde_json::to_string_pretty(results).map_err(|e| TuneError::Invalid(e.to_string()))? + "\n";
    let mut written = Vec::new();
    for (name, text) in
        [("heldout.json", json), ("heldout.csv", heldout_csv(tune, results)), ("heldout.txt", heldout_table(results))]
    {
        let path = dir.join(name);
        write_atomically(&path, text.as_bytes())?;
        written.push(path);
    }
    Ok(written)
}
