//! The plot glue of `sitl scenario` and `sitl sweep`: which figure each experiment draws from its runs,
//! with what panels, titles and file names (the drawing itself is `sitl::scenario::plot`).

use std::path::{Path, PathBuf};

use anyhow::Result;
use sitl::scenario::plot::{self, Panel, Run};
use sitl::scenario::reference::{ReferenceMode, ReferenceSpec, SplinePath};
use sitl::scenario::runner::{self, RunOutput};
use sitl::scenario::{MetricKind, Scenario, file_label};
use sitl::sweep::Sweep;

/// The figures of one scenario's runs; returns the files written.
pub(crate) fn plots(
    scenario: &Scenario,
    dir: &Path,
    outputs: &[RunOutput],
    mode: ReferenceMode,
) -> Result<Vec<PathBuf>> {
    let Some(first) = outputs.first() else { return Ok(Vec::new()) };
    let labels: Vec<String> = outputs.iter().map(|o| o.metrics.controller.to_uppercase()).collect();
    let m = &first.metrics;
    let suffix = if scenario.reference_modes().len() > 1 { format!("_{mode}") } else { String::new() };
    let plant = file_label(&m.plant);
    let file = |kind: &str| dir.join(format!("{kind}_{plant}{suffix}_seed{}_{}hz.png", m.seed, m.rate_hz));
    let mut written = Vec::new();
    // Each figure is a PNG and an SVG of the same name.
    let mut written_file = |kind: &str| {
        let path = file(kind);
        written.extend([path.clone(), path.with_extension("svg")]);
        path
    };
    let title = |what: &str| format!("{what}: {} plant, {}", m.plant, labels.join(" vs "));
    match &scenario.reference {
        ReferenceSpec::Attitude { .. } => {
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            let panels = [
                Panel::new("roll (rad)", "roll", Some("ref_roll"), 1.0),
                Panel::new("pitch (rad)", "pitch", Some("ref_pitch"), 1.0),
                Panel::new("yaw (rad)", "yaw", Some("ref_yaw"), 1.0),
            ];
            plot::time_panels(&written_file("attitude"), &title("Attitude (paper Fig. 5)"), &panels, &runs)?;
        }
        ReferenceSpec::Rates { .. } => {
            // The trace keeps the attitude, the integral of the rates flown: a rate step is a ramp.
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            let panels = [
                Panel::new("roll (rad)", "roll", None, 1.0),
                Panel::new("pitch (rad)", "pitch", None, 1.0),
                Panel::new("yaw (rad)", "yaw", None, 1.0),
            ];
            plot::time_panels(&written_file("rates"), &title("Body-rate steps (attitude flown)"), &panels, &runs)?;
        }
        ReferenceSpec::Position { .. } if scenario.metrics.contains(&MetricKind::Gust) => {
            let traces: Vec<_> = outputs.iter().map(|o| with_horizontal_error(&o.trace)).collect();
            let runs: Vec<Run<'_>> = traces.iter().zip(&labels).map(|(t, l)| Run { label: l, trace: t }).collect();
            let panels = [
                Panel::new("horizontal error (m)", "err_xy", None, 1.0),
                Panel::new("altitude error (m)", "err_alt", None, 1.0),
                Panel::new("wind east (m/s)", "windE", None, 1.0).common_to_all_runs(),
            ];
            // The gust is what the figure is about: the start-up transient before its onset does not set
            // the scale (it is drawn clipped over a shaded band).
            let panels = match &scenario.wind.gust {
                Some(g) => panels.map(|p| p.settled_from(g.onset_s)),
                None => panels,
            };
            plot::time_panels(&written_file("gust"), &title("Hover under a Beaufort-4 gust"), &panels, &runs)?;
        }
        ReferenceSpec::Position { .. } => {
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            let panels = [
                Panel::new("north (m)", "pN", Some("refN"), 1.0),
                Panel::new("east (m)", "pE", Some("refE"), 1.0),
                Panel::new("altitude (m)", "pD", Some("refD"), -1.0),
            ];
            plot::time_panels(&written_file("translation"), &title("Translation (paper Fig. 6)"), &panels, &runs)?;
        }
        ReferenceSpec::Track(track) => {
            let path = SplinePath::new(&track.waypoints_ne_m);
            let samples = 600;
            let pts: Vec<(f64, f64)> = (0..=samples)
                .map(|k| path.eval(path.length_m() * f64::from(k) / f64::from(samples)).0)
                .map(|p| (p.x, p.y))
                .collect();
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            plot::track(
                &written_file("figure8"),
                &title(&format!("Figure-8 at {} m/s, {mode}", track.speed_mps)),
                &pts,
                &runs,
            )?;
        }
    }
    Ok(written)
}

/// The trace with `err_xy` (horizontal distance to the reference) and `err_alt` (altitude error) added.
pub(crate) fn with_horizontal_error(trace: &runner::Trace) -> runner::Trace {
    let mut t = trace.clone();
    let idx = |name: &str| t.columns.iter().position(|c| c == name).expect("core column");
    let (n, e, d, rn, re, rd) = (idx("pN"), idx("pE"), idx("pD"), idx("refN"), idx("refE"), idx("refD"));
    t.columns.push("err_xy".into());
    t.columns.push("err_alt".into());
    for row in &mut t.rows {
        let exy = (row[n] - row[rn]).hypot(row[e] - row[re]);
        let ealt = row[rd] - row[d];
        row.push(exy);
        row.push(ealt);
    }
    t
}

/// One figure per metric (flags and the airframe's thrust-to-weight excepted): its CDF and box plot per
/// controller.
pub(crate) fn sweep_plots(spec: &Sweep, rows: &[sitl::sweep::Row], out: &Path) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for (i, metric) in spec.metric_columns().iter().enumerate() {
        if ["weights_at_bounds", "non_finite"].iter().chain(&sitl::sweep::table::THRUST_TO_WEIGHT).any(|c| c == metric)
        {
            continue;
        }
        let per_controller: Vec<(String, Vec<f64>)> = spec
            .controllers
            .iter()
            .map(|c| {
                let values =
                    rows.iter().filter(|r| r.controller == *c).map(|r| r.metrics[i].unwrap_or(f64::INFINITY)).collect();
                (c.to_string(), values)
            })
            .collect();
        let samples: Vec<plot::Sample<'_>> =
            per_controller.iter().map(|(label, values)| plot::Sample { label, values }).collect();
        let path = out.join(format!("{metric}.png"));
        let title =
            format!("{}: {metric} over {} runs per controller", spec.name, rows.len() / spec.controllers.len().max(1));
        plot::distribution(&path, &title, &metric_axis_label(metric), &samples)?;
        written.push(path);
    }
    written.extend(robustness_plot(spec, rows, out)?);
    Ok(written)
}

/// A sweep over one rotor's efficiency (`motN_eff`) of a scenario with the fault metric: the median peak
/// position error per thrust loss and controller, against the airframe's physical bounds
/// (`sitl::plant::envelope`); nothing for any other sweep.
pub(crate) fn robustness_plot(spec: &Sweep, rows: &[sitl::sweep::Row], out: &Path) -> Result<Vec<PathBuf>> {
    let names = spec.param_names();
    let Some(p) = names.iter().position(|n| n.starts_with("mot") && n.ends_with("_eff")) else { return Ok(Vec::new()) };
    let metric = "fault_peak_position_error_m";
    let Some(m) = spec.metric_columns().iter().position(|c| c == metric) else { return Ok(Vec::new()) };
    let airframe = runner::plant_config(&spec.scenario, spec.plant.as_deref())?.airframe;
    let e = sitl::plant::hover_envelope(&airframe);
    let loss_pct = |eff: f64| 100.0 * (1.0 - eff);
    let curves: Vec<(String, Vec<(f64, f64)>)> = spec
        .controllers
        .iter()
        .map(|c| {
            let mut by_loss: std::collections::BTreeMap<u64, Vec<f64>> = std::collections::BTreeMap::new();
            for r in rows.iter().filter(|r| r.controller == *c) {
                by_loss.entry(loss_pct(r.params[p]).to_bits()).or_default().push(r.metrics[m].unwrap_or(f64::INFINITY));
            }
            let mut points: Vec<(f64, f64)> = by_loss
                .into_iter()
                .map(|(x, mut v)| {
                    v.sort_by(f64::total_cmp);
                    (f64::from_bits(x), v[v.len() / 2])
                })
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            (c.to_string().to_uppercase(), points)
        })
        .collect();
    let bounds = [
        plot::Bound {
            x: loss_pct(e.min_health_full_control),
            label: format!("all moments: {:.1} %", loss_pct(e.min_health_full_control)),
        },
        plot::Bound {
            x: loss_pct(e.min_health_without_yaw),
            label: format!("roll/pitch: {:.1} %", loss_pct(e.min_health_without_yaw)),
        },
    ];
    let path = out.join("robustness.png");
    let title = format!(
        "{}: median peak position error after the fault ({} plant)",
        spec.name,
        spec.scenario.plant_label(spec.plant.as_deref())
    );
    let layout = plot::Layout {
        title: &title,
        x_label: &format!("rotor {} thrust lost (%)", &names[p][3..4]),
        y_label: "peak position error (m)",
        bounds: &bounds,
        threshold: Some((sitl::scenario::metrics::FAULT_HOLD_BAND_M, "0.3 m")),
        y_max: 2.0,
    };
    plot::robustness(&path, &layout, &curves)?;
    Ok(vec![path.clone(), path.with_extension("svg")])
}

/// `gust_peak_m` -> `gust peak (m)`.
pub(crate) fn metric_axis_label(metric: &str) -> String {
    for (suffix, unit) in [("_m", "m"), ("_s", "s"), ("_pct", "%"), ("_rad", "rad"), ("_us", "µs")] {
        if let Some(stem) = metric.strip_suffix(suffix) {
            return format!("{} ({unit})", stem.replace('_', " "));
        }
    }
    metric.replace('_', " ")
}
