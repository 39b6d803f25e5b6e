//! The north-east track view (the figure-8): the path and every run's flown track.

use std::ops::Range;
use std::path::Path;

use super::draw::{Line, PixelMap, cartesian, draw_legend, draw_line, draw_mesh, padded_range, px, titled};
use super::time_panels::{Run, column};
use super::{
    Figure, LEGEND_ROW, LineStyle, PlotError, REFERENCE_STYLE, draw_order, e2s, legend, run_style, write_figure,
};
use plotters::coord::Shift;
use plotters::prelude::*;

pub(super) struct TrackFigure {
    title: String,
    legend: Vec<(String, LineStyle)>,
    x: Range<f64>,
    y: Range<f64>,
    /// Path first, ACO last.
    lines: Vec<Line>,
}

impl Figure for TrackFigure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: f64) -> Result<(), String> {
        root.fill(&WHITE).map_err(e2s)?;
        let root = titled(root, &self.title, s)?;
        let (legend, body) = root.split_vertically(px(LEGEND_ROW * s));
        draw_legend(&legend, &self.legend, s)?;
        let build = |x: Range<f64>, y: Range<f64>| cartesian(&body, x, y, 70.0, s);
        // Equal scales: widen the range of the axis with room to spare to the plotting area's shape.
        let (w, h) = build(self.x.clone(), self.y.clone())?.plotting_area().dim_in_pixel();
        let per_px = ((self.x.end - self.x.start) / f64::from(w)).max((self.y.end - self.y.start) / f64::from(h));
        let centred = |r: &Range<f64>, n: u32| {
            let (c, half) = ((r.start + r.end) / 2.0, per_px * f64::from(n) / 2.0);
            (c - half)..(c + half)
        };
        let (x, y) = (centred(&self.x, w), centred(&self.y, h));
        let mut chart = build(x.clone(), y.clone())?;
        draw_mesh(&mut chart, &x, &y, "east (m)", "north (m)", s)?;
        let map = PixelMap::new(&chart, x, y);
        for line in &self.lines {
            draw_line(&mut chart, &map, line, s)?;
        }
        Ok(())
    }
}

/// The north-east track of each run over the reference path (`path_ne_m`), equal axis scales; written
/// as `path` (PNG) and its `.svg`.
///
/// # Errors
/// A missing column or a drawing failure.
pub fn track(path: &Path, title: &str, path_ne_m: &[(f64, f64)], runs: &[Run<'_>]) -> Result<(), PlotError> {
    let labels: Vec<&str> = runs.iter().map(|r| r.label).collect();
    let mut tracks = Vec::new();
    for run in runs {
        let n = column(run, "pN")?;
        let e = column(run, "pE")?;
        tracks.push(e.into_iter().zip(n).collect::<Vec<(f64, f64)>>());
    }
    let reference: Vec<(f64, f64)> = path_ne_m.iter().map(|&(n, e)| (e, n)).collect();
    let all = || reference.iter().chain(tracks.iter().flatten());
    let (x, y) = (padded_range(all().map(|p| p.0)), padded_range(all().map(|p| p.1)));
    // The plotting area follows the track's shape (within limits), so equal scales leave little empty.
    let aspect = ((y.end - y.start) / (x.end - x.start)).clamp(0.6, 1.6);
    let plot_w = 480.0;
    let height = 44 + LEGEND_ROW as u32 + 56 + (plot_w * aspect) as u32;
    let mut lines = vec![Line { points: reference, style: REFERENCE_STYLE }];
    for i in draw_order(&labels) {
        lines.push(Line { points: tracks[i].clone(), style: run_style(labels[i], i) });
    }
    let fig = TrackFigure { title: title.to_owned(), legend: legend(&labels, Some("path")), x, y, lines };
    write_figure(path, (plot_w as u32 + 96, height), &fig)
}
