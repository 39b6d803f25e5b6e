//! The two shapes a scenario track can take through its waypoints: the C2 spline of the navigator, or
//! straight segments (a polyline). In: horizontal waypoints (N, E in m), closed when the last repeats
//! the first (and there are at least four). Out: position, unit tangent and curvature vector at an arc
//! length (m), and the distance (m) from a point to the path near a given arc length.
//!
//! A polyline's tangent is constant along each segment and jumps at the waypoints; its curvature is zero
//! everywhere (the turn at a corner is concentrated at one point). At a corner the arc length belongs to
//! the segment that starts there.

pub use autopilot::core::navigator::spline::SplinePath;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

/// Which path a track's reference follows through its waypoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    /// A C2 cubic spline through the waypoints (periodic when closed), as the navigator flies missions.
    #[default]
    Spline,
    /// Straight segments between consecutive waypoints.
    Polyline,
}

/// A track's path: either kind, with one interface for the reference generator and the metrics.
#[derive(Debug, Clone)]
pub enum TrackPath {
    Spline(SplinePath),
    Polyline(PolylinePath),
}

impl TrackPath {
    /// The path of `kind` through `waypoints_ne_m` (N, E in m).
    ///
    /// # Panics
    /// If the waypoints do not make a path (fewer than two, non-finite, or two consecutive equal points);
    /// scenario files are validated before this is called.
    #[must_use]
    pub fn new(kind: PathKind, waypoints_ne_m: &[[f64; 2]]) -> Self {
        match kind {
            PathKind::Spline => Self::Spline(SplinePath::new(waypoints_ne_m)),
            PathKind::Polyline => Self::Polyline(PolylinePath::new(waypoints_ne_m).expect("validated waypoints")),
        }
    }

    /// Length of one lap (m).
    #[must_use]
    pub fn length_m(&self) -> f64 {
        match self {
            Self::Spline(p) => p.length_m(),
            Self::Polyline(p) => p.length_m(),
        }
    }

    /// Position (m), unit tangent and curvature vector (1/m) at progress `s_m`, wrapping over laps when
    /// closed and clamped at the ends when open.
    #[must_use]
    pub fn eval(&self, s_m: f64) -> (Vector2<f64>, Vector2<f64>, Vector2<f64>) {
        match self {
            Self::Spline(p) => p.eval(s_m),
            Self::Polyline(p) => p.eval(s_m),
        }
    }

    /// Distance (m) from `p_ne_m` to the path near arc length `s_m` and the arc length (m, unwrapped like
    /// `s_m`) of the nearest point. See [`SplinePath::nearest_near`] and [`PolylinePath::nearest_near`]
    /// for what "near" covers.
    #[must_use]
    pub fn nearest_near(&self, p_ne_m: Vector2<f64>, s_m: f64, window_m: f64) -> (f64, f64) {
        match self {
            Self::Spline(p) => p.nearest_near(p_ne_m, s_m, window_m),
            Self::Polyline(p) => p.nearest_near(p_ne_m, s_m, window_m),
        }
    }
}

/// Straight segments through waypoints, parametrised by arc length.
#[derive(Debug, Clone)]
pub struct PolylinePath {
    /// The waypoints; a closed path's last point repeats its first.
    points: Vec<Vector2<f64>>,
    /// Arc length (m) at each point: `cum_m[0] = 0`, the last is the lap's length.
    cum_m: Vec<f64>,
    /// Unit direction of each segment.
    tangent: Vec<Vector2<f64>>,
    closed: bool,
}

impl PolylinePath {
    /// The polyline through `waypoints_ne_m` (N, E in m), closed when there are at least four and the last
    /// repeats the first (the spline's rule); `None` for fewer than two points, a non-finite coordinate or
    /// two consecutive points closer than 1 µm.
    #[must_use]
    pub fn new(waypoints_ne_m: &[[f64; 2]]) -> Option<Self> {
        let points: Vec<Vector2<f64>> = waypoints_ne_m.iter().map(|w| Vector2::new(w[0], w[1])).collect();
        if points.len() < 2
            || points.iter().any(|p| !p.iter().all(|x| x.is_finite()))
            || points.windows(2).any(|w| (w[1] - w[0]).norm() < 1e-6)
        {
            return None;
        }
        let closed = points.len() >= 4 && points.first() == points.last();
        let mut cum_m = vec![0.0];
        let mut tangent = Vec::with_capacity(points.len() - 1);
        for w in points.windows(2) {
            let d = w[1] - w[0];
            let len = d.norm();
            cum_m.push(cum_m.last().copied().unwrap_or(0.0) + len);
            tangent.push(d / len);
        }
        Some(Self { points, cum_m, tangent, closed })
    }

    /// Length of one lap (m).
    #[must_use]
    pub fn length_m(&self) -> f64 {
        *self.cum_m.last().expect("at least two points")
    }

    #[must_use]
    pub fn closed(&self) -> bool {
        self.closed
    }

    fn segments(&self) -> usize {
        self.tangent.len()
    }

    /// The segment holding arc length `s_m` of one lap (clamped to the lap).
    fn segment_at(&self, s_m: f64) -> usize {
        self.cum_m[1..].partition_point(|&c| c <= s_m).min(self.segments() - 1)
    }

    /// Position (m), unit tangent and curvature vector (zero) at progress `s_m` (wrapping over laps when
    /// closed, clamped at the ends when open).
    #[must_use]
    pub fn eval(&self, s_m: f64) -> (Vector2<f64>, Vector2<f64>, Vector2<f64>) {
        let len = self.length_m();
        let s = if self.closed && s_m >= len { s_m.rem_euclid(len) } else { s_m }.clamp(0.0, len);
        let i = self.segment_at(s);
        let t = self.tangent[i];
        (self.points[i] + t * (s - self.cum_m[i]), t, Vector2::zeros())
    }

    /// Distance (m) from `p_ne_m` to the polyline and the arc length (m, unwrapped like `s_m`) of the
    /// nearest point, searched over every segment that overlaps `[s_m - window_m, s_m + window_m]` and the
    /// segment before and after them, each in full. A point near a crossing is thus measured against its
    /// own branch (the segments next to it in arc length), and a point cutting a corner against the nearer
    /// of the corner's two segments, however far the corner is.
    #[must_use]
    pub fn nearest_near(&self, p_ne_m: Vector2<f64>, s_m: f64, window_m: f64) -> (f64, f64) {
        let len = self.length_m();
        let n = self.segments() as i64;
        // The global index (lap · n + segment) of the segment holding an unwrapped arc length.
        let global = |s: f64| -> i64 {
            if self.closed {
                let lap = (s / len).floor();
                lap as i64 * n + self.segment_at(s - lap * len) as i64
            } else {
                self.segment_at(s.clamp(0.0, len)) as i64
            }
        };
        let (mut lo, mut hi) = (global(s_m - window_m) - 1, global(s_m + window_m) + 1);
        if !self.closed {
            (lo, hi) = (lo.max(0), hi.min(n - 1));
        }
        let mut best = (f64::INFINITY, s_m);
        for k in lo..=hi {
            let i = usize::try_from(k.rem_euclid(n)).expect("rem_euclid is non-negative");
            let lap = k.div_euclid(n) as f64;
            let (a, t) = (self.points[i], self.tangent[i]);
            let seg_len = self.cum_m[i + 1] - self.cum_m[i];
            let x = (p_ne_m - a).dot(&t).clamp(0.0, seg_len);
            let d = (p_ne_m - (a + t * x)).norm();
            if d < best.0 {
                best = (d, lap * len + self.cum_m[i] + x);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [[f64; 2]; 5] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];

    #[test]
    fn given_a_square_then_eval_walks_its_straight_sides_at_unit_speed() {
        let path = PolylinePath::new(&SQUARE).unwrap();
        assert!(path.closed());
        assert_eq!(path.length_m(), 4.0);
        let (p, t, k) = path.eval(0.25);
        assert_eq!((p, t, k), (Vector2::new(0.25, 0.0), Vector2::new(1.0, 0.0), Vector2::zeros()));
        // The corner belongs to the segment that starts there.
        let (p, t, _) = path.eval(1.0);
        assert_eq!((p, t), (Vector2::new(1.0, 0.0), Vector2::new(0.0, 1.0)));
        let (p, t, _) = path.eval(2.5);
        assert_eq!((p, t), (Vector2::new(0.5, 1.0), Vector2::new(-1.0, 0.0)));
        // A second lap wraps.
        assert!((path.eval(5.5).0 - Vector2::new(1.0, 0.5)).norm() < 1e-12);
    }

    #[test]
    fn given_a_point_beside_a_side_then_its_distance_is_to_the_straight_segment() {
        let poly = TrackPath::new(PathKind::Polyline, &SQUARE);
        let spline = TrackPath::new(PathKind::Spline, &SQUARE);
        let p = Vector2::new(0.5, 0.1);
        let (d, s) = poly.nearest_near(p, 0.5, 0.05);
        assert!((d - 0.1).abs() < 1e-12 && (s - 0.5).abs() < 1e-12, "{d} {s}");
        // The spline through the same corners bulges outward between them: not the same distance.
        let (ds, _) = spline.nearest_near(p, 0.5, 0.05);
        assert!(ds > 0.15, "{ds}");
    }

    #[test]
    fn given_a_point_cutting_a_corner_then_the_nearer_side_counts_even_beyond_the_window() {
        let path = PolylinePath::new(&SQUARE).unwrap();
        // 0.2 m inside the first corner, 0.1 m before it: nearer the second side (0.1 m) than the first.
        let (d, s) = path.nearest_near(Vector2::new(0.9, 0.2), 0.9, 0.05);
        assert!((d - 0.1).abs() < 1e-12 && (s - 1.2).abs() < 1e-12, "{d} {s}");
        // Unwrapped over laps: the same point a lap later.
        let (d2, s2) = path.nearest_near(Vector2::new(0.9, 0.2), 4.9, 0.05);
        assert!((d2 - d).abs() < 1e-12 && (s2 - 5.2).abs() < 1e-12, "{d2} {s2}");
    }

    #[test]
    fn given_a_figure8_polyline_then_a_point_at_the_crossing_stays_on_its_branch() {
        let fig8 = autopilot::core::navigator::spline::FIGURE8_NE_M;
        let path = PolylinePath::new(&fig8).unwrap();
        // Tracked just past the crossing on the diagonal N = -E (s = 4 sides), at a point much nearer the
        // other diagonal N = E (0.007 m) than its own (0.078 m): it is measured against its own.
        let side = 0.6 * 2f64.sqrt();
        let p = Vector2::new(0.05, 0.06);
        let (d, s) = path.nearest_near(p, 4.0 * side + 0.05, 0.05);
        let own = (p.x + p.y).abs() / 2f64.sqrt();
        assert!((d - own).abs() < 1e-12, "{d} vs {own}");
        assert!(s > 4.0 * side && s < 4.0 * side + 0.05, "{s}");
    }

    #[test]
    fn given_the_figure8_waypoints_as_a_spline_then_a_lap_is_7_23_m_and_24_1_s_at_0_3_mps() {
        // docs/choices.md's figure-8 ("7.23 m a lap, 24.1 s at 0.3 m/s"), to its printed digits.
        let lap_m = TrackPath::new(PathKind::Spline, &autopilot::core::navigator::spline::FIGURE8_NE_M).length_m();
        assert_eq!((format!("{lap_m:.2}"), format!("{:.1}", lap_m / 0.3)), ("7.23".to_owned(), "24.1".to_owned()));
    }

    #[test]
    fn given_bad_waypoints_then_there_is_no_polyline() {
        assert!(PolylinePath::new(&[[0.0, 0.0]]).is_none());
        assert!(PolylinePath::new(&[[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]]).is_none());
        assert!(PolylinePath::new(&[[0.0, 0.0], [f64::NAN, 0.0]]).is_none());
        let open = PolylinePath::new(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]).unwrap();
        assert!(!open.closed());
        // Open: clamped at the ends.
        assert_eq!(open.eval(5.0).0, Vector2::new(1.0, 1.0));
        assert_eq!(open.nearest_near(Vector2::new(2.0, 1.0), 2.0, 0.05).0, 1.0);
    }
}
