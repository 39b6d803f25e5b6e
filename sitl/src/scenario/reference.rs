//! Reference generators for scenarios: step schedules (position or attitude) and a closed waypoint track.
//!
//! In: simulated time `t_s`, monotonically non-decreasing. Out: an `autopilot` [`Reference`] (NED, metres,
//! radians; feed-forward velocity and acceleration for tracks). Evaluated once per control tick.
//!
//! The track is a C2 cubic spline through the waypoints (periodic when the last waypoint repeats the
//! first), parametrised by arc length. The prefilter (critically damped, natural frequency `wf`) acts on
//! the along-track progress `s(t)`, not on the position: the reference therefore never leaves the path,
//! starts from rest and reaches the commanded speed smoothly, and its velocity `P'(s) s_dot` and
//! acceleration `P''(s) s_dot^2 + P'(s) s_ddot` are exact feed-forward for it.

use autopilot::core::control::Reference;
use nalgebra::{DMatrix, DVector, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::ScenarioError;

/// One step of an attitude schedule: from `t_s` on, hold `euler_rad` (phi, theta, psi; NED/FRD ZYX).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttitudeStep {
    pub t_s: f64,
    pub euler_rad: [f64; 3],
}

/// One step of a position schedule: from `t_s` on, hold `pos_ned_m` with heading `yaw_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionStep {
    pub t_s: f64,
    pub pos_ned_m: [f64; 3],
    #[serde(default)]
    pub yaw_rad: f64,
}

/// How a track's reference is handed to the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferenceMode {
    /// Position, velocity and acceleration of the prefiltered reference.
    FeedForward,
    /// Position of the prefiltered reference only (velocity and acceleration zero).
    PositionOnly,
}

impl std::fmt::Display for ReferenceMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::FeedForward => "feed-forward",
            Self::PositionOnly => "position-only",
        })
    }
}

/// A waypoint track flown at constant speed and altitude.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackSpec {
    /// Horizontal waypoints (N, E) in metres. The track is closed when the last repeats the first.
    pub waypoints_ne_m: Vec<[f64; 2]>,
    pub pos_d_m: f64,
    pub speed_mps: f64,
    /// Natural frequency of the critically damped progress prefilter.
    pub prefilter_wn_radps: f64,
    /// Time at which the reference starts to move (it holds the first waypoint before).
    pub start_s: f64,
    #[serde(default = "one")]
    pub laps: u32,
    #[serde(default)]
    pub yaw_rad: f64,
    /// Each mode is one run of the scenario.
    pub reference_modes: Vec<ReferenceMode>,
}

fn one() -> u32 {
    1
}

/// The reference part of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ReferenceSpec {
    /// The paper's Fig. 5 mode: scripted attitude, altitude held at `pos_d_m`.
    Attitude {
        pos_d_m: f64,
        steps: Vec<AttitudeStep>,
    },
    Position {
        steps: Vec<PositionStep>,
    },
    Track(TrackSpec),
}

impl ReferenceSpec {
    /// Checks the schedule or track for a clear error before anything runs.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the problem.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let check_times = |times: &mut dyn Iterator<Item = f64>| -> Result<(), ScenarioError> {
            let mut last = f64::NEG_INFINITY;
            let mut any = false;
            for t in times {
                any = true;
                if !t.is_finite() || t < 0.0 || t <= last {
                    return Err(invalid("reference steps need finite, increasing t_s >= 0"));
                }
                last = t;
            }
            if any { Ok(()) } else { Err(invalid("reference needs at least one step")) }
        };
        match self {
            Self::Attitude { pos_d_m, steps } => {
                check_times(&mut steps.iter().map(|s| s.t_s))?;
                if !pos_d_m.is_finite() || steps.iter().any(|s| !finite(&s.euler_rad)) {
                    return Err(invalid("attitude reference values must be finite"));
                }
                if steps.iter().any(|s| s.euler_rad[0].abs() > 0.5 || s.euler_rad[1].abs() > 0.5) {
                    return Err(invalid("attitude steps must keep |roll|, |pitch| <= 0.5 rad (the tilt limit)"));
                }
            }
            Self::Position { steps } => {
                check_times(&mut steps.iter().map(|s| s.t_s))?;
                if steps.iter().any(|s| !finite(&s.pos_ned_m) || !s.yaw_rad.is_finite()) {
                    return Err(invalid("position reference values must be finite"));
                }
            }
            Self::Track(track) => {
                if track.waypoints_ne_m.len() < 3 {
                    return Err(invalid("a track needs at least 3 waypoints"));
                }
                if track.waypoints_ne_m.iter().any(|w| !finite(w)) {
                    return Err(invalid("track waypoints must be finite"));
                }
                if track.waypoints_ne_m.windows(2).any(|w| w[0] == w[1]) {
                    return Err(invalid("consecutive track waypoints must differ"));
                }
                if !(track.speed_mps > 0.0 && track.speed_mps <= 3.0) {
                    return Err(invalid("track speed_mps must be in (0, 3] m/s"));
                }
                if !(track.prefilter_wn_radps > 0.0 && track.prefilter_wn_radps.is_finite()) {
                    return Err(invalid("track prefilter_wn_radps must be > 0"));
                }
                if !track.start_s.is_finite()
                    || track.start_s < 0.0
                    || !track.pos_d_m.is_finite()
                    || !track.yaw_rad.is_finite()
                {
                    return Err(invalid("track start_s must be >= 0 and pos_d_m, yaw_rad finite"));
                }
                if track.laps == 0 || track.reference_modes.is_empty() {
                    return Err(invalid("a track needs laps >= 1 and at least one reference mode"));
                }
            }
        }
        Ok(())
    }
}

fn invalid(msg: &str) -> ScenarioError {
    ScenarioError::Invalid(msg.to_owned())
}

/// A reference generator for one run.
#[derive(Debug, Clone)]
pub enum ReferenceGen {
    Attitude { pos_d_m: f64, steps: Vec<AttitudeStep> },
    Position { steps: Vec<PositionStep> },
    Track(TrackGen),
}

impl ReferenceGen {
    /// Builds the generator; `mode` selects feed-forward for tracks and is ignored otherwise.
    #[must_use]
    pub fn new(spec: &ReferenceSpec, mode: ReferenceMode) -> Self {
        match spec {
            ReferenceSpec::Attitude { pos_d_m, steps } => Self::Attitude { pos_d_m: *pos_d_m, steps: steps.clone() },
            ReferenceSpec::Position { steps } => Self::Position { steps: steps.clone() },
            ReferenceSpec::Track(track) => Self::Track(TrackGen::new(track, mode)),
        }
    }

    /// The reference at `t_s`. Before the first step, the first step applies.
    pub fn at(&mut self, t_s: f64) -> Reference {
        match self {
            Self::Attitude { pos_d_m, steps } => {
                let s = active(steps, t_s, |s| s.t_s);
                Reference::attitude(Vector3::from(s.euler_rad), *pos_d_m)
            }
            Self::Position { steps } => {
                let s = active(steps, t_s, |s| s.t_s);
                Reference::position(Vector3::from(s.pos_ned_m), s.yaw_rad)
            }
            Self::Track(track) => track.at(t_s),
        }
    }
}

/// The last item whose start time is <= t (or the first, before it). `items` is non-empty and sorted.
fn active<T: Copy>(items: &[T], t_s: f64, start: impl Fn(&T) -> f64) -> T {
    // A step at t applies from the tick at t on; 1e-9 s absorbs tick-time rounding.
    let idx = items.partition_point(|i| start(i) <= t_s + 1e-9);
    items[idx.saturating_sub(1)]
}

/// The prefiltered progress along a spline path.
#[derive(Debug, Clone)]
pub struct TrackGen {
    pub path: SplinePath,
    spec: TrackSpec,
    mode: ReferenceMode,
    /// Prefilter state: progress (m) and its rate (m/s), after `filter_steps` steps.
    s_m: f64,
    s_dot_mps: f64,
    filter_steps: u64,
}

/// The prefilter is integrated at this fixed step, whatever the control rate, so the reference is the
/// same function of time at every loop rate.
const PREFILTER_STEP_S: f64 = 1e-4;

impl TrackGen {
    #[must_use]
    pub fn new(spec: &TrackSpec, mode: ReferenceMode) -> Self {
        Self {
            path: SplinePath::new(&spec.waypoints_ne_m),
            spec: spec.clone(),
            mode,
            s_m: 0.0,
            s_dot_mps: 0.0,
            filter_steps: 0,
        }
    }

    /// Total arc length the reference travels (all laps).
    #[must_use]
    pub fn total_length_m(&self) -> f64 {
        self.path.length_m() * f64::from(self.spec.laps)
    }

    /// The time at which the unfiltered progress reaches the end of the last lap.
    #[must_use]
    pub fn end_s(&self) -> f64 {
        self.spec.start_s + self.total_length_m() / self.spec.speed_mps
    }

    fn raw_progress_m(&self, t_s: f64) -> f64 {
        ((t_s - self.spec.start_s) * self.spec.speed_mps).clamp(0.0, self.total_length_m())
    }

    /// Progress along the path (m) of the prefiltered reference at `t_s`.
    pub fn progress_m(&mut self, t_s: f64) -> f64 {
        let wf = self.spec.prefilter_wn_radps;
        // Steps are counted, not summed as time, so every tick integrates exactly its share.
        let target_steps = (t_s / PREFILTER_STEP_S + 1e-6).floor().max(0.0) as u64;
        while self.filter_steps < target_steps {
            // Semi-implicit Euler at 0.1 ms on s_ddot = wf^2 (r - s) - 2 wf s_dot: error far below
            // anything a metric resolves.
            let r = self.raw_progress_m(self.filter_time_s());
            let s_ddot = wf * wf * (r - self.s_m) - 2.0 * wf * self.s_dot_mps;
            self.s_dot_mps += s_ddot * PREFILTER_STEP_S;
            self.s_m += self.s_dot_mps * PREFILTER_STEP_S;
            self.filter_steps += 1;
        }
        self.s_m
    }

    fn filter_time_s(&self) -> f64 {
        self.filter_steps as f64 * PREFILTER_STEP_S
    }

    pub fn at(&mut self, t_s: f64) -> Reference {
        let s = self.progress_m(t_s);
        let wf = self.spec.prefilter_wn_radps;
        let s_ddot = wf * wf * (self.raw_progress_m(self.filter_time_s()) - s) - 2.0 * wf * self.s_dot_mps;
        let (p, dp_ds, d2p_ds2) = self.path.eval(s);
        let d = self.spec.pos_d_m;
        let mut reference = Reference::position(Vector3::new(p.x, p.y, d), self.spec.yaw_rad);
        if self.mode == ReferenceMode::FeedForward {
            let v = dp_ds * self.s_dot_mps;
            let a = d2p_ds2 * self.s_dot_mps.powi(2) + dp_ds * s_ddot;
            reference.vel_ned_mps = Vector3::new(v.x, v.y, 0.0);
            reference.acc_ned_mps2 = Vector3::new(a.x, a.y, 0.0);
        }
        reference
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
    /// # Panics
    /// If fewer than 3 waypoints are given ([`ReferenceSpec::validate`] refuses that first).
    #[must_use]
    pub fn new(waypoints_ne_m: &[[f64; 2]]) -> Self {
        assert!(waypoints_ne_m.len() >= 3, "a spline path needs >= 3 waypoints");
        let mut points: Vec<Vector2<f64>> = waypoints_ne_m.iter().map(|w| Vector2::new(w[0], w[1])).collect();
        let closed = points.first() == points.last();
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
        let lu = a.lu();
        let mx = lu.solve(&rhs[0]).expect("spline system is diagonally dominant");
        let my = lu.solve(&rhs[1]).expect("spline system is diagonally dominant");
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
        let count = (path.length_m() / POLYLINE_STEP_M).ceil() as usize;
        let step = path.length_m() / count as f64;
        path.polyline = (0..=count).map(|k| path.eval(k as f64 * step).0).collect();
        path
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
        let n = segments as i64;
        let point = |k: i64| self.polyline[usize::try_from(k.rem_euclid(n)).expect("rem_euclid is non-negative")];
        let mut best = (f64::INFINITY, s_m);
        for k in lo..hi {
            let (a, b) = (point(k), point(k + 1));
            let (d, x) = point_segment(p_ne_m, a, b);
            if d < best.0 {
                best = (d, (k as f64 + x) * step);
            }
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
        vec![
            [0.0, 0.0],
            [0.6, 0.6],
            [1.2, 0.0],
            [0.6, -0.6],
            [0.0, 0.0],
            [-0.6, 0.6],
            [-1.2, 0.0],
            [-0.6, -0.6],
            [0.0, 0.0],
        ]
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
    fn given_a_track_when_followed_then_feed_forward_is_the_derivative_of_the_reference() {
        let spec = TrackSpec {
            waypoints_ne_m: figure8(),
            pos_d_m: -1.5,
            speed_mps: 0.3,
            prefilter_wn_radps: 2.5,
            start_s: 1.0,
            laps: 1,
            yaw_rad: 0.0,
            reference_modes: vec![ReferenceMode::FeedForward],
        };
        let mut track = TrackGen::new(&spec, ReferenceMode::FeedForward);
        let dt = 0.002;
        let mut prev = track.at(0.0);
        assert_eq!(prev.vel_ned_mps, Vector3::zeros());
        let mut max_speed: f64 = 0.0;
        for k in 1..15_000 {
            let t = f64::from(k) * dt;
            let r = track.at(t);
            let fd_v = (r.pos_ned_m - prev.pos_ned_m) / dt;
            let mid_v = (r.vel_ned_mps + prev.vel_ned_mps) / 2.0;
            assert!((fd_v - mid_v).norm() < 2e-3, "t {t}: fd {fd_v:?} ff {mid_v:?}");
            let fd_a = (r.vel_ned_mps - prev.vel_ned_mps) / dt;
            let mid_a = (r.acc_ned_mps2 + prev.acc_ned_mps2) / 2.0;
            assert!((fd_a - mid_a).norm() < 2e-2, "t {t}: fd {fd_a:?} ff {mid_a:?}");
            max_speed = max_speed.max(r.vel_ned_mps.norm());
            prev = r;
        }
        assert!((max_speed - 0.3).abs() < 1e-3, "cruise speed {max_speed}");
        // After the end, the reference comes to rest back at the start of the closed track.
        let r = track.at(track.end_s() + 10.0);
        assert!(r.pos_ned_m.xy().norm() < 1e-3 && r.vel_ned_mps.norm() < 1e-3);
    }

    #[test]
    fn given_position_only_mode_then_the_reference_has_no_feed_forward() {
        let spec = TrackSpec {
            waypoints_ne_m: figure8(),
            pos_d_m: -1.5,
            speed_mps: 0.3,
            prefilter_wn_radps: 2.5,
            start_s: 0.0,
            laps: 1,
            yaw_rad: 0.0,
            reference_modes: vec![ReferenceMode::PositionOnly],
        };
        let mut ff = TrackGen::new(&spec, ReferenceMode::FeedForward);
        let mut po = TrackGen::new(&spec, ReferenceMode::PositionOnly);
        let (a, b) = (ff.at(5.0), po.at(5.0));
        assert_eq!(a.pos_ned_m, b.pos_ned_m);
        assert!(a.vel_ned_mps.norm() > 0.2);
        assert_eq!(b.vel_ned_mps, Vector3::zeros());
        assert_eq!(b.acc_ned_mps2, Vector3::zeros());
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
    fn given_a_step_schedule_then_each_step_applies_from_its_time() {
        let spec = ReferenceSpec::Attitude {
            pos_d_m: -3.0,
            steps: vec![
                AttitudeStep { t_s: 0.0, euler_rad: [0.0; 3] },
                AttitudeStep { t_s: 6.0, euler_rad: [-0.2, 0.2, 0.2] },
            ],
        };
        spec.validate().unwrap();
        let mut g = ReferenceGen::new(&spec, ReferenceMode::FeedForward);
        assert_eq!(g.at(5.998).attitude_rad, Some(Vector3::zeros()));
        assert_eq!(g.at(6.0).attitude_rad, Some(Vector3::new(-0.2, 0.2, 0.2)));
        assert_eq!(g.at(6.0).pos_ned_m.z, -3.0);
    }

    #[test]
    fn given_bad_references_then_validate_says_what_is_wrong() {
        let bad = ReferenceSpec::Position {
            steps: vec![
                PositionStep { t_s: 1.0, pos_ned_m: [0.0; 3], yaw_rad: 0.0 },
                PositionStep { t_s: 1.0, pos_ned_m: [1.0; 3], yaw_rad: 0.0 },
            ],
        };
        assert!(bad.validate().unwrap_err().to_string().contains("increasing"));
        let tilt = ReferenceSpec::Attitude {
            pos_d_m: -1.0,
            steps: vec![AttitudeStep { t_s: 0.0, euler_rad: [0.7, 0.0, 0.0] }],
        };
        assert!(tilt.validate().unwrap_err().to_string().contains("0.5 rad"));
    }
}
