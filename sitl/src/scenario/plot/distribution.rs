//! A sweep's distribution of one metric per controller: CDF and box plot side by side.

use std::ops::Range;
use std::path::Path;

use super::draw::{
    Line, PixelMap, cartesian, draw_legend, draw_line, draw_mesh, draw_mesh_with, padded_range, px, titled,
};
use super::{Figure, LEGEND_ROW, LineStyle, PlotError, draw_order, e2s, run_style, write_figure};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One series of a sweep's distribution figure: a controller's values of one metric (non-finite
/// values are runs where the event never came: off the chart, so the CDF ends below 1).
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    pub label: &'a str,
    pub values: &'a [f64],
}

pub(super) struct DistributionFigure {
    title: String,
    x_label: String,
    legend: Vec<(String, LineStyle)>,
    x: Range<f64>,
    /// CDF steps, in drawing order (ACO last).
    cdfs: Vec<Line>,
    /// Per label, top to bottom: style, and the 5th, 25th, 50th, 75th and 95th percentiles.
    boxes: Vec<(String, LineStyle, [f64; 5])>,
}

impl Figure for DistributionFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: f64) -> Result<(), String> {
        root.fill(&WHITE).map_err(e2s)?;
        let root = titled(root, &self.title, s)?;
        let (legend, body) = root.split_vertically(px(LEGEND_ROW * s));
        draw_legend(&legend, &self.legend, s)?;
        let (left, right) = body.split_horizontally(px(f64::from(body.dim_in_pixel().0) / 2.0));
        let x = self.x.clone();
        let y = 0.0..1.02;
        let mut chart = cartesian(&left, x.clone(), y.clone(), 70.0, s)?;
        draw_mesh(&mut chart, &x, &y, &self.x_label, "fraction of runs", s)?;
        let map = PixelMap::new(&chart, x.clone(), y);
        for line in &self.cdfs {
            draw_line(&mut chart, &map, line, s)?;
        }
        let n = self.boxes.len();
        let y = -0.5..(n as f64 - 0.5);
        let mut chart = cartesian(&right, x.clone(), y.clone(), 60.0, s)?;
        let names: Vec<String> = self.boxes.iter().map(|b| b.0.clone()).collect();
        let name_of = move |v: &f64| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                names.get(n - 1 - i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        let caption = "box: quartiles, median; whiskers: 5th-95th percentile";
        draw_mesh_with(&mut chart, &x, (n + 1, &name_of), caption, "", s)?;
        for (i, (_, style, q)) in self.boxes.iter().enumerate() {
            let yc = (n - 1 - i) as f64;
            let stroke = ShapeStyle::from(&style.colour).stroke_width(px(1.6 * s).max(1));
            let clamp = |v: f64| v.clamp(x.start, x.end);
            let [p5, q1, med, q3, p95] = q.map(clamp);
            let boxes = [
                Rectangle::new([(q1, yc - 0.28), (q3, yc + 0.28)], style.colour.mix(0.18).filled()),
                Rectangle::new([(q1, yc - 0.28), (q3, yc + 0.28)], stroke),
            ];
            chart.draw_series(boxes).map_err(e2s)?;
            let lines = [
                vec![(med, yc - 0.28), (med, yc + 0.28)],
                vec![(p5, yc), (q1, yc)],
                vec![(q3, yc), (p95, yc)],
                vec![(p5, yc - 0.14), (p5, yc + 0.14)],
                vec![(p95, yc - 0.14), (p95, yc + 0.14)],
            ];
            let widths = [3.0, 1.6, 1.6, 1.6, 1.6];
            chart
                .draw_series(
                    lines.into_iter().zip(widths).map(|(l, w)| {
                        PathElement::new(l, ShapeStyle::from(&style.colour).stroke_width(px(w * s).max(1)))
                    }),
                )
                .map_err(e2s)?;
        }
        Ok(())
    }
}

/// A metric's distribution over a sweep's runs, one series per controller: its CDF (left) and a box
/// plot (right) on the same axis; written as `path` (PNG) and its `.svg`. A series' non-finite values
/// (never recovered, never settled) are counted in its legend label.
///
/// # Errors
/// A drawing failure (e.g. the directory is not writable).
pub fn distribution(path: &Path, title: &str, x_label: &str, samples: &[Sample<'_>]) -> Result<(), PlotError> {
    let labels: Vec<String> = samples
        .iter()
        .map(|smp| {
            let never = smp.values.iter().filter(|v| !v.is_finite()).count();
            let name = smp.label.to_ascii_uppercase();
            if never > 0 { format!("{name} ({never} of {} never)", smp.values.len()) } else { name }
        })
        .collect();
    // The axis ends at the largest 95th percentile: a few runs that flew away would otherwise squash
    // every distribution into its first pixels. The CDFs run on off the chart; the title says so.
    let p95 = samples
        .iter()
        .map(|smp| {
            let mut sorted = smp.values.to_vec();
            sorted.sort_by(f64::total_cmp);
            crate::sweep::table::percentile(&sorted, 95.0)
        })
        .filter(|v| v.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    let shown = |v: &f64| v.is_finite() && (!p95.is_finite() || *v <= p95);
    let x = padded_range(samples.iter().flat_map(|smp| smp.values.iter().copied().filter(shown)));
    let beyond: usize =
        samples.iter().map(|smp| smp.values.iter().filter(|v| v.is_finite() && !shown(v)).count()).sum();
    let title = if beyond > 0 {
        format!("{title} (axis to the 95th percentile; {beyond} runs beyond)")
    } else {
        title.to_owned()
    };
    let order = draw_order(&samples.iter().map(|smp| smp.label).collect::<Vec<_>>());
    let mut cdfs = Vec::new();
    for &i in &order {
        let mut finite: Vec<f64> = samples[i].values.iter().copied().filter(|v| v.is_finite()).collect();
        finite.sort_by(f64::total_cmp);
        let n = samples[i].values.len().max(1) as f64;
        let mut points = vec![(x.start, 0.0)];
        for (k, v) in finite.iter().enumerate() {
            points.push((*v, k as f64 / n));
            points.push((*v, (k + 1) as f64 / n));
        }
        points.push((x.end, finite.len() as f64 / n));
        cdfs.push(Line { points, style: run_style(samples[i].label, i) });
    }
    let boxes = samples
        .iter()
        .enumerate()
        .map(|(i, smp)| {
            let mut sorted = smp.values.to_vec();
            sorted.sort_by(f64::total_cmp);
            let q = [5.0, 25.0, 50.0, 75.0, 95.0].map(|p| crate::sweep::table::percentile(&sorted, p));
            (smp.label.to_ascii_uppercase(), run_style(smp.label, i), q)
        })
        .collect();
    let legend = samples.iter().enumerate().map(|(i, smp)| (labels[i].clone(), run_style(smp.label, i))).collect();
    let fig = DistributionFigure { title, x_label: x_label.to_owned(), legend, x, cdfs, boxes };
    write_figure(path, (1100, 44 + LEGEND_ROW as u32 + 320), &fig)
}
