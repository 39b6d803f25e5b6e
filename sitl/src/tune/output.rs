//! What `sitl tune` writes: the optimizer's trace (CSV), the result as a `[controller]` block and as an
//! autopilot parameter file, a result summary (JSON), and the held-out report (table, JSON, CSV). Every
//! number is the shortest decimal that reads back as the same float, so the files of two runs of one spec
//! compare byte for byte; every file is written to a temporary file and renamed into place.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{HeldOut, Outcome, Tune, TuneError};

/// A float as its shortest round-trip decimal.
#[must_use]
pub fn short(v: f64) -> String {
    format!("{v}")
}

/// A CSV cell: quoted when it holds a comma, a quote or a line break.
fn csv_cell(text: &str) -> String {
    if text.contains([',', '"', '\n']) { format!("\"{}\"", text.replace('"', "\"\"")) } else { text.to_owned() }
}

/// The trace: one row per evaluation, `evaluation,generation,<gains>,cost,penalised_cost,safe,violations`
/// (violations joined by `; `, empty when safe).
#[must_use]
pub fn trace_csv(tune: &Tune, outcome: &Outcome) -> String {
    let mut out = String::from("evaluation,generation");
    for g in &tune.gains {
        out.push(',');
        out.push_str(&csv_cell(&g.label));
    }
    out.push_str(",cost,penalised_cost,safe,violations\n");
    for e in &outcome.evaluations {
        let _ = write!(out, "{},{}", e.index, e.generation);
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
    pub seed: u64,
    pub budget: usize,
    pub evaluations: usize,
    pub gains: Vec<String>,
    pub start: Point,
    pub result: Point,
}

/// One evaluation in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct Point {
    pub evaluation: usize,
    pub gains: Vec<f64>,
    pub cost: f64,
    pub safe: bool,
    pub violations: Vec<String>,
}

impl Summary {
    #[must_use]
    pub fn of(tune: &Tune, outcome: &Outcome) -> Self {
        let point = |e: &super::Evaluated| Point {
            evaluation: e.index,
            gains: e.gains.clone(),
            cost: e.verdict.cost,
            safe: e.verdict.safe(),
            violations: e.verdict.violations.clone(),
        };
        Self {
            name: tune.name.clone(),
            controller: tune.controller.to_string(),
            seed: tune.seed,
            budget: tune.budget,
            evaluations: outcome.evaluations.len(),
            gains: tune.gains.iter().map(|g| g.label.clone()).collect(),
            start: point(outcome.start()),
            result: point(outcome.result()),
        }
    }

    /// The lines printed at the end of a tuning.
    #[must_use]
    pub fn text(&self) -> String {
        let mut s =
            format!("{} ({}): {} evaluations, seed {}\n", self.name, self.controller, self.evaluations, self.seed);
        for (label, p) in [("start", &self.start), ("result", &self.result)] {
            let _ = writeln!(
                s,
                "  {label:6} evaluation {:>4}: cost {:.6}  {}",
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
        s
    }
}

/// The held-out report as a table: per gain set and held-out set its report metrics, then the verdict.
#[must_use]
pub fn heldout_table(results: &[HeldOut]) -> String {
    let mut s = String::new();
    for r in results {
        let _ = writeln!(s, "{} [{}]: {}", r.gains, r.controller, if r.safe { "safe" } else { "UNSAFE" });
        for set in &r.sets {
            let metrics: Vec<String> = set
                .metrics
                .iter()
                .map(|(m, v)| format!("{m} {}", v.map_or_else(|| "never".to_owned(), |v| format!("{v:.4}"))))
                .collect();
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
    let io = |source| TuneError::Io { path: path.display().to_string(), source };
    let tmp = path.with_extension(format!("{}.tmp", path.extension().and_then(|e| e.to_str()).unwrap_or("")));
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

/// Writes a tuning's files into `dir`: `trace.csv`, `controller.toml`, `params.txt`, `result.json`.
/// Returns their paths.
///
/// # Errors
/// The file system's, or gains that make no configuration (not for an outcome of [`Tune::run`]).
pub fn write_tuning(dir: &Path, tune: &Tune, outcome: &Outcome) -> Result<Vec<PathBuf>, TuneError> {
    std::fs::create_dir_all(dir).map_err(|source| TuneError::Io { path: dir.display().to_string(), source })?;
    let result = outcome.result();
    let verdict = if result.verdict.safe() { "safe on every guard" } else { "UNSAFE: no evaluation kept every guard" };
    let header = format!(
        "sitl tune {name}: {controller}, evaluation {index} of {n} (seed {seed}), training cost {cost} \
         (start: {start}), {verdict}",
        name = tune.name,
        controller = tune.controller,
        index = result.index,
        n = outcome.evaluations.len(),
        seed = tune.seed,
        cost = short(result.verdict.cost),
        start = short(outcome.start().verdict.cost),
    );
    let invalid = |e: String| TuneError::Invalid(e);
    let block = tune.controller_block(&result.gains).map_err(invalid)?;
    let files = [
        ("trace.csv", trace_csv(tune, outcome)),
        ("controller.toml", format!("# {header}\n{block}")),
        ("params.txt", tune.param_file(&result.gains, &header).map_err(invalid)?),
        (
            "result.json",
            serde_json::to_string_pretty(&Summary::of(tune, outcome)).map_err(|e| invalid(e.to_string()))? + "\n",
        ),
    ];
    let mut written = Vec::new();
    for (name, text) in files {
        let path = dir.join(name);
        write_atomically(&path, text.as_bytes())?;
        written.push(path);
    }
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
