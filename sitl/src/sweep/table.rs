//! A sweep's results: one row per run as CSV (shortest round-trip decimals, so a value read back is
//! the same float bit for bit), the merge of shards, and the per-controller robustness summary
//! (percentiles of each metric, the fraction of runs within each bound).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use autopilot::core::control::ControllerKind;
use serde::Serialize;

use super::{Sweep, SweepError};
use crate::scenario::runner::RunMetrics;
use crate::scenario::{MetricKind, ReferenceSpec, Scenario};

/// One run's row: which run, its case's values, and its metrics (`None`: never happened, e.g. a
/// recovery that never came, or a group this scenario does not compute).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub run: u64,
    pub case: u64,
    pub controller: ControllerKind,
    pub seed: u64,
    pub params: Vec<f64>,
    pub metrics: Vec<Option<f64>>,
}

const GUST_COLUMNS: [&str; 13] = [
    "gust_recovery_onset_s",
    "gust_recovery_release_s",
    "gust_peak_m",
    "gust_rms_xy_m",
    "gust_steady_err_m",
    "gust_rms_z_m",
    "gust_iae_onset_m_s",
    "gust_iae_release_m_s",
    "gust_itae_onset_m_s2",
    "gust_itae_release_m_s2",
    "gust_within_5cm_s",
    "gust_within_10cm_s",
    "gust_within_20cm_s",
];
const TRACK_COLUMNS: [&str; 4] = ["cross_track_rms_m", "cross_track_max_m", "alt_rms_m", "cross_track_iae_m_s"];
const FAULT_COLUMNS: [&str; 9] = [
    "fault_peak_position_error_m",
    "fault_peak_tilt_rad",
    "fault_peak_yaw_error_rad",
    "fault_iae_m_s",
    "fault_altitude_drop_m",
    "fault_recovery_s",
    "fault_within_0_3_m",
    "fault_lost_control",
    "fault_final_error_m",
];
const COMMON_COLUMNS: [&str; 6] = [
    "weights_at_bounds",
    "non_finite",
    "pwm_activity_us",
    "effort_pwm_sq_us2_s",
    "pwm_rate_mean_us_per_s",
    "saturation_s",
];
/// The case's airframe: its total lift with every rotor at full PWM, and at the least PWM, over its
/// weight. The paper's lift curve spans only 11.28-14.48 N a rotor, so at `thrust_scale` 1 an airframe
/// of more than 5.90 kg cannot hover (max under 1) and one of less than 4.60 kg cannot descend (min
/// over 1), whatever the controller does.
pub const THRUST_TO_WEIGHT: [&str; 2] = ["max_thrust_to_weight", "min_thrust_to_weight"];

/// The step axes' RMS column names of a scenario (with their unit).
fn step_rms_columns(scenario: &Scenario) -> [&'static str; 3] {
    match scenario.reference {
        ReferenceSpec::Attitude { .. } => ["rms_roll_rad", "rms_pitch_rad", "rms_yaw_rad"],
        ReferenceSpec::Rates { .. } => ["rms_p_radps", "rms_q_radps", "rms_r_radps"],
        _ => ["rms_n_m", "rms_e_m", "rms_d_m"],
    }
}

/// The step segments' summed IAE and ITAE column names of a scenario (with their unit).
fn step_integral_columns(scenario: &Scenario) -> [&'static str; 2] {
    match scenario.reference {
        ReferenceSpec::Attitude { .. } => ["steps_iae_rad_s", "steps_itae_rad_s2"],
        ReferenceSpec::Rates { .. } => ["steps_iae_rad", "steps_itae_rad_s"],
        _ => ["steps_iae_m_s", "steps_itae_m_s2"],
    }
}

/// The metric columns of a scenario's rows, in order.
#[must_use]
pub fn metric_columns(scenario: &Scenario) -> Vec<String> {
    let mut columns: Vec<&str> = THRUST_TO_WEIGHT.to_vec();
    if scenario.metrics.contains(&MetricKind::Steps) {
        columns.extend(["max_overshoot_pct", "max_settling_s"]);
        columns.extend(step_rms_columns(scenario));
        columns.extend(step_integral_columns(scenario));
    }
    if scenario.metrics.contains(&MetricKind::Gust) {
        columns.extend(GUST_COLUMNS);
    }
    if scenario.metrics.contains(&MetricKind::Track) {
        columns.extend(TRACK_COLUMNS);
    }
    if scenario.metrics.contains(&MetricKind::Fault) {
        columns.extend(FAULT_COLUMNS);
    }
    columns.extend(COMMON_COLUMNS);
    columns.into_iter().map(str::to_owned).collect()
}

/// A run's metrics in [`metric_columns`] order. A step that never settled makes `max_settling_s` empty.
#[must_use]
pub fn metric_values(scenario: &Scenario, thrust_to_weight: [f64; 2], m: &RunMetrics) -> Vec<Option<f64>> {
    let mut v: Vec<Option<f64>> = thrust_to_weight.iter().copied().map(Some).collect();
    if scenario.metrics.contains(&MetricKind::Steps) {
        let segments = m.segments.as_deref().unwrap_or_default();
        v.push(Some(segments.iter().map(|s| s.overshoot_pct).fold(0.0, f64::max)));
        v.push(segments.iter().try_fold(0.0, |worst: f64, s| s.settling_s.map(|t| worst.max(t))));
        let rms = m.rms.as_ref();
        let axes = match scenario.reference {
            ReferenceSpec::Attitude { .. } => ["roll", "pitch", "yaw"],
            ReferenceSpec::Rates { .. } => ["p", "q", "r"],
            _ => ["n", "e", "d"],
        };
        v.extend(axes.iter().map(|a| rms.and_then(|r| r.get(a).copied())));
        v.push(Some(segments.iter().map(|s| s.iae).sum()));
        v.push(Some(segments.iter().map(|s| s.itae).sum()));
    }
    if scenario.metrics.contains(&MetricKind::Gust) {
        let g = m.gust.as_ref();
        v.push(g.and_then(|g| g.recovery_onset_s));
        v.push(g.and_then(|g| g.recovery_release_s));
        v.extend([g.map(|g| g.peak_m), g.map(|g| g.rms_xy_m), g.map(|g| g.steady_err_m), g.map(|g| g.rms_z_m)]);
        v.extend([g.map(|g| g.iae_onset_m_s), g.map(|g| g.iae_release_m_s)]);
        v.extend([g.map(|g| g.itae_onset_m_s2), g.map(|g| g.itae_release_m_s2)]);
        v.extend([g.map(|g| g.within_5cm_s), g.map(|g| g.within_10cm_s), g.map(|g| g.within_20cm_s)]);
    }
    if scenario.metrics.contains(&MetricKind::Track) {
        let t = m.track.as_ref();
        v.extend([t.map(|t| t.cross_track_rms_m), t.map(|t| t.cross_track_max_m), t.map(|t| t.alt_rms_m)]);
        v.push(t.map(|t| t.cross_track_iae_m_s));
    }
    if scenario.metrics.contains(&MetricKind::Fault) {
        let f = m.fault.as_ref();
        let flag = |b: bool| f64::from(u8::from(b));
        v.extend([f.map(|f| f.peak_position_error_m), f.map(|f| f.peak_tilt_rad), f.map(|f| f.peak_yaw_error_rad)]);
        v.extend([f.map(|f| f.iae_m_s), f.map(|f| f.altitude_drop_m), f.and_then(|f| f.recovery_s)]);
        v.extend([f.map(|f| flag(f.within_0_3_m)), f.map(|f| flag(f.lost_control)), f.map(|f| f.final_error_m)]);
    }
    v.push(Some(f64::from(u8::from(m.weights_at_bounds))));
    v.push(Some(f64::from(u8::from(m.non_finite))));
    v.push(Some(m.pwm_activity_us));
    let e = &m.effort;
    v.extend([Some(e.pwm_dev_sq_us2_s), Some(e.pwm_rate_mean_us_per_s), Some(e.saturation_s)]);
    v
}

/// The rows' header: run, case, controller, seed, the varied values, the metrics.
#[must_use]
pub fn header(sweep: &Sweep) -> Vec<String> {
    let mut h: Vec<String> = ["run", "case", "controller", "seed"].map(str::to_owned).to_vec();
    h.extend(sweep.param_names().iter().map(|s| (*s).to_owned()));
    h.extend(sweep.metric_columns());
    h
}

/// A float as its shortest round-trip decimal (never an exponent); `None` as an empty cell.
fn cell(v: Option<f64>) -> String {
    v.map_or_else(String::new, |v| format!("{v}"))
}

/// CSV text of the rows, header first.
#[must_use]
pub fn to_csv(sweep: &Sweep, rows: &[Row]) -> String {
    let mut out = header(sweep).join(",");
    out.push('\n');
    for r in rows {
        let _ = write!(out, "{},{},{},{}", r.run, r.case, r.controller, r.seed);
        for v in r.params.iter().map(|v| Some(*v)).chain(r.metrics.iter().copied()) {
            out.push(',');
            out.push_str(&cell(v));
        }
        out.push('\n');
    }
    out
}

/// Rows read back from CSV text written by [`to_csv`] for this sweep.
///
/// # Errors
/// A header that is not this sweep's, or a row that does not parse (named by file and line).
pub fn from_csv(sweep: &Sweep, name: &str, text: &str) -> Result<Vec<Row>, SweepError> {
    let err = |line: usize, m: String| SweepError::Table(format!("{name}:{line}: {m}"));
    let mut lines = text.lines();
    let expected = header(sweep).join(",");
    match lines.next() {
        Some(h) if h == expected => {}
        Some(h) => return Err(err(1, format!("header `{h}` is not this sweep's (`{expected}`)"))),
        None => return Err(err(1, "empty file".into())),
    }
    let n_params = sweep.vary.len();
    let n_metrics = sweep.metric_columns().len();
    let mut rows = Vec::new();
    for (i, line) in lines.enumerate() {
        let at = i + 2;
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != 4 + n_params + n_metrics {
            return Err(err(at, format!("{} cells, expected {}", cells.len(), 4 + n_params + n_metrics)));
        }
        let whole =
            |s: &str, what: &str| s.parse::<u64>().map_err(|_| err(at, format!("{what} `{s}` is not a whole number")));
        let float = |s: &str| -> Result<Option<f64>, SweepError> {
            if s.is_empty() {
                Ok(None)
            } else {
                s.parse().map(Some).map_err(|_| err(at, format!("`{s}` is not a number")))
            }
        };
        let controller = cells[2].parse::<ControllerKind>().map_err(|e| err(at, e.to_string()))?;
        let params = cells[4..4 + n_params]
            .iter()
            .map(|s| float(s)?.ok_or_else(|| err(at, "a varied value is empty".into())))
            .collect::<Result<Vec<_>, _>>()?;
        let metrics = cells[4 + n_params..].iter().map(|s| float(s)).collect::<Result<Vec<_>, _>>()?;
        rows.push(Row {
            run: whole(cells[0], "run")?,
            case: whole(cells[1], "case")?,
            controller,
            seed: whole(cells[3], "seed")?,
            params,
            metrics,
        });
    }
    Ok(rows)
}

/// Shards' rows merged into the whole sweep, in run order. Every run must be present exactly once, and
/// each row's case values and seed must be those the spec gives that run (a shard of another spec, or
/// an edited row, is refused).
///
/// # Errors
/// A missing, repeated or foreign run.
pub fn merge(sweep: &Sweep, shards: Vec<Vec<Row>>) -> Result<Vec<Row>, SweepError> {
    let total = sweep.runs();
    let mut by_run: BTreeMap<u64, Row> = BTreeMap::new();
    for row in shards.into_iter().flatten() {
        if row.run >= total {
            return Err(SweepError::Table(format!("run {} is beyond this sweep's {total} runs", row.run)));
        }
        let run = row.run;
        if by_run.insert(run, row).is_some() {
            return Err(SweepError::Table(format!("run {run} is in more than one shard")));
        }
    }
    if let Some(missing) = (0..total).find(|r| !by_run.contains_key(r)) {
        let n = (0..total).filter(|r| !by_run.contains_key(r)).count();
        return Err(SweepError::Table(format!("{n} of {total} runs are missing (the first: run {missing})")));
    }
    let k = sweep.controllers.len() as u64;
    for row in by_run.values() {
        let case = sweep.case(row.run / k)?;
        let expected = (case.index, sweep.controllers[(row.run % k) as usize], case.seed, &case.values);
        if (row.case, row.controller, row.seed, &row.params) != expected {
            return Err(SweepError::Table(format!(
                "run {}: its case, controller, seed or values are not this spec's (another spec's shard?)",
                row.run
            )));
        }
    }
    Ok(by_run.into_values().collect())
}

/// One metric's distribution for one controller.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MetricSummary {
    pub metric: String,
    /// Runs with a value; the others (a recovery that never came) count as worse than any value.
    pub n: usize,
    pub missing: usize,
    /// The mean of the values (for a flag such as `non_finite`: the fraction of runs where it is set).
    pub mean: f64,
    pub p50: f64,
    pub p90: f64,
    pub p99: f64,
    pub max: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bound: Option<f64>,
    /// The fraction of all runs at or under the bound.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub within: Option<f64>,
}

/// Per controller, each metric's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    pub sweep: String,
    pub scenario: String,
    pub runs: usize,
    pub controllers: BTreeMap<String, Vec<MetricSummary>>,
}

/// The nearest-rank percentile `p` (0..=100) of ascending values.
#[must_use]
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The summary of rows (all runs of a sweep, or one shard's).
#[must_use]
pub fn summarize(sweep: &Sweep, rows: &[Row]) -> Summary {
    let columns = sweep.metric_columns();
    let mut controllers = BTreeMap::new();
    for &c in &sweep.controllers {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.controller == c).collect();
        let mut out = Vec::new();
        for (i, name) in columns.iter().enumerate() {
            // Missing values (never recovered, never settled) are worse than any: +inf in the ranks.
            let mut values: Vec<f64> = mine.iter().map(|r| r.metrics[i].unwrap_or(f64::INFINITY)).collect();
            values.sort_by(f64::total_cmp);
            let missing = mine.iter().filter(|r| r.metrics[i].is_none()).count();
            let bound = sweep.bounds.get(name).copied();
            let within = bound.map(|b| {
                if values.is_empty() {
                    f64::NAN
                } else {
                    values.iter().filter(|v| **v <= b).count() as f64 / values.len() as f64
                }
            });
            out.push(MetricSummary {
                metric: name.clone(),
                n: values.len() - missing,
                missing,
                mean: mine.iter().filter_map(|r| r.metrics[i]).sum::<f64>() / (values.len() - missing).max(1) as f64,
                p50: percentile(&values, 50.0),
                p90: percentile(&values, 90.0),
                p99: percentile(&values, 99.0),
                max: values.last().copied().unwrap_or(f64::NAN),
                bound,
                within,
            });
        }
        controllers.insert(c.to_string(), out);
    }
    Summary { sweep: sweep.name.clone(), scenario: sweep.scenario.name.clone(), runs: rows.len(), controllers }
}

fn fmt_value(v: f64) -> String {
    if v.is_infinite() {
        "never".to_owned()
    } else if v.is_nan() {
        "-".to_owned()
    } else if v != 0.0 && v.abs() < 0.01 {
        format!("{v:.5}")
    } else {
        format!("{v:.3}")
    }
}

impl Summary {
    /// The robustness table: per metric, a line per controller (ACO first, as the paper compares).
    #[must_use]
    pub fn table(&self) -> String {
        let mut out = format!("sweep {} of {}: {} runs\n", self.sweep, self.scenario, self.runs);
        let _ = writeln!(
            out,
            "{:<26} {:<4} {:>10} {:>10} {:>10} {:>10} {:>10} {:>8} {:>16}",
            "metric", "ctrl", "mean", "p50", "p90", "p99", "max", "missing", "within bound"
        );
        let Some(first) = self.controllers.values().next() else { return out };
        for (i, metric) in first.iter().enumerate() {
            for (c, list) in &self.controllers {
                let m = &list[i];
                let within = match (m.bound, m.within) {
                    (Some(b), Some(w)) => format!("{:.1} % <= {}", 100.0 * w, fmt_value(b)),
                    _ => String::new(),
                };
                let _ = writeln!(
                    out,
                    "{:<26} {:<4} {:>10} {:>10} {:>10} {:>10} {:>10} {:>8} {:>16}",
                    metric.metric,
                    c,
                    fmt_value(m.mean),
                    fmt_value(m.p50),
                    fmt_value(m.p90),
                    fmt_value(m.p99),
                    fmt_value(m.max),
                    m.missing,
                    within
                );
            }
        }
        out
    }
}
