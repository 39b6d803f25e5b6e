//! PNG plots of scenario traces (plotters, bitmap backend, DejaVu Sans embedded so no system font is
//! needed): stacked time panels (the paper's Fig. 5 and Fig. 6 layouts, the gust-hover error) and a
//! north-east track view (figure-8), with several controllers on one figure.

use std::path::Path;
use std::sync::Once;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::runner::Trace;

/// Why a plot was not written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("trace `{run}` has no column `{column}`")]
    MissingColumn { run: String, column: String },
    #[error("drawing {path}: {message}")]
    Draw { path: String, message: String },
}

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
    pub y_label: String,
    pub column: String,
    pub reference: Option<String>,
    pub scale: f64,
}

impl Panel {
    #[must_use]
    pub fn new(y_label: &str, column: &str, reference: Option<&str>, scale: f64) -> Self {
        Self { y_label: y_label.to_owned(), column: column.to_owned(), reference: reference.map(str::to_owned), scale }
    }
}

const FONT: &str = "sans-serif";

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TTF shipped by the dejavu crate; failure would be a packaging bug.
        if plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_err() {
            panic!("embedded DejaVu Sans is not a valid font: a packaging bug");
        }
    });
}

fn colour(i: usize) -> RGBColor {
    const PALETTE: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
    ];
    PALETTE[i % PALETTE.len()]
}

/// The colour of references and paths.
const REFERENCE_GREY: RGBColor = RGBColor(120, 120, 120);

/// Both figure kinds draw on this chart: f64 axes on a bitmap.
type Chart<'a, 'b> = ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// One labelled line, with its legend swatch.
fn draw_line(
    chart: &mut Chart<'_, '_>,
    path: &Path,
    points: impl IntoIterator<Item = (f64, f64)>,
    colour: RGBColor,
    width: u32,
    label: &str,
) -> Result<(), PlotError> {
    chart
        .draw_series(LineSeries::new(points, ShapeStyle::from(&colour).stroke_width(width)))
        .map_err(|e| draw_err(path, e))?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    Ok(())
}

/// The legend box, upper right.
fn draw_legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>, path: &Path) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| draw_err(path, e))
}

fn draw_err(path: &Path, e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw { path: path.display().to_string(), message: e.to_string() }
}

fn column(run: &Run<'_>, name: &str) -> Result<Vec<f64>, PlotError> {
    run.trace
        .column(name)
        .ok_or_else(|| PlotError::MissingColumn { run: run.label.to_owned(), column: name.to_owned() })
}

fn padded_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) =
        values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let pad = ((hi - lo) * 0.08).max(1e-3);
    (lo - pad)..(hi + pad)
}

/// Stacked time panels, one line per run, reference in grey.
///
/// # Errors
/// A missing column or a drawing failure (e.g. the directory is not writable).
pub fn time_panels(path: &Path, title: &str, panels: &[Panel], runs: &[Run<'_>]) -> Result<(), PlotError> {
    register_font();
    let height = 60 + 260 * panels.len() as u32;
    let root = BitMapBackend::new(path, (1100, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(path, e))?;
    let root = root.titled(title, (FONT, 24)).map_err(|e| draw_err(path, e))?;
    let areas = root.split_evenly((panels.len(), 1));
    for (panel, area) in panels.iter().zip(&areas) {
        let mut lines = Vec::new();
        let mut reference = None;
        for run in runs {
            let t = column(run, "t")?;
            let y: Vec<f64> = column(run, &panel.column)?.iter().map(|v| v * panel.scale).collect();
            if reference.is_none()
                && let Some(r) = &panel.reference
            {
                reference = Some((t.clone(), column(run, r)?.iter().map(|v| v * panel.scale).collect::<Vec<f64>>()));
            }
            lines.push((run.label, t, y));
        }
        let t_max = lines.iter().filter_map(|l| l.1.last().copied()).fold(0.0, f64::max);
        let y_range = padded_range(
            lines.iter().flat_map(|l| l.2.iter().copied()).chain(reference.iter().flat_map(|r| r.1.iter().copied())),
        );
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_max.max(1e-3), y_range)
            .map_err(|e| draw_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc(panel.y_label.as_str())
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(|e| draw_err(path, e))?;
        if let Some((t, r)) = &reference {
            draw_line(&mut chart, path, t.iter().copied().zip(r.iter().copied()), REFERENCE_GREY, 2, "reference")?;
        }
        for (i, (label, t, y)) in lines.iter().enumerate() {
            draw_line(&mut chart, path, t.iter().copied().zip(y.iter().copied()), colour(i), 2, label)?;
        }
        draw_legend(&mut chart, path)?;
    }
    root.present().map_err(|e| draw_err(path, e))
}

/// The north-east track of each run over the reference path (`path_ne_m`), equal axis scales.
///
/// # Errors
/// A missing column or a drawing failure.
pub fn track(path: &Path, title: &str, path_ne_m: &[(f64, f64)], runs: &[Run<'_>]) -> Result<(), PlotError> {
    register_font();
    let mut tracks = Vec::new();
    for run in runs {
        let n = column(run, "pN")?;
        let e = column(run, "pE")?;
        tracks.push((run.label, e.into_iter().zip(n).collect::<Vec<(f64, f64)>>()));
    }
    let all = || path_ne_m.iter().map(|&(n, e)| (e, n)).chain(tracks.iter().flat_map(|t| t.1.iter().copied()));
    let xr = padded_range(all().map(|p| p.0));
    let yr = padded_range(all().map(|p| p.1));
    let half = (xr.end - xr.start).max(yr.end - yr.start) / 2.0;
    let (xc, yc) = ((xr.start + xr.end) / 2.0, (yr.start + yr.end) / 2.0);
    let root = BitMapBackend::new(path, (900, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 22))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((xc - half)..(xc + half), (yc - half)..(yc + half))
        .map_err(|e| draw_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("east (m)")
        .y_desc("north (m)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(|e| draw_err(path, e))?;
    draw_line(&mut chart, path, path_ne_m.iter().map(|&(n, e)| (e, n)), REFERENCE_GREY, 3, "path")?;
    for (i, (label, pts)) in tracks.iter().enumerate() {
        draw_line(&mut chart, path, pts.iter().copied(), colour(i), 2, label)?;
    }
    draw_legend(&mut chart, path)?;
    root.present().map_err(|e| draw_err(path, e))
}
