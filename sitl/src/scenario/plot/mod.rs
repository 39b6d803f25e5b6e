//! Figures of scenario traces, each written twice from one drawing: SVG (vector, for print; its text
//! names the font family `sans-serif`, so any viewer renders it) and PNG at twice the layout size,
//! drawn at four times and averaged down 2x2 so lines are smooth (plotters draws whole pixels without
//! anti-aliasing; DejaVu Sans is embedded so no system font is needed). Two kinds: stacked time panels
//! (the paper's Fig. 5 and Fig. 6 layouts, the gust-hover error) and a north-east track view (figure-8),
//! several controllers on one figure; and a sweep's distribution of one metric per controller (CDF and
//! box plot side by side).
//!
//! Print conventions: ACO, the paper's controller, is drawn last with the widest solid line, so the
//! baselines never hide it; CA is dashed, PID dash-dotted, and the three colours differ in grey level
//! too, so a grey-scale print keeps them apart; references are thin grey solid lines. One legend per
//! figure sits in a row under the title, off the data. Every axis is labelled with its unit, and tick
//! labels never read `-0.0`. A panel may have a settle time: its y range is computed from the samples at
//! or after it, and the earlier start-up transient is still drawn, clipped at the panel's edge (then over
//! a shaded band marked "start-up, clipped"), so a transient does not set the scale of the response the
//! figure is about; the time axis still starts at 0, so events keep their times.
//!
//! This module holds the styles, the fonts and the writing of a figure's two files; `draw` the chart
//! primitives (ticks, ranges, dashed lines, legend, mesh); one module per kind of figure.

mod convergence;
mod distribution;
mod draw;
mod robustness;
mod time_panels;
mod track;

pub use convergence::convergence;
pub use distribution::{Sample, distribution};
pub use robustness::{Bound, Layout, robustness};
pub use time_panels::{Panel, Run, time_panels};
pub use track::track;

use std::path::Path;
use std::sync::Once;

use autopilot::runtime::persist::write_file_atomically;
use image::ImageEncoder;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use draw::px;

/// Why a plot was not written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("trace `{run}` has no column `{column}`")]
    MissingColumn { run: String, column: String },
    #[error("drawing {path}: {message}")]
    Draw { path: String, message: String },
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

/// A PNG pixel per this many layout pixels.
const PNG_SCALE: u32 = 2;

/// The PNG is drawn this many times larger again and averaged down (anti-aliasing).
const SUPERSAMPLE: u32 = 2;

/// Both outputs are drawn at this scale; the SVG declares the layout size, so its coordinates have a
/// quarter-pixel resolution.
const RENDER_SCALE: u32 = PNG_SCALE * SUPERSAMPLE;

/// Font sizes and line widths below are in layout pixels.
const TITLE_SIZE: f64 = 20.0;

const LEGEND_SIZE: f64 = 16.0;

const TICK_SIZE: f64 = 15.0;

const AXIS_LABEL_SIZE: f64 = 16.0;

const LEGEND_ROW: f64 = 34.0;

const X_TICKS: usize = 10;

const Y_TICKS: usize = 6;

/// How one series is stroked: colour, width (layout pixels) and dash pattern (on, off, ... in layout
/// pixels; empty is solid).
#[derive(Debug, Clone, Copy, PartialEq)]
struct LineStyle {
    colour: RGBColor,
    width: f64,
    dash: &'static [f64],
}

impl LineStyle {
    fn shape(&self, s: f64) -> ShapeStyle {
        ShapeStyle::from(&self.colour).stroke_width(px(self.width * s).max(1))
    }
}

/// ACO: dark blue (grey level about 50 of 255), widest, solid, drawn last.
const ACO_STYLE: LineStyle = LineStyle { colour: RGBColor(0, 60, 140), width: 2.6, dash: &[] };

/// CA: vermilion (grey about 120), dashed.
const CA_STYLE: LineStyle = LineStyle { colour: RGBColor(213, 94, 0), width: 2.0, dash: &[8.0, 4.0] };

/// PID: orange (grey about 160), dash-dot.
const PID_STYLE: LineStyle = LineStyle { colour: RGBColor(230, 159, 0), width: 2.2, dash: &[9.0, 3.5, 2.0, 3.5] };

/// Any other label, in turn.
const OTHER_STYLES: [LineStyle; 2] = [
    LineStyle { colour: RGBColor(150, 70, 160), width: 2.0, dash: &[2.0, 3.0] },
    LineStyle { colour: RGBColor(86, 180, 233), width: 2.0, dash: &[14.0, 4.0] },
];

/// References and the track's path.
const REFERENCE_STYLE: LineStyle = LineStyle { colour: RGBColor(140, 140, 140), width: 1.4, dash: &[] };

/// A column common to all runs.
const COMMON_STYLE: LineStyle = LineStyle { colour: RGBColor(0, 0, 0), width: 1.6, dash: &[] };

const GRID: RGBColor = RGBColor(225, 225, 225);

fn is_aco(label: &str) -> bool {
    label.eq_ignore_ascii_case("aco")
}

/// The style of the run labelled `label`; `index` picks among the spare styles for unknown labels.
fn run_style(label: &str, index: usize) -> LineStyle {
    match label.to_ascii_uppercase().as_str() {
        "ACO" => ACO_STYLE,
        "CA" => CA_STYLE,
        "PID" => PID_STYLE,
        _ => OTHER_STYLES[index % OTHER_STYLES.len()],
    }
}

/// Run indices in drawing order: the others as given, then ACO, so ACO is on top.
fn draw_order(labels: &[&str]) -> Vec<usize> {
    let (aco, others): (Vec<usize>, Vec<usize>) = (0..labels.len()).partition(|&i| is_aco(labels[i]));
    others.into_iter().chain(aco).collect()
}

fn font(size: f64) -> TextStyle<'static> {
    TextStyle::from(FontDesc::new(FontFamily::Name(FONT), size, FontStyle::Normal))
}

fn e2s(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// A figure drawn once per backend, at scale `s` (device pixels per layout pixel).
trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: f64) -> Result<(), String>;
}

/// Writes `fig` as SVG (`png` with the extension `svg`) and as PNG at [`PNG_SCALE`] times the layout
/// `size`, each via a temporary file and a rename.
fn write_figure(png: &Path, size: (u32, u32), fig: &impl Figure) -> Result<(), PlotError> {
    register_font();
    let err = |e: String| PlotError::Draw { path: png.display().to_string(), message: e };
    let big = (size.0 * RENDER_SCALE, size.1 * RENDER_SCALE);
    let s = f64::from(RENDER_SCALE);

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, big).into_drawing_area();
        fig.draw(&root, s).map_err(err)?;
        root.present().map_err(|e| err(e2s(e)))?;
    }
    // Declare the layout size (the drawing keeps its finer coordinates through the viewBox); round joins.
    let svg = svg.replacen(
        &format!("width=\"{}\" height=\"{}\"", big.0, big.1),
        &format!("width=\"{}\" height=\"{}\" stroke-linejoin=\"round\"", size.0, size.1),
        1,
    );
    write_atomically(&png.with_extension("svg"), svg.as_bytes()).map_err(err)?;

    let mut buf = vec![0u8; big.0 as usize * big.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, big).into_drawing_area();
        fig.draw(&root, s).map_err(err)?;
        root.present().map_err(|e| err(e2s(e)))?;
    }
    let (w, h) = (size.0 * PNG_SCALE, size.1 * PNG_SCALE);
    let small = downsample(&buf, big.0 as usize, SUPERSAMPLE as usize, (w as usize, h as usize));
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut bytes,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&small, w, h, image::ColorType::Rgb8)
    .map_err(|e| err(e2s(e)))?;
    write_atomically(png, &bytes).map_err(err)
}

/// An RGB image `k` times smaller, each pixel the mean of a k x k block of `buf` (`stride` pixels wide).
fn downsample(buf: &[u8], stride: usize, k: usize, (w, h): (usize, usize)) -> Vec<u8> {
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut sum = 0usize;
                for dy in 0..k {
                    for dx in 0..k {
                        sum += usize::from(buf[((y * k + dy) * stride + x * k + dx) * 3 + c]);
                    }
                }
                out[(y * w + x) * 3 + c] = ((sum + k * k / 2) / (k * k)) as u8;
            }
        }
    }
    out
}

fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), String> {
    write_file_atomically(path, bytes).map_err(|e| format!("writing {}: {e}", path.display()))
}

/// Legend entries: the runs in their given order, then the reference if the figure has one.
fn legend(labels: &[&str], reference: Option<&str>) -> Vec<(String, LineStyle)> {
    let mut entries: Vec<(String, LineStyle)> =
        labels.iter().enumerate().map(|(i, l)| ((*l).to_owned(), run_style(l, i))).collect();
    if let Some(r) = reference {
        entries.push((r.to_owned(), REFERENCE_STYLE));
    }
    entries
}

#[cfg(test)]
mod tests;
