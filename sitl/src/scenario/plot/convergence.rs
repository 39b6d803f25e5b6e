//! Convergence curves: lines over evaluations (a tuning's best cost so far per seed).

use std::ops::Range;
use std::path::Path;

use super::draw::{Line, PixelMap, cartesian, draw_legend, draw_line, draw_mesh, padded_range, px, titled};
use super::{
    ACO_STYLE, CA_STYLE, Figure, LEGEND_ROW, LineStyle, OTHER_STYLES, PID_STYLE, PlotError, e2s, write_figure,
};
use plotters::coord::Shift;
use plotters::prelude::*;

pub(super) struct LineFigure {
    title: String,
    x_label: String,
    y_label: String,
    legend: Vec<(String, LineStyle)>,
    x: Range<f64>,
    y: Range<f64>,
    lines: Vec<Line>,
}

impl LineFigure {
    pub(super) fn new(
        title: &str,
        x_label: &str,
        y_label: &str,
        legend: Vec<(String, LineStyle)>,
        x: Range<f64>,
        y: Range<f64>,
        lines: Vec<Line>,
    ) -> Self {
        Self { title: title.to_owned(), x_label: x_label.to_owned(), y_label: y_label.to_owned(), legend, x, y, lines }
    }
}

impl Figure for LineFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: f64) -> Result<(), String> {
        root.fill(&WHITE).map_err(e2s)?;
        let root = titled(root, &self.title, s)?;
        let (legend, body) = root.split_vertically(px(LEGEND_ROW * s));
        draw_legend(&legend, &self.legend, s)?;
        let mut chart = cartesian(&body, self.x.clone(), self.y.clone(), 70.0, s)?;
        draw_mesh(&mut chart, &self.x, &self.y, &self.x_label, &self.y_label, s)?;
        let map = PixelMap::new(&chart, self.x.clone(), self.y.clone());
        for line in &self.lines {
            draw_line(&mut chart, &map, line, s)?;
        }
        Ok(())
    }
}

/// Labelled curves (`(label, points)`, points as (x, y)) on one chart, e.g. a tuning's convergence per
/// seed; written as `path` (PNG) and its `.svg`. A curve with no points is listed in the legend only.
///
/// # Errors
/// A drawing failure (e.g. the directory is not writable).
pub fn convergence(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    curves: &[(String, Vec<(f64, f64)>)],
) -> Result<(), PlotError> {
    let x = padded_range(curves.iter().flat_map(|(_, p)| p.iter().map(|q| q.0)).chain([0.0]));
    let y = padded_range(curves.iter().flat_map(|(_, p)| p.iter().map(|q| q.1)));
    let styles: Vec<LineStyle> =
        (0..curves.len()).map(|i| [ACO_STYLE, CA_STYLE, PID_STYLE, OTHER_STYLES[0], OTHER_STYLES[1]][i % 5]).collect();
    let fig = LineFigure {
        title: title.to_owned(),
        x_label: x_label.to_owned(),
        y_label: y_label.to_owned(),
        legend: curves.iter().zip(&styles).map(|((l, _), st)| (l.clone(), *st)).collect(),
        x,
        y,
        lines: curves.iter().zip(&styles).map(|((_, p), st)| Line { points: p.clone(), style: *st }).collect(),
    };
    write_figure(path, (900, 480), &fig)
}
