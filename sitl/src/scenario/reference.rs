//! Reference generators for scenarios: step schedules (position, attitude or body rates) and a waypoint
//! track.
//!
//! In: simulated time `t_s`, monotonically non-decreasing. Out: an `autopilot` [`Reference`] (NED, metres,
//! radians; feed-forward velocity and acceleration for tracks, and for position steps that carry it).
//! Evaluated once per control tick.
//!
//! The track is a path through the waypoints ([`TrackPath`]: a C2 cubic spline, periodic when the last
//! waypoint repeats the first, or straight segments), parametrised by arc length. The prefilter
//! (critically damped, natural frequency `wf`) acts on the along-track progress `s(t)`, not on the
//! position: the reference therefore never leaves the path, starts from rest and reaches the commanded
//! speed smoothly, and its velocity `P'(s) s_dot` and acceleration `P''(s) s_dot^2 + P'(s) s_ddot` are
//! exact feed-forward for it. On a polyline `P'` is the current segment's direction and `P''` is zero:
//! the speed is constant along each segment and the velocity turns instantly at a corner (a velocity
//! step; the corner's impulse of acceleration is not fed forward).

use autopilot::core::control::Reference;
use autopilot::core::navigator::spline::ProgressFilter;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::ScenarioError;
pub use super::path::{PathKind, SplinePath, TrackPath};

/// One step of an attitude schedule: from `t_s` on, hold `euler_rad` (phi, theta, psi; NED/FRD ZYX).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttitudeStep {
    pub t_s: f64,
    pub euler_rad: [f64; 3],
}

/// One step of a body-rate schedule (the rate level): from `t_s` on, turn at `rate_frd_radps` (FRD).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RateStep {
    pub t_s: f64,
    pub rate_frd_radps: [f64; 3],
}

/// One step of a position schedule: from `t_s` on, hold `pos_ned_m` with heading `yaw_rad`, handing the
/// controller `vel_ned_mps` and `acc_ned_mps2` as feed-forward (zero by default: a plain step).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionStep {
    pub t_s: f64,
    pub pos_ned_m: [f64; 3],
    #[serde(default)]
    pub yaw_rad: f64,
    /// Velocity feed-forward (m/s, NED).
    #[serde(default)]
    pub vel_ned_mps: [f64; 3],
    /// Acceleration feed-forward (m/s², NED).
    #[serde(default)]
    pub acc_ned_mps2: [f64; 3],
}

/// How a track's reference is handed to the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferenceMode {
    /// Position, velocity and acceleration of the prefiltered reference.
    FeedForward,
    /// Position of the prefiltered reference only (velocity and acceleration zero).
    PositionOnly,
    /// Position, velocity, acceleration and jerk of the prefiltered reference: the jerk lets ACO and PID
    /// lead their tilt (`control::tilt_lead_mps2`), as they do on the navigator's trajectories.
    FeedForwardJerk,
}

impl std::fmt::Display for ReferenceMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::FeedForward => "feed-forward",
            Self::PositionOnly => "position-only",
            Self::FeedForwardJerk => "feed-forward-jerk",
        })
    }
}

/// A waypoint track flown at constant speed and altitude.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackSpec {
    /// Horizontal waypoints (N, E) in metres. The track is closed when the last repeats the first.
    pub waypoints_ne_m: Vec<[f64; 2]>,
    /// The path through them: a spline (default) or straight segments.
    #[serde(default)]
    pub path: PathKind,
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

/// The reference part of a scenario file: a table with `kind` and that kind's keys.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
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
    /// The rate level: scripted body rates with a constant collective thrust (0-1, normalized as offboard
    /// thrust); position and attitude are not controlled. Only a controller with a rate loop flies it.
    Rates {
        thrust_frac: f64,
        steps: Vec<RateStep>,
    },
}

/// Read by hand rather than as serde's internally tagged enum, which buffers the table and so loses the
/// key a type error is about: here the kind's keys are read from the table with their path, and an error
/// says e.g. ``[reference] kind = "position": invalid length 2, expected an array of length 3 in
/// `steps.vel_ned_mps` ``. Unknown keys stay an error.
impl<'de> Deserialize<'de> for ReferenceSpec {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error;

        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct AttitudeTable {
            pos_d_m: f64,
            steps: Vec<AttitudeStep>,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct PositionTable {
            steps: Vec<PositionStep>,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct RatesTable {
            thrust_frac: f64,
            steps: Vec<RateStep>,
        }

        let mut table = toml::Table::deserialize(deserializer)?;
        let kind = match table.remove("kind") {
            Some(toml::Value::String(kind)) => kind,
            Some(other) => return Err(D::Error::custom(format!("reference.kind must be a string, got {other}"))),
            None => {
                return Err(D::Error::custom(
                    "reference.kind is missing: \"attitude\", \"position\", \"track\" or \"rates\"",
                ));
            }
        };
        let body = toml::Value::Table(table);
        let keyed = |e: toml::de::Error| {
            let text = e.to_string();
            let message: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
            D::Error::custom(format!("[reference] kind = \"{kind}\": {}", message.join(" ")))
        };
        match kind.as_str() {
            "attitude" => {
                let AttitudeTable { pos_d_m, steps } = body.try_into().map_err(keyed)?;
                Ok(Self::Attitude { pos_d_m, steps })
            }
            "position" => {
                let PositionTable { steps } = body.try_into().map_err(keyed)?;
                Ok(Self::Position { steps })
            }
            "track" => Ok(Self::Track(body.try_into().map_err(keyed)?)),
            "rates" => {
                let RatesTable { thrust_frac, steps } = body.try_into().map_err(keyed)?;
                Ok(Self::Rates { thrust_frac, steps })
            }
            other => Err(D::Error::custom(format!(
                "unknown reference kind `{other}`, expected `attitude`, `position`, `track` or `rates`"
            ))),
        }
    }
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
                if steps.iter().any(|s| !finite(&s.vel_ned_mps)) {
                    return Err(invalid("position step vel_ned_mps must be finite"));
                }
                if steps.iter().any(|s| !finite(&s.acc_ned_mps2)) {
                    return Err(invalid("position step acc_ned_mps2 must be finite"));
                }
            }
            Self::Rates { thrust_frac, steps } => {
                check_times(&mut steps.iter().map(|s| s.t_s))?;
                if steps.iter().any(|s| !finite(&s.rate_frd_radps)) {
                    return Err(invalid("rate steps must be finite"));
                }
                if steps.iter().any(|s| s.rate_frd_radps.iter().any(|r| r.abs() > 3.0)) {
                    return Err(invalid("rate steps must keep every body rate within 3 rad/s (the rate limits)"));
                }
                if !(0.0..=1.0).contains(thrust_frac) {
                    return Err(invalid("rates thrust_frac must be in [0, 1] (normalized collective)"));
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
    Track(Box<TrackGen>),
    Rates { thrust_frac: f64, steps: Vec<RateStep> },
}

impl ReferenceGen {
    /// Builds the generator; `mode` selects feed-forward for tracks and is ignored otherwise.
    #[must_use]
    pub fn new(spec: &ReferenceSpec, mode: ReferenceMode) -> Self {
        match spec {
            ReferenceSpec::Attitude { pos_d_m, steps } => Self::Attitude { pos_d_m: *pos_d_m, steps: steps.clone() },
            ReferenceSpec::Position { steps } => Self::Position { steps: steps.clone() },
            ReferenceSpec::Track(track) => Self::Track(Box::new(TrackGen::new(track, mode))),
            ReferenceSpec::Rates { thrust_frac, steps } => {
                Self::Rates { thrust_frac: *thrust_frac, steps: steps.clone() }
            }
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
                let mut reference = Reference::position(Vector3::from(s.pos_ned_m), s.yaw_rad);
                reference.vel_ned_mps = Vector3::from(s.vel_ned_mps);
                reference.acc_ned_mps2 = Vector3::from(s.acc_ned_mps2);
                reference
            }
            Self::Track(track) => track.at(t_s),
            Self::Rates { thrust_frac, steps } => {
                let s = active(steps, t_s, |s| s.t_s);
                Reference::rates(Vector3::from(s.rate_frd_radps), *thrust_frac, 0.0)
            }
        }
    }
}

/// The last item whose start time is <= t (or the first, before it). `items` is non-empty and sorted.
fn active<T: Copy>(items: &[T], t_s: f64, start: impl Fn(&T) -> f64) -> T {
    // A step at t applies from the tick at t on; 1e-9 s absorbs tick-time rounding.
    let idx = items.partition_point(|i| start(i) <= t_s + 1e-9);
    items[idx.saturating_sub(1)]
}

/// The prefiltered progress along a track's path.
#[derive(Debug, Clone)]
pub struct TrackGen {
    pub path: TrackPath,
    spec: TrackSpec,
    mode: ReferenceMode,
    /// The progress (m, m/s) after `filter_steps` steps.
    filter: ProgressFilter,
    filter_steps: u64,
    /// One lap's length times the laps (m), read at every prefilter step.
    total_length_m: f64,
}

/// The prefilter is integrated at this fixed step, whatever the control rate, so the reference is the
/// same function of time at every loop rate.
const PREFILTER_STEP_S: f64 = 1e-4;

/// The arc-length step (m) of the path's third derivative in the jerk feed-forward.
const JERK_ARC_STEP_M: f64 = 1e-3;

impl TrackGen {
    #[must_use]
    pub fn new(spec: &TrackSpec, mode: ReferenceMode) -> Self {
        let path = TrackPath::new(spec.path, &spec.waypoints_ne_m);
        let total_length_m = path.length_m() * f64::from(spec.laps);
        Self {
            path,
            spec: spec.clone(),
            mode,
            filter: ProgressFilter::at_rest(spec.prefilter_wn_radps, 0.0),
            filter_steps: 0,
            total_length_m,
        }
    }

    /// Total arc length the reference travels (all laps).
    #[must_use]
    pub fn total_length_m(&self) -> f64 {
        self.total_length_m
    }

    /// The time at which the unfiltered progress reaches the end of the last lap.
    #[must_use]
    pub fn end_s(&self) -> f64 {
        self.spec.start_s + self.total_length_m() / self.spec.speed_mps
    }

    fn raw_progress_m(&self, t_s: f64) -> f64 {
        ((t_s - self.spec.start_s) * self.spec.speed_mps).clamp(0.0, self.total_length_m())
    }

    /// The rate of [`Self::raw_progress_m`] (m/s): the speed while it ramps, zero before and after.
    fn raw_rate_mps(&self, t_s: f64) -> f64 {
        let s = (t_s - self.spec.start_s) * self.spec.speed_mps;
        if s > 0.0 && s < self.total_length_m() { self.spec.speed_mps } else { 0.0 }
    }

    /// Progress along the path (m) of the prefiltered reference at `t_s`.
    pub fn progress_m(&mut self, t_s: f64) -> f64 {
        // Steps are counted, not summed as time, so every tick integrates exactly its share.
        let target_steps = (t_s / PREFILTER_STEP_S + 1e-6).floor().max(0.0) as u64;
        while self.filter_steps < target_steps {
            // Semi-implicit Euler at 0.1 ms: error far below anything a metric resolves.
            let r = self.raw_progress_m(self.filter_time_s());
            self.filter.step(r, PREFILTER_STEP_S);
            self.filter_steps += 1;
        }
        self.filter.s_m
    }

    fn filter_time_s(&self) -> f64 {
        self.filter_steps as f64 * PREFILTER_STEP_S
    }

    pub fn at(&mut self, t_s: f64) -> Reference {
        let s = self.progress_m(t_s);
        let s_ddot = self.filter.accel_mps2(self.raw_progress_m(self.filter_time_s()));
        let s_dot = self.filter.s_dot_mps;
        let (p, dp_ds, d2p_ds2) = self.path.eval(s);
        let d = self.spec.pos_d_m;
        let mut reference = Reference::position(Vector3::new(p.x, p.y, d), self.spec.yaw_rad);
        if matches!(self.mode, ReferenceMode::FeedForward | ReferenceMode::FeedForwardJerk) {
            let v = dp_ds * s_dot;
            let a = d2p_ds2 * s_dot.powi(2) + dp_ds * s_ddot;
            reference.vel_ned_mps = Vector3::new(v.x, v.y, 0.0);
            reference.acc_ned_mps2 = Vector3::new(a.x, a.y, 0.0);
        }
        if self.mode == ReferenceMode::FeedForwardJerk {
            // Jerk = p3 v^3 + 3 p2 v a + p1 j_s, with p1..p3 the path's derivatives in arc length and v, a,
            // j_s the progress's rate, acceleration and jerk. The prefilter's j_s = wn^2 (r' - v) - 2 wn a
            // (r' the raw progress's rate); p3 is a central difference of the curvature vector over a
            // millimetre of arc.
            let wn = self.filter.wn_radps;
            let s_dddot = wn * wn * (self.raw_rate_mps(self.filter_time_s()) - s_dot) - 2.0 * wn * s_ddot;
            let from = (s - JERK_ARC_STEP_M / 2.0).max(0.0);
            let d3p_ds3 = (self.path.eval(from + JERK_ARC_STEP_M).2 - self.path.eval(from).2) / JERK_ARC_STEP_M;
            let j = d3p_ds3 * s_dot.powi(3) + d2p_ds2 * (3.0 * s_dot * s_ddot) + dp_ds * s_dddot;
            reference.jerk_ned_mps3 = Vector3::new(j.x, j.y, 0.0);
        }
        reference
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figure8() -> Vec<[f64; 2]> {
        autopilot::core::navigator::spline::FIGURE8_NE_M.to_vec()
    }

    #[test]
    fn given_a_track_when_followed_then_feed_forward_is_the_derivative_of_the_reference() {
        let spec = TrackSpec {
            waypoints_ne_m: figure8(),
            path: PathKind::Spline,
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
    fn given_the_jerk_mode_then_the_jerk_is_the_derivative_of_the_acceleration_and_the_rest_is_unchanged() {
        let spec = TrackSpec {
            waypoints_ne_m: figure8(),
            path: PathKind::Spline,
            pos_d_m: -1.5,
            speed_mps: 0.9,
            prefilter_wn_radps: 2.5,
            start_s: 1.0,
            laps: 1,
            yaw_rad: 0.0,
            reference_modes: vec![ReferenceMode::FeedForwardJerk],
        };
        let mut jerk = TrackGen::new(&spec, ReferenceMode::FeedForwardJerk);
        let mut plain = TrackGen::new(&spec, ReferenceMode::FeedForward);
        let dt = 0.002;
        let mut prev = jerk.at(0.0);
        plain.at(0.0);
        let mut max_jerk: f64 = 0.0;
        for k in 1..7_000 {
            let t = f64::from(k) * dt;
            let r = jerk.at(t);
            let p = plain.at(t);
            assert_eq!((r.pos_ned_m, r.vel_ned_mps, r.acc_ned_mps2), (p.pos_ned_m, p.vel_ned_mps, p.acc_ned_mps2));
            assert_eq!(p.jerk_ned_mps3, Vector3::zeros());
            // The difference of the acceleration over the tick lies between the jerks at its ends (the jerk
            // steps where the spline's third derivative does, at the knots, and where the ramp starts).
            let fd_j = (r.acc_ned_mps2 - prev.acc_ned_mps2) / dt;
            let (a, b) = (prev.jerk_ned_mps3, r.jerk_ned_mps3);
            let x = if (b - a).norm() > 0.0 {
                ((fd_j - a).dot(&(b - a)) / (b - a).norm_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let off = (fd_j - (a + (b - a) * x)).norm();
            assert!(off < 0.02 * (1.0 + b.norm()), "t {t}: fd {fd_j:?} ff {a:?} .. {b:?}");
            max_jerk = max_jerk.max(r.jerk_ned_mps3.norm());
            prev = r;
        }
        assert!(max_jerk > 1.0, "a 0.9 m/s figure-8 has jerk: {max_jerk}");
    }

    #[test]
    fn given_position_only_mode_then_the_reference_has_no_feed_forward() {
        let spec = TrackSpec {
            waypoints_ne_m: figure8(),
            path: PathKind::Spline,
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
                PositionStep {
                    t_s: 1.0,
                    pos_ned_m: [0.0; 3],
                    yaw_rad: 0.0,
                    vel_ned_mps: [0.0; 3],
                    acc_ned_mps2: [0.0; 3],
                },
                PositionStep {
                    t_s: 1.0,
                    pos_ned_m: [1.0; 3],
                    yaw_rad: 0.0,
                    vel_ned_mps: [0.0; 3],
                    acc_ned_mps2: [0.0; 3],
                },
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
