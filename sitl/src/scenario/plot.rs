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

use std::ops::Range;
use std::path::Path;
use std::sync::Once;

use autopilot::runtime::persist::write_file_atomically;
use image::ImageEncoder;
use plotters::coord::Shift;
use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::FontStyle;
use plotters::style::text_anchor::{HPos, Pos, VPos};

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

/// A length in layout pixels at scale `s`, in whole device pixels.
fn px(v: f64) -> u32 {
    v.round().max(0.0) as u32
}

/// A tick label with `decimals` decimals; a value that rounds to zero prints without a sign.
#[must_use]
pub fn fmt_tick(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_owned(),
        _ => s,
    }
}

/// The fewest decimals (up to 6) that print every tick plotters puts on `range` (at most `n`) exactly.
fn tick_decimals(range: Range<f64>, n: usize) -> usize {
    let ticks = RangedCoordf64::from(range).key_points(n);
    (0..=6)
        .find(|&d| {
            let f = 10f64.powi(d as i32);
            ticks.iter().all(|v| ((v * f).round() - v * f).abs() < 1e-6)
        })
        .unwrap_or(6)
}

fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) =
        values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let pad = ((hi - lo) * 0.08).max(1e-3);
    (lo - pad)..(hi + pad)
}

/// The padded y range of the series' points at or after `settle_s` (all points without one).
fn y_range(series: &[&[(f64, f64)]], settle_s: Option<f64>) -> Range<f64> {
    let from = settle_s.unwrap_or(f64::NEG_INFINITY);
    padded_range(series.iter().flat_map(|s| s.iter()).filter(|p| p.0 >= from).map(|p| p.1))
}

/// The pieces of a polyline inside `lo <= y <= hi`, cut where it crosses a bound; non-finite points
/// break the line.
fn clip_y(points: &[(f64, f64)], lo: f64, hi: f64) -> Vec<Vec<(f64, f64)>> {
    let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let mut out = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    let mut flush = |current: &mut Vec<(f64, f64)>| {
        if current.len() >= 2 {
            out.push(std::mem::take(current));
        } else {
            current.clear();
        }
    };
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !finite(&a) || !finite(&b) {
            flush(&mut current);
            continue;
        }
        let dy = b.1 - a.1;
        let (t0, t1) = if dy == 0.0 {
            if a.1 >= lo && a.1 <= hi { (0.0, 1.0) } else { (1.0, 0.0) }
        } else {
            let (ta, tb) = ((lo - a.1) / dy, (hi - a.1) / dy);
            (ta.min(tb).max(0.0), ta.max(tb).min(1.0))
        };
        if t0 > t1 {
            flush(&mut current);
            continue;
        }
        let at = |t: f64| (a.0 + (b.0 - a.0) * t, a.1 + dy * t);
        if t0 > 0.0 || current.is_empty() {
            flush(&mut current);
            current.push(at(t0));
        }
        current.push(at(t1));
        if t1 < 1.0 {
            flush(&mut current);
        }
    }
    flush(&mut current);
    out
}

/// The "on" pieces of a polyline under a dash pattern (on, off, ... lengths in device pixels, measured
/// along the drawn line through `to_px`); an empty pattern returns the line whole.
fn dashes(points: &[(f64, f64)], pattern: &[f64], to_px: impl Fn((f64, f64)) -> (f64, f64)) -> Vec<Vec<(f64, f64)>> {
    if points.len() < 2 {
        return Vec::new();
    }
    if pattern.is_empty() || pattern.len() % 2 == 1 || pattern.iter().any(|&d| d.is_nan() || d <= 0.0) {
        return vec![points.to_vec()];
    }
    let mut out = Vec::new();
    let mut k = 0;
    let mut left = pattern[0];
    let mut current = vec![points[0]];
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (pa, pb) = (to_px(a), to_px(b));
        let len = (pb.0 - pa.0).hypot(pb.1 - pa.1);
        let mut done = 0.0;
        while len - done > left {
            done += left;
            let f = done / len;
            let p = (a.0 + (b.0 - a.0) * f, a.1 + (b.1 - a.1) * f);
            if k % 2 == 0 {
                current.push(p);
                out.push(std::mem::take(&mut current));
            } else {
                current = vec![p];
            }
            k = (k + 1) % pattern.len();
            left = pattern[k];
        }
        left -= len - done;
        if k % 2 == 0 {
            current.push(b);
        }
    }
    if k % 2 == 0 && current.len() >= 2 {
        out.push(current);
    }
    out
}

fn font(size: f64) -> TextStyle<'static> {
    TextStyle::from(FontDesc::new(FontFamily::Name(FONT), size, FontStyle::Normal))
}

fn e2s(e: impl std::fmt::Display) -> String {
    e.to_string()
}

fn column(run: &Run<'_>, name: &str) -> Result<Vec<f64>, PlotError> {
    run.trace
        .column(name)
        .ok_or_else(|| PlotError::MissingColumn { run: run.label.to_owned(), column: name.to_owned() })
}

/// One stroked series.
#[derive(Debug, Clone)]
struct Line {
    points: Vec<(f64, f64)>,
    style: LineStyle,
}

/// A figure drawn once per backend, at scale `s` (device pixels per layout pixel).
trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: f64) -> Result<(), String>;
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart over `x` and `y` on `area` with every figure's margins, `y_label_px` layout pixels for the y
/// tick labels, at scale `s`.
fn cartesian<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    x: Range<f64>,
    y: Range<f64>,
    y_label_px: f64,
    s: f64,
) -> Result<Chart<'a, DB>, String> {
    ChartBuilder::on(area)
        .margin(px(6.0 * s))
        .margin_right(px(20.0 * s))
        .x_label_area_size(px(44.0 * s))
        .y_label_area_size(px(y_label_px * s))
        .build_cartesian_2d(x, y)
        .map_err(e2s)
}

/// Data to device pixels of a chart's plotting area, in floating point (dash lengths).
#[derive(Debug, Clone)]
struct PixelMap {
    x: Range<f64>,
    y: Range<f64>,
    w: f64,
    h: f64,
}

impl PixelMap {
    fn new<DB: DrawingBackend>(chart: &Chart<'_, DB>, x: Range<f64>, y: Range<f64>) -> Self {
        let (w, h) = chart.plotting_area().dim_in_pixel();
        Self { x, y, w: f64::from(w), h: f64::from(h) }
    }

    fn px(&self, (x, y): (f64, f64)) -> (f64, f64) {
        (
            (x - self.x.start) / (self.x.end - self.x.start) * self.w,
            (self.y.end - y) / (self.y.end - self.y.start) * self.h,
        )
    }
}

/// A series on a chart: clipped to the chart's y range, dashed, stroked.
fn draw_line<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, map: &PixelMap, line: &Line, s: f64) -> Result<(), String> {
    let pattern: Vec<f64> = line.style.dash.iter().map(|d| d * s).collect();
    let pieces: Vec<Vec<(f64, f64)>> = clip_y(&line.points, map.y.start, map.y.end)
        .iter()
        .flat_map(|piece| dashes(piece, &pattern, |p| map.px(p)))
        .collect();
    let shape = line.style.shape(s);
    chart.draw_series(pieces.into_iter().map(|p| PathElement::new(p, shape))).map_err(e2s)?;
    Ok(())
}

/// The area under the figure's title; a title wider than the figure is set smaller to fit.
fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    s: f64,
) -> Result<DrawingArea<DB, Shift>, String> {
    let root = root.margin(px(8.0 * s), 0, 0, 0);
    let room = 0.96 * f64::from(root.dim_in_pixel().0);
    let wide = f64::from(root.estimate_text_size(title, &font(TITLE_SIZE * s)).map_err(e2s)?.0);
    let size = if wide > room { TITLE_SIZE * s * room / wide } else { TITLE_SIZE * s };
    root.titled(title, font(size)).map_err(e2s)
}

/// The figure's legend, centred in its row: a stroke sample and the label per entry.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, LineStyle)],
    s: f64,
) -> Result<(), String> {
    let style = font(LEGEND_SIZE * s);
    let (sample, gap, spacing) = (44.0 * s, 8.0 * s, 30.0 * s);
    let mut widths = Vec::new();
    for (label, _) in entries {
        widths.push(f64::from(area.estimate_text_size(label, &style).map_err(e2s)?.0));
    }
    let total = widths.iter().map(|w| sample + gap + w).sum::<f64>() + spacing * (entries.len().max(1) - 1) as f64;
    let (aw, ah) = area.dim_in_pixel();
    let mut x = ((f64::from(aw) - total) / 2.0).max(0.0);
    let y = f64::from(ah) / 2.0;
    let text_style = style.pos(Pos::new(HPos::Left, VPos::Center));
    for ((label, line), w) in entries.iter().zip(&widths) {
        let pattern: Vec<f64> = line.dash.iter().map(|d| d * s).collect();
        for piece in dashes(&[(x, y), (x + sample, y)], &pattern, |p| p) {
            let pts: Vec<(i32, i32)> = piece.iter().map(|p| (p.0.round() as i32, p.1.round() as i32)).collect();
            area.draw(&PathElement::new(pts, line.shape(s))).map_err(e2s)?;
        }
        let at = ((x + sample + gap).round() as i32, y.round() as i32);
        area.draw(&Text::new(label.clone(), at, text_style.clone())).map_err(e2s)?;
        x += sample + gap + w + spacing;
    }
    Ok(())
}

/// The mesh every figure uses: light major grid only, units on both axes, ticks without `-0.0`.
fn draw_mesh<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    x: &Range<f64>,
    y: &Range<f64>,
    x_desc: &str,
    y_desc: &str,
    s: f64,
) -> Result<(), String> {
    let yd = tick_decimals(y.clone(), Y_TICKS);
    draw_mesh_with(chart, x, (Y_TICKS, &move |v: &f64| fmt_tick(*v, yd)), x_desc, y_desc, s)
}

/// [`draw_mesh`] with the y axis's tick count and labels given (e.g. names at whole numbers).
fn draw_mesh_with<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    x: &Range<f64>,
    (y_ticks, y_fmt): (usize, &dyn Fn(&f64) -> String),
    x_desc: &str,
    y_desc: &str,
    s: f64,
) -> Result<(), String> {
    let xd = tick_decimals(x.clone(), X_TICKS);
    let x_fmt = move |v: &f64| fmt_tick(*v, xd);
    chart
        .configure_mesh()
        .x_labels(X_TICKS)
        .y_labels(y_ticks)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(y_fmt)
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(font(TICK_SIZE * s))
        .axis_desc_style(font(AXIS_LABEL_SIZE * s))
        .bold_line_style(ShapeStyle::from(&GRID).stroke_width(px(s)))
        .light_line_style(TRANSPARENT)
        .axis_style(ShapeStyle::from(&BLACK).stroke_width(px(s)))
        .set_all_tick_mark_size(px(5.0 * s))
        .draw()
        .map_err(e2s)
}

/// One time panel ready to draw.
struct PreparedPanel {
    y_label: String,
    settle_s: Option<f64>,
    t_max: f64,
    /// In drawing order: reference first, ACO last.
    lines: Vec<Line>,
}

struct TimePanels {
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

struct TrackFigure {
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

/// One series of a sweep's distribution figure: a controller's values of one metric (non-finite
/// values are runs where the event never came: off the chart, so the CDF ends below 1).
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    pub label: &'a str,
    pub values: &'a [f64],
}

struct DistributionFigure {
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

struct LineFigure {
    title: String,
    x_label: String,
    y_label: String,
    legend: Vec<(String, LineStyle)>,
    x: Range<f64>,
    y: Range<f64>,
    lines: Vec<Line>,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn trace(rows: impl Iterator<Item = [f64; 4]>) -> Trace {
        Trace { columns: ["t", "pN", "pE", "x"].map(str::to_owned).to_vec(), rows: rows.map(|r| r.to_vec()).collect() }
    }

    /// A trace of 10 s at 50 Hz: `x` is `f(t)`, the track a circle of radius `r`.
    fn run_trace(f: impl Fn(f64) -> f64, r: f64) -> Trace {
        trace((0..=500).map(|k| {
            let t = f64::from(k) / 50.0;
            [t, r * (t * 0.6).cos(), r * (t * 0.6).sin(), f(t)]
        }))
    }

    fn hex(c: RGBColor) -> String {
        format!("stroke=\"#{:02X}{:02X}{:02X}\"", c.0, c.1, c.2)
    }

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("sitl-plot-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Positions of the first and last element stroked in `colour`.
    fn span(svg: &str, colour: RGBColor) -> (usize, usize) {
        let key = hex(colour);
        (svg.find(&key).unwrap_or_else(|| panic!("no {key}")), svg.rfind(&key).unwrap())
    }

    #[test]
    fn both_figures_are_written_as_svg_and_png_with_aco_drawn_last() {
        let dir = temp_dir("order");
        let aco = run_trace(|t| t.sin(), 1.0);
        let ca = run_trace(|t| t.sin() * 1.1, 1.05);
        let pid = run_trace(|t| t.sin() * 0.9, 0.95);
        // ACO listed first: the figure must still draw it after the others.
        let runs =
            [Run { label: "ACO", trace: &aco }, Run { label: "CA", trace: &ca }, Run { label: "PID", trace: &pid }];
        let png = dir.join("panels.png");
        time_panels(&png, "test", &[Panel::new("x (m)", "x", None, 1.0)], &runs).unwrap();
        let circle: Vec<(f64, f64)> = (0..=100).map(|k| (f64::from(k) * 0.063).sin_cos()).collect();
        let track_png = dir.join("track.png");
        track(&track_png, "test", &circle, &runs).unwrap();
        for png in [png, track_png] {
            let svg = std::fs::read_to_string(png.with_extension("svg")).unwrap();
            assert!(svg.starts_with("<svg width=\""), "{}", &svg[..80]);
            // The legend (drawn first) has a sample of each; ACO's data line comes after all the others'.
            let (_, aco_last) = span(&svg, ACO_STYLE.colour);
            let (_, ca_last) = span(&svg, CA_STYLE.colour);
            let (_, pid_last) = span(&svg, PID_STYLE.colour);
            assert!(aco_last > ca_last && aco_last > pid_last, "{aco_last} {ca_last} {pid_last}");
            assert!(span(&svg, ACO_STYLE.colour).0 < ca_last, "the legend's ACO sample precedes the data");
            // Dashed: CA and PID are many short polylines, ACO one.
            assert!(svg.matches(&hex(CA_STYLE.colour)).count() > 20);
            assert!(svg.matches(&hex(PID_STYLE.colour)).count() > 20);
            let bytes = std::fs::read(&png).unwrap();
            let img = image::load_from_memory(&bytes).unwrap();
            // Twice the layout size the SVG declares.
            let declared = |attr: &str| -> u32 {
                let at = svg.find(&format!("{attr}=\"")).unwrap() + attr.len() + 2;
                svg[at..at + svg[at..].find('"').unwrap()].parse().unwrap()
            };
            assert_eq!((img.width(), img.height()), (declared("width") * PNG_SCALE, declared("height") * PNG_SCALE));
            assert!(svg.contains(&format!("viewBox=\"0 0 {} ", declared("width") * RENDER_SCALE)));
            assert!(!std::fs::exists(png.with_extension("png.tmp")).unwrap());
        }
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_distribution_figure_counts_runs_that_never_came_and_keeps_a_far_tail_off_the_axis() {
        let dir = temp_dir("distribution");
        let mut aco: Vec<f64> = (0..100).map(|k| f64::from(k) * 0.01).collect();
        aco[99] = 60.0; // one run that flew away
        aco[98] = f64::INFINITY; // one that never recovered
        let ca: Vec<f64> = (0..100).map(|k| f64::from(k) * 0.012).collect();
        let png = dir.join("dist.png");
        let samples = [Sample { label: "aco", values: &aco }, Sample { label: "ca", values: &ca }];
        distribution(&png, "test", "peak (m)", &samples).unwrap();
        let svg = std::fs::read_to_string(png.with_extension("svg")).unwrap();
        assert!(svg.contains("ACO (1 of 100 never)"), "the never-recovered run is counted in the legend");
        assert!(svg.contains("runs beyond"), "the far tail is named in the title");
        // The axis ends near the 95th percentiles (about 1.1 m), not at 60 m.
        assert!(!svg.contains(">60<") && !svg.contains(">50<"), "the tail set the axis");
        assert!(image::load_from_memory(&std::fs::read(&png).unwrap()).is_ok());
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_title_wider_than_the_figure_is_set_smaller() {
        let dir = temp_dir("title");
        let run = run_trace(|t| t.sin(), 1.0);
        let circle: Vec<(f64, f64)> = (0..=100).map(|k| (f64::from(k) * 0.063).sin_cos()).collect();
        let title_size = |title: &str| -> f64 {
            let png = dir.join("t.png");
            track(&png, title, &circle, &[Run { label: "ACO", trace: &run }]).unwrap();
            let svg = std::fs::read_to_string(png.with_extension("svg")).unwrap();
            let at = svg.find("font-size=\"").unwrap() + 11;
            svg[at..at + svg[at..].find('"').unwrap()].parse().unwrap()
        };
        let short = title_size("Figure-8");
        let long = title_size(&"Figure-8 at 0.3 m/s, position-only: mismatch plant, ACO vs CA vs PID ".repeat(2));
        assert!(long < 0.7 * short, "{long} {short}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn tick_labels_never_read_minus_zero() {
        for v in [-1e-17, -0.0, -0.004, -0.049, -4e-7] {
            for d in 0..4 {
                let s = fmt_tick(v, d);
                let zero = s.parse::<f64>().unwrap() == 0.0;
                assert!(!(zero && s.starts_with('-')), "{v} with {d} decimals: {s}");
            }
        }
        assert_eq!(fmt_tick(-1e-17, 1), "0.0");
        assert_eq!(fmt_tick(-0.004, 3), "-0.004");
        assert_eq!(fmt_tick(-0.04, 1), "0.0");
        assert_eq!(fmt_tick(-0.05000001, 1), "-0.1");
        assert_eq!(fmt_tick(-0.2, 1), "-0.2");
        assert_eq!(fmt_tick(2.0, 0), "2");
        // Ticks on a range straddling zero come out as plotters' float steps (e.g. -1.4e-17): none reads -0.
        let r = -0.25..0.45;
        let d = tick_decimals(r.clone(), Y_TICKS);
        assert_eq!(d, 1);
        let labels: Vec<String> = RangedCoordf64::from(r).key_points(Y_TICKS).iter().map(|&v| fmt_tick(v, d)).collect();
        assert!(labels.contains(&"0.0".to_owned()), "{labels:?}");
        assert!(!labels.contains(&"-0.0".to_owned()), "{labels:?}");
        assert_eq!(tick_decimals(0.0..30.0, X_TICKS), 0);
        assert_eq!(tick_decimals(-0.02..0.013, Y_TICKS), 2);
        assert_eq!(tick_decimals(-0.004..0.011, Y_TICKS), 3);
    }

    #[test]
    fn the_settle_window_keeps_the_transient_out_of_the_range() {
        // A -0.18 dip before 5 s, then +-0.01.
        let line: Vec<(f64, f64)> = (0..300)
            .map(|k| {
                let t = f64::from(k) * 0.1;
                (t, if t < 5.0 { -0.18 * (t * 0.6).sin() } else { 0.01 * t.sin() })
            })
            .collect();
        let full = y_range(&[&line], None);
        assert!(full.start < -0.17, "{full:?}");
        let settled = y_range(&[&line], Some(5.0));
        assert!(settled.start > -0.02 && settled.end < 0.02, "{settled:?}");
        // The transient is still drawn, clipped to the range: pieces within it, cut at its edge.
        let pieces = clip_y(&line, settled.start, settled.end);
        assert!(pieces.len() >= 2, "{}", pieces.len());
        for p in pieces.iter().flatten() {
            assert!(p.1 >= settled.start - 1e-12 && p.1 <= settled.end + 1e-12, "{p:?}");
        }
        assert!(pieces[0].first().unwrap().0 < 0.2, "the start is drawn");
        assert!(pieces.last().unwrap().last().unwrap().0 > 29.0, "the end is drawn");
    }

    #[test]
    fn dashes_follow_the_pattern_in_pixels() {
        let line = [(0.0, 0.0), (100.0, 0.0)];
        let pieces = dashes(&line, &[8.0, 4.0], |p| p);
        assert_eq!(pieces.len(), 9, "{pieces:?}");
        assert!((pieces[0][1].0 - 8.0).abs() < 1e-9 && (pieces[1][0].0 - 12.0).abs() < 1e-9);
        // Lengths are measured through the pixel map: at 2 pixels per unit the dashes halve in data.
        let halved = dashes(&line, &[8.0, 4.0], |p| (p.0 * 2.0, p.1));
        assert!((halved[0][1].0 - 4.0).abs() < 1e-9);
        // Solid: the line whole.
        assert_eq!(dashes(&line, &[], |p| p), vec![line.to_vec()]);
    }

    #[test]
    fn aco_is_drawn_last_whatever_the_run_order() {
        assert_eq!(draw_order(&["ACO", "CA", "PID"]), vec![1, 2, 0]);
        assert_eq!(draw_order(&["CA", "aco", "PID"]), vec![0, 2, 1]);
        assert_eq!(draw_order(&["PID", "CA"]), vec![0, 1]);
        assert!(ACO_STYLE.dash.is_empty() && ACO_STYLE.width > CA_STYLE.width.max(PID_STYLE.width));
        assert_ne!(CA_STYLE.dash, PID_STYLE.dash);
    }
}
