//! A fault sweep's robustness figure: one metric (e.g. the peak position error) against the fault's
//! magnitude (e.g. one rotor's thrust loss in %), a curve per controller, with the physical bounds of the
//! airframe drawn as vertical lines (past them no controller can hold the vehicle) and a horizontal
//! threshold (e.g. the 0.3 m a hold must stay within). Values above the chart's top are drawn at the top.

use std::path::Path;

use super::convergence::LineFigure;
use super::draw::{Line, padded_range};
use super::{LineStyle, PlotError, REFERENCE_STYLE, run_style, write_figure};
use plotters::prelude::RGBColor;

/// A physical bound: its x (in the figure's units) and its legend label.
#[derive(Debug, Clone, PartialEq)]
pub struct Bound {
    pub x: f64,
    pub label: String,
}

/// Bounds are drawn dark grey, dashed; the threshold light grey, solid.
const BOUND_STYLES: [LineStyle; 2] = [
    LineStyle { colour: RGBColor(60, 60, 60), width: 1.6, dash: &[6.0, 4.0] },
    LineStyle { colour: RGBColor(60, 60, 60), width: 1.6, dash: &[2.0, 3.0] },
];

/// What a robustness figure shows besides its curves.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    /// Vertical lines at the physical bounds.
    pub bounds: &'a [Bound],
    /// A horizontal line `(y, label)`.
    pub threshold: Option<(f64, &'a str)>,
    /// Values above are drawn at it (a lost run's error is unbounded).
    pub y_max: f64,
}

/// Curves (`(controller label, points (x, y))`) laid out by `layout`; written as `path` (PNG) and its
/// `.svg`.
///
/// # Errors
/// A drawing failure.
pub fn robustness(path: &Path, layout: &Layout<'_>, curves: &[(String, Vec<(f64, f64)>)]) -> Result<(), PlotError> {
    let Layout { title, x_label, y_label, bounds, threshold, y_max } = *layout;
    let x = padded_range(curves.iter().flat_map(|(_, p)| p.iter().map(|q| q.0)).chain(bounds.iter().map(|b| b.x)));
    let clipped: Vec<(String, Vec<(f64, f64)>)> = curves
        .iter()
        .map(|(l, p)| {
            (l.clone(), p.iter().map(|&(a, b)| (a, if b.is_finite() { b.min(y_max) } else { y_max })).collect())
        })
        .collect();
    let y = padded_range(clipped.iter().flat_map(|(_, p)| p.iter().map(|q| q.1)).chain([0.0, y_max]));
    let mut legend = Vec::new();
    let mut lines = Vec::new();
    for (i, b) in bounds.iter().enumerate() {
        let style = BOUND_STYLES[i % BOUND_STYLES.len()];
        legend.push((b.label.clone(), style));
        lines.push(Line { points: vec![(b.x, y.start), (b.x, y.end)], style });
    }
    if let Some((level, label)) = threshold {
        legend.push((label.to_owned(), REFERENCE_STYLE));
        lines.push(Line { points: vec![(x.start, level), (x.end, level)], style: REFERENCE_STYLE });
    }
    // ACO last, so the baselines never hide it.
    let mut order: Vec<usize> = (0..clipped.len()).collect();
    order.sort_by_key(|&i| super::is_aco(&clipped[i].0));
    for (i, (label, _)) in clipped.iter().enumerate() {
        legend.push((label.clone(), run_style(label, i)));
    }
    for i in order {
        let (label, points) = &clipped[i];
        lines.push(Line { points: points.clone(), style: run_style(label, i) });
    }
    let fig = LineFigure::new(title, x_label, y_label, legend, x, y, lines);
    write_figure(path, (900, 520), &fig)
}
