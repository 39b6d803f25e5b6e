//! Tests of the figures: ticks, ranges, clipping, styles, downsampling and the files written.

use plotters::coord::types::RangedCoordf64;

use super::draw::{clip_y, dashes, fmt_tick, tick_decimals, y_range};
use super::*;
use crate::scenario::runner::Trace;

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
    let runs = [Run { label: "ACO", trace: &aco }, Run { label: "CA", trace: &ca }, Run { label: "PID", trace: &pid }];
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
