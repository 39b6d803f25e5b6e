//! The chart primitives every figure draws with: pixel sizes, tick labels and ranges, clipping, dashed
//! lines, titles, legends and meshes.

use std::ops::Range;

use super::{AXIS_LABEL_SIZE, GRID, LEGEND_SIZE, LineStyle, TICK_SIZE, TITLE_SIZE, X_TICKS, Y_TICKS, e2s, font};
use plotters::coord::Shift;
use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// A length in layout pixels at scale `s`, in whole device pixels.
pub(super) fn px(v: f64) -> u32 {
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
pub(super) fn tick_decimals(range: Range<f64>, n: usize) -> usize {
    let ticks = RangedCoordf64::from(range).key_points(n);
    (0..=6)
        .find(|&d| {
            let f = 10f64.powi(d as i32);
            ticks.iter().all(|v| ((v * f).round() - v * f).abs() < 1e-6)
        })
        .unwrap_or(6)
}

pub(super) fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) =
        values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let pad = ((hi - lo) * 0.08).max(1e-3);
    (lo - pad)..(hi + pad)
}

/// The padded y range of the series' points at or after `settle_s` (all points without one).
pub(super) fn y_range(series: &[&[(f64, f64)]], settle_s: Option<f64>) -> Range<f64> {
    let from = settle_s.unwrap_or(f64::NEG_INFINITY);
    padded_range(series.iter().flat_map(|s| s.iter()).filter(|p| p.0 >= from).map(|p| p.1))
}

/// The pieces of a polyline inside `lo <= y <= hi`, cut where it crosses a bound; non-finite points
/// break the line.
pub(super) fn clip_y(points: &[(f64, f64)], lo: f64, hi: f64) -> Vec<Vec<(f64, f64)>> {
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
pub(super) fn dashes(
    points: &[(f64, f64)],
    pattern: &[f64],
    to_px: impl Fn((f64, f64)) -> (f64, f64),
) -> Vec<Vec<(f64, f64)>> {
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

/// One stroked series.
#[derive(Debug, Clone)]
pub(super) struct Line {
    pub(super) points: Vec<(f64, f64)>,
    pub(super) style: LineStyle,
}

pub(super) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart over `x` and `y` on `area` with every figure's margins, `y_label_px` layout pixels for the y
/// tick labels, at scale `s`.
pub(super) fn cartesian<'a, DB: DrawingBackend>(
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
pub(super) struct PixelMap {
    x: Range<f64>,
    y: Range<f64>,
    w: f64,
    h: f64,
}

impl PixelMap {
    pub(super) fn new<DB: DrawingBackend>(chart: &Chart<'_, DB>, x: Range<f64>, y: Range<f64>) -> Self {
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
pub(super) fn draw_line<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    map: &PixelMap,
    line: &Line,
    s: f64,
) -> Result<(), String> {
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
pub(super) fn titled<DB: DrawingBackend>(
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
pub(super) fn draw_legend<DB: DrawingBackend>(
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
pub(super) fn draw_mesh<DB: DrawingBackend>(
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
pub(super) fn draw_mesh_with<DB: DrawingBackend>(
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
