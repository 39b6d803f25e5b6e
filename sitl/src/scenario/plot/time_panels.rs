//! Stacked time panels (the paper's Fig. 5 and Fig. 6 layouts, the gust-hover error): one line per run
//! and the reference, each panel with its own y range and optional settle time.

use std::path::Path;

use super::draw::{Line, PixelMap, cartesian, draw_legend, draw_line, draw_mesh, px, titled, y_range};
use super::{
    COMMON_STYLE, Figure, LEGEND_ROW, LineStyle, PlotError, REFERENCE_STYLE, draw_order, e2s, font, legend, run_style,
    write_figure,
};
use crate::scenario::runner::Trace;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// One run on a figure.
#[derive(Debug, Clone, Copy)]
pub struct Run<'a> {
    pub label: &'a str,
    pub trace: &'a Trace,
}

/// One stacked panel: a column against time, scaled (e.g. -1 turns D into altitude), with an optional
/// reference column drawn in grey.
#[derive(Debug, Clone)]
pub struct Panel {
    /// The axis label, with its unit, e.g. `roll (rad)`.
    pub y_label: String,
    pub column: String,
    pub reference: Option<String>,
    pub scale: f64,
    /// The y range is computed from samples at or after this time (s); the earlier part is drawn clipped,
    /// over a shaded band if anything is cut off.
    pub settle_s: Option<f64>,
    /// The column is the same in every run (e.g. the wind): drawn once, black, with no legend entry. If
    /// the runs differ after all, each is drawn in its own style.
    pub common: bool,
}

impl Panel {
    #[must_use]
    pub fn new(y_label: &str, column: &str, reference: Option<&str>, scale: f64) -> Self {
        Self {
            y_label: y_label.to_owned(),
            column: column.to_owned(),
            reference: reference.map(str::to_owned),
            scale,
            settle_s: None,
            common: false,
        }
    }

    /// The y range from `t_s` on (see [`Panel::settle_s`]).
    #[must_use]
    pub fn settled_from(mut self, t_s: f64) -> Self {
        self.settle_s = Some(t_s);
        self
    }

    /// A column every run shares (see [`Panel::common`]).
    #[must_use]
    pub fn common_to_all_runs(mut self) -> Self {
        self.common = true;
        self
    }
}

pub(super) fn column(run: &Run<'_>, name: &str) -> Result<Vec<f64>, PlotError> {
    run.trace
        .column(name)
        .ok_or_else(|| PlotError::MissingColumn { run: run.label.to_owned(), column: name.to_owned() })
}

/// One time panel ready to draw.
pub(super) struct PreparedPanel {
    y_label: String,
    settle_s: Option<f64>,
    t_max: f64,
    /// In drawing order: reference first, ACO last.
    lines: Vec<Line>,
}

pub(super) struct TimePanels {
    title: String,
    legend: Vec<(String, LineStyle)>,
    panels: Vec<PreparedPanel>,
}

impl Figure for TimePanels {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: f64) -> Result<(), String> {
        root.fill(&WHITE).map_err(e2s)?;
        let root = titled(root, &self.title, s)?;
        let (legend, body) = root.split_vertically(px(LEGEND_ROW * s));
        draw_legend(&legend, &self.legend, s)?;
        let areas = body.split_evenly((self.panels.len(), 1));
        for (panel, area) in self.panels.iter().zip(&areas) {
            let x = 0.0..panel.t_max.max(1e-3);
            let series: Vec<&[(f64, f64)]> = panel.lines.iter().map(|l| l.points.as_slice()).collect();
            let y = y_range(&series, panel.settle_s);
            let mut chart = cartesian(area, x.clone(), y.clone(), 78.0, s)?;
            draw_mesh(&mut chart, &x, &y, "time (s)", &panel.y_label, s)?;
            let clipped =
                |t: f64| panel.lines.iter().flat_map(|l| &l.points).any(|p| p.0 < t && (p.1 < y.start || p.1 > y.end));
            if let Some(t) = panel.settle_s.filter(|&t| t > x.start && clipped(t)) {
                let band = Rectangle::new([(x.start, y.start), (t.min(x.end), y.end)], BLACK.mix(0.06).filled());
                chart.draw_series(std::iter::once(band)).map_err(e2s)?;
                let note = font(12.0 * s).color(&RGBColor(90, 90, 90)).pos(Pos::new(HPos::Left, VPos::Top));
                let offset = (px(4.0 * s) as i32, px(3.0 * s) as i32);
                let label = EmptyElement::at((x.start, y.end)) + Text::new("start-up, clipped", offset, note);
                chart.plotting_area().draw(&label).map_err(e2s)?;
            }
            let map = PixelMap::new(&chart, x.clone(), y.clone());
            for line in &panel.lines {
                draw_line(&mut chart, &map, line, s)?;
            }
        }
        Ok(())
    }
}

/// Stacked time panels, one line per run, reference in grey; written as `path` (PNG) and its `.svg`.
///
/// # Errors
/// A missing column or a drawing failure (e.g. the directory is not writable).
pub fn time_panels(path: &Path, title: &str, panels: &[Panel], runs: &[Run<'_>]) -> Result<(), PlotError> {
    let labels: Vec<&str> = runs.iter().map(|r| r.label).collect();
    let order = draw_order(&labels);
    let mut prepared = Vec::new();
    for panel in panels {
        let mut per_run = Vec::new();
        let mut reference = None;
        for run in runs {
            let t = column(run, "t")?;
            let y = column(run, &panel.column)?;
            per_run.push(t.iter().copied().zip(y.iter().map(|v| v * panel.scale)).collect::<Vec<_>>());
            if reference.is_none()
                && let Some(r) = &panel.reference
            {
                reference = Some(t.iter().copied().zip(column(run, r)?.iter().map(|v| v * panel.scale)).collect());
            }
        }
        let t_max = per_run.iter().filter_map(|l| l.last().map(|p| p.0)).fold(0.0, f64::max);
        let mut lines: Vec<Line> =
            reference.into_iter().map(|points| Line { points, style: REFERENCE_STYLE }).collect();
        if panel.common && !per_run.is_empty() && per_run.iter().all(|l| *l == per_run[0]) {
            lines.push(Line { points: per_run.swap_remove(0), style: COMMON_STYLE });
        } else {
            for &i in &order {
                lines.push(Line { points: per_run[i].clone(), style: run_style(labels[i], i) });
            }
        }
        prepared.push(PreparedPanel { y_label: panel.y_label.clone(), settle_s: panel.settle_s, t_max, lines });
    }
    let has_reference = panels.iter().any(|p| p.reference.is_some());
    let fig = TimePanels {
        title: title.to_owned(),
        legend: legend(&labels, has_reference.then_some("reference")),
        panels: prepared,
    };
    let height = 44 + LEGEND_ROW as u32 + 250 * panels.len() as u32;
    write_figure(path, (1100, height), &fig)
}
