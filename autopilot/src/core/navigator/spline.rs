//! Smooth paths through waypoints and the progress along them, shared by the navigator's missions and
//! the scenario runner's figure-8. In: horizontal waypoints (N, E in m). Out: position, unit tangent and
//! curvature vector at an arc length (m), distances to the path; and a critically damped prefilter on the
//! along-track progress, so a reference moving along the path starts from rest, reaches its speed
//! smoothly and has exact velocity `P'(s) ṡ` and acceleration `P''(s) ṡ² + P'(s) s̈` feed-forward.
//!
//! The path is a C2 cubic spline (periodic when the last waypoint repeats the first, natural otherwise),
//! parametrised by arc length through a table of 400 samples per segment.

use nalgebra::{DMatrix, DVector, Vector2};

/// The figure-8 of the paper's tracking experiment as this project reads it (docs/choices.md): nine
/// waypoints (N, E in m) on a 0.6 m grid, closed, so the path through them is a periodic spline. The
/// built-in `figure8` scenario and the ground-station scripts fly these points.
pub const FIGURE8_NE_M: [[f64; 2]; 9] =
    [[0.0, 0.0], [0.6, 0.6], [1.2, 0.0], [0.6, -0.6], [0.0, 0.0], [-0.6, 0.6], [-1.2, 0.0], [-0.6, -0.6], [0.0, 0.0]];

/// The critically damped second-order prefilter of the progress along a path:
/// `s̈ = wn² (r - s) - 2 wn ṡ`, for a target progress `r` (m) that the caller moves at the cruise speed
/// and clamps at the path's end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgressFilter {
    /// Natural frequency (rad/s).
    pub wn_radps: f64,
    /// Progress (m) and its rate (m/s).
    pub s_m: f64,
    pub s_dot_mps: f64,
}

impl ProgressFilter {
    /// At rest at progress `s_m`.
    #[must_use]
    pub fn at_rest(wn_radps: f64, s_m: f64) -> Self {
        Self { wn_radps, s_m, s_dot_mps: 0.0 }
    }

    /// `s̈` (m/s²) towards `target_m` now.
    #[must_use]
    pub fn accel_mps2(&self, target_m: f64) -> f64 {
        let wn = self.wn_radps;
        wn * wn * (target_m - self.s_m) - 2.0 * wn * self.s_dot_mps
    }

    /// One semi-implicit Euler step of `dt_s` towards `target_m`.
    pub fn step(&mut self, target_m: f64, dt_s: f64) {
        self.s_dot_mps += self.accel_mps2(target_m) * dt_s;
        self.s_m += self.s_dot_mps * dt_s;
    }
}

/// A C2 cubic spline through waypoints (periodic if closed, natural if open), with an arc-length table.
#[derive(Debug, Clone)]
pub struct SplinePath {
    points: Vec<Vector2<f64>>,
    /// Second derivatives at the knots (uniform knot parameter u = 0, 1, ..., n_seg).
    second: Vec<Vector2<f64>>,
    closed: bool,
    /// Arc length at u = j / SAMPLES_PER_SEGMENT.
    arc_m: Vec<f64>,
    /// Points every `POLYLINE_STEP_M` of arc length, for distance queries.
    polyline: Vec<Vector2<f64>>,
}

const POLYLINE_STEP_M: f64 = 0.005;

const SAMPLES_PER_SEGMENT: usize = 400;

impl SplinePath {
    /// The path through `waypoints_ne_m` (N, E in m), closed when the last repeats the first.
    ///
    /// # Panics
    /// If the waypoints are not a usable path (see [`SplinePath::try_new`]); scenario files are validated
    /// before this is called.
    #[must_use]
    pub fn new(waypoints_ne_m: &[[f64; 2]]) -> Self {
        Self::try_new(waypoints_ne_m).expect("validated waypoints")
    }

    /// The path through `waypoints_ne_m`, or `None` when they do not make one: fewer than two distinct
    /// points, a non-finite coordinate, two consecutive equal points, or a closed path of fewer than
    /// three distinct points. Two points make a straight line (a natural spline).
    #[must_use]
    pub fn try_new(waypoints_ne_m: &[[f64; 2]]) -> Option<Self> {
        let mut points: Vec<Vector2<f64>> = waypoints_ne_m.iter().map(|w| Vector2::new(w[0], w[1])).collect();
        if points.len() < 2
            || points.iter().any(|p| !p.iter().all(|x| x.is_finite()))
            || points.windows(2).any(|w| (w[1] - w[0]).norm() < 1e-6)
        {
            return None;
        }
        let closed = points.len() >= 4 && points.first() == points.last();
        if closed {
            points.pop();
        }
        let n = points.len();
        // Solve for knot second derivatives M: M[i-1] + 4 M[i] + M[i+1] = 6 (P[i-1] - 2 P[i] + P[i+1]).
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut rhs = [DVector::<f64>::zeros(n), DVector::<f64>::zeros(n)];
        for i in 0..n {
            if !closed && (i == 0 || i == n - 1) {
                a[(i, i)] = 1.0; // natural end: M = 0
                continue;
            }
            let (im, ip) = ((i + n - 1) % n, (i + 1) % n);
            a[(i, im)] += 1.0;
            a[(i, i)] += 4.0;
            a[(i, ip)] += 1.0;
            let d = points[im] - 2.0 * points[i] + points[ip];
            rhs[0][i] = 6.0 * d.x;
            rhs[1][i] = 6.0 * d.y;
        }
        // Diagonally dominant, so the factorisation never fails for finite points.
        let lu = a.lu();
        let mx = lu.solve(&rhs[0])?;
        let my = lu.solve(&rhs[1])?;
        let second = (0..n).map(|i| Vector2::new(mx[i], my[i])).collect();
        let mut path = Self { points, second, closed, arc_m: Vec::new(), polyline: Vec::new() };
        let samples = path.segments() * SAMPLES_PER_SEGMENT;
        let mut arc = Vec::with_capacity(samples + 1);
        arc.push(0.0);
        let mut prev = path.point_u(0.0).0;
        for j in 1..=samples {
            let p = path.point_u(j as f64 / SAMPLES_PER_SEGMENT as f64).0;
            arc.push(arc[j - 1] + (p - prev).norm());
            prev = p;
        }
        path.arc_m = arc;
        if !(path.length_m() > 0.0 && path.length_m().is_finite()) {
            return None;
        }
        let count = (path.length_m() / POLYLINE_STEP_M).ceil() as usize;
        let step = path.length_m() / count as f64;
        path.polyline = (0..=count).map(|k| path.eval(k as f64 * step).0).collect();
        Some(path)
    }

    /// Arc length (m) at waypoint `i` (0 = the first; a closed path's last waypoint is at the lap's
    /// length).
    #[must_use]
    pub fn knot_arc_m(&self, i: usize) -> f64 {
        let j = (i * SAMPLES_PER_SEGMENT).min(self.arc_m.len() - 1);
        self.arc_m[j]
    }

    fn segments(&self) -> usize {
        if self.closed { self.points.len() } else { self.points.len() - 1 }
    }

    #[must_use]
    pub fn closed(&self) -> bool {
        self.closed
    }

    /// Length of one lap (m).
    #[must_use]
    pub fn length_m(&self) -> f64 {
        *self.arc_m.last().expect("arc table is non-empty")
    }

    /// Position, first and second derivative with respect to the knot parameter u.
    fn point_u(&self, u: f64) -> (Vector2<f64>, Vector2<f64>, Vector2<f64>) {
        let n = self.points.len();
        let seg_count = self.segments();
        let u = u.clamp(0.0, seg_count as f64);
        let i = (u.floor() as usize).min(seg_count - 1);
        let x = u - i as f64;
        let (p0, p1) = (self.points[i], self.points[(i + 1) % n]);
        let (m0, m1) = (self.second[i], self.second[(i + 1) % n]);
        let y = 1.0 - x;
        let p = y * p0 + x * p1 + ((y.powi(3) - y) * m0 + (x.powi(3) - x) * m1) / 6.0;
        let dp = p1 - p0 + ((-3.0 * y * y + 1.0) * m0 + (3.0 * x * x - 1.0) * m1) / 6.0;
        let d2p = y * m0 + x * m1;
        (p, dp, d2p)
    }

    /// Knot parameter u at arc length s within one lap.
    fn u_at(&self, s_m: f64) -> f64 {
        let s = s_m.clamp(0.0, self.length_m());
        let j = self.arc_m.partition_point(|&a| a <= s).clamp(1, self.arc_m.len() - 1);
        let (a0, a1) = (self.arc_m[j - 1], self.arc_m[j]);
        let frac = if a1 > a0 { (s - a0) / (a1 - a0) } else { 0.0 };
        (j as f64 - 1.0 + frac) / SAMPLES_PER_SEGMENT as f64
    }

    /// Position and its first and second derivatives with respect to arc length, at progress `s_m`
    /// (wrapping over laps when closed; clamped at the ends when open).
    #[must_use]
    pub fn eval(&self, s_m: f64) -> (Vector2<f64>, Vector2<f64>, Vector2<f64>) {
        let len = self.length_m();
        let s = if self.closed && s_m >= len { s_m.rem_euclid(len) } else { s_m };
        let (p, dp, d2p) = self.point_u(self.u_at(s));
        let speed = dp.norm();
        let t = dp / speed;
        // d2P/ds2 = (P'' - (t . P'') t) / |P'|^2: the curvature vector.
        let k = (d2p - t * t.dot(&d2p)) / (speed * speed);
        (p, t, k)
    }

    /// Distance (m) from `p_ne_m` to the path within `window_m` of arc length around `s_m` (so a point
    /// near a crossing is measured against its own branch), on a polyline of 5 mm segments, and the arc
    /// length (m, unwrapped like `s_m`) of the nearest point.
    #[must_use]
    pub fn nearest_near(&self, p_ne_m: Vector2<f64>, s_m: f64, window_m: f64) -> (f64, f64) {
        let segments = self.polyline.len() - 1;
        let step = self.length_m() / segments as f64;
        let lo = ((s_m - window_m) / step).floor() as i64;
        let hi = ((s_m + window_m) / step).ceil() as i64;
        let (lo, hi) = if self.closed { (lo, hi) } else { (lo.max(0), hi.min(segments as i64)) };
        // Segment k runs from point k mod n to point (k + 1) mod n; the index is stepped along rather than
        // reduced per segment.
        let mut i = usize::try_from(lo.rem_euclid(segments as i64)).expect("rem_euclid is non-negative");
        let mut best = (f64::INFINITY, s_m);
        for k in lo..hi {
            let next = if i + 1 == segments { 0 } else { i + 1 };
            let (d, x) = point_segment(p_ne_m, self.polyline[i], self.polyline[next]);
            if d < best.0 {
                best = (d, (k as f64 + x) * step);
            }
            i = next;
        }
        best
    }

    /// [`SplinePath::nearest_near`], the distance only.
    #[must_use]
    pub fn distance_near(&self, p_ne_m: Vector2<f64>, s_m: f64, window_m: f64) -> f64 {
        self.nearest_near(p_ne_m, s_m, window_m).0
    }
}

/// Distance from `p` to segment `ab` and the fraction along it of the nearest point.
fn point_segment(p: Vector2<f64>, a: Vector2<f64>, b: Vector2<f64>) -> (f64, f64) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let x = if len2 > 0.0 { ((p - a).dot(&ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    ((p - (a + ab * x)).norm(), x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figure8() -> Vec<[f64; 2]> {
        FIGURE8_NE_M.to_vec()
    }

    #[test]
    fn given_closed_waypoints_when_evaluated_then_the_spline_passes_through_each_and_is_unit_speed() {
        let path = SplinePath::new(&figure8());
        assert!(path.closed());
        for (i, w) in figure8().iter().enumerate().take(8) {
            let (p, _, _) = path.point_u(i as f64);
            assert!((p - Vector2::new(w[0], w[1])).norm() < 1e-12, "knot {i}");
        }
        for k in 0..50 {
            let (_, t, _) = path.eval(path.length_m() * k as f64 / 50.0);
            assert!((t.norm() - 1.0).abs() < 1e-9);
        }
        // A periodic spline is C1 across the seam.
        let (_, t0, _) = path.eval(1e-6);
        let (_, t1, _) = path.eval(path.length_m() - 1e-6);
        assert!((t0 - t1).norm() < 1e-4);
    }

    #[test]
    fn given_a_circle_of_points_when_evaluated_then_curvature_is_one_over_radius() {
        let r = 2.0;
        let pts: Vec<[f64; 2]> = (0..=24)
            .map(|k| {
                let a = std::f64::consts::TAU * f64::from(k % 24) / 24.0;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let path = SplinePath::new(&pts);
        assert!((path.length_m() - std::f64::consts::TAU * r).abs() < 1e-3);
        let (_, _, k) = path.eval(1.234);
        assert!((k.norm() - 1.0 / r).abs() < 2e-3, "curvature {}", k.norm());
    }

    #[test]
    fn given_a_point_off_the_path_then_distance_near_measures_it() {
        let path = SplinePath::new(&figure8());
        let (p, t, _) = path.eval(1.0);
        let normal = Vector2::new(-t.y, t.x);
        let d = path.distance_near(p + 0.05 * normal, 1.0, 0.5);
        assert!((d - 0.05).abs() < 1e-3, "{d}");
    }

    #[test]
    fn given_two_points_then_the_path_is_the_straight_line_and_degenerate_input_is_refused() {
        let path = SplinePath::try_new(&[[0.0, 0.0], [3.0, 4.0]]).expect("a line");
        assert!((path.length_m() - 5.0).abs() < 1e-9);
        let (p, t, k) = path.eval(2.5);
        assert!((p - Vector2::new(1.5, 2.0)).norm() < 1e-9 && (t - Vector2::new(0.6, 0.8)).norm() < 1e-9);
        assert!(k.norm() < 1e-9);
        assert!((path.knot_arc_m(1) - 5.0).abs() < 1e-9);
        assert!(SplinePath::try_new(&[[0.0, 0.0]]).is_none());
        assert!(SplinePath::try_new(&[[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]]).is_none());
        assert!(SplinePath::try_new(&[[0.0, 0.0], [f64::NAN, 0.0]]).is_none());
        let closed = SplinePath::new(&figure8());
        assert!((closed.knot_arc_m(8) - closed.length_m()).abs() < 1e-9);
        assert!(closed.knot_arc_m(4) > 0.4 * closed.length_m() && closed.knot_arc_m(4) < 0.6 * closed.length_m());
    }

    #[test]
    fn given_a_target_when_filtered_then_the_progress_settles_on_it_without_overshoot() {
        let mut f = ProgressFilter::at_rest(2.5, 0.0);
        let mut max: f64 = 0.0;
        for _ in 0..100_000 {
            f.step(1.0, 1e-4);
            max = max.max(f.s_m);
        }
        assert!((f.s_m - 1.0).abs() < 1e-3 && f.s_dot_mps.abs() < 1e-3, "{f:?}");
        assert!(max <= 1.0 + 1e-9, "critically damped: no overshoot ({max})");
    }
}
