//! A leg: one move of the reference along a path (a straight 3D line, or a C2 spline through a run of
//! waypoints), its progress a jerk-limited [`Profile`] in vehicle time. In: the reference's motion when
//! the leg starts (NED m, m/s, m/s²), the path, the [`Limits`] of the progress, the start time (µs). Out,
//! at any later vehicle time: the reference's position, velocity and acceleration (exact feed-forward:
//! the path's derivatives times the progress's), which knots (mission items) the reference has passed,
//! and whether the leg has arrived.
//!
//! A leg that starts while the reference moves across its direction first brakes to rest along the
//! reference's velocity (jerk-limited), then flies its path from that stopping point; a start that moves
//! along the path's direction is continued smoothly. A closed spline repeated by a DO_JUMP adds laps as it
//! flies, replanning its progress from the current motion, so the laps are flown through the seam.

use nalgebra::Vector3;

use super::spline::SplinePath;
use super::trajectory::{Limits, Motion1, Profile};
use crate::core::seconds_to_us;

/// A motion of the reference in NED (m, m/s, m/s², m/s³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion3 {
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    pub acc_ned_mps2: Vector3<f64>,
    pub jerk_ned_mps3: Vector3<f64>,
}

impl Motion3 {
    /// At rest at `pos_ned_m`.
    #[must_use]
    pub fn rest(pos_ned_m: Vector3<f64>) -> Self {
        Self {
            pos_ned_m,
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            jerk_ned_mps3: Vector3::zeros(),
        }
    }

    fn finite(&self) -> bool {
        self.pos_ned_m.iter().chain(self.vel_ned_mps.iter()).chain(self.acc_ned_mps2.iter()).all(|x| x.is_finite())
    }
}

/// Speeds below this count as rest (m/s).
const REST_MPS: f64 = 1e-3;
/// A start moving across the leg faster than this brakes first (m/s).
const CROSS_MPS: f64 = 0.02;
/// A vehicle lagging its reference along the path by more than this slows the reference (m).
const LAG_FREE_M: f64 = 0.05;
/// ... and stops it at this lag (m).
const LAG_STOP_M: f64 = 0.30;
/// The step of the jerk's central difference (s).
const JERK_STEP_S: f64 = 1e-3;
/// Legs shorter than this are no move (m).
pub const MIN_LEG_M: f64 = 1e-3;

/// The shape of a leg.
#[derive(Debug, Clone)]
pub enum LegPath {
    Line {
        from: Vector3<f64>,
        to: Vector3<f64>,
    },
    /// A horizontal spline; `alt` holds (arc length, down) at each knot.
    Spline {
        path: SplinePath,
        alt: Vec<(f64, f64)>,
    },
}

impl LegPath {
    #[must_use]
    pub fn length_m(&self) -> f64 {
        match self {
            Self::Line { from, to } => (to - from).norm(),
            Self::Spline { path, .. } => path.length_m(),
        }
    }

    /// Position, first and second derivatives with respect to the progress `s_m`.
    #[must_use]
    pub fn eval(&self, s_m: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        match self {
            Self::Line { from, to } => {
                let len = (to - from).norm();
                let t = if len > 0.0 { (to - from) / len } else { Vector3::zeros() };
                (from + t * s_m.clamp(0.0, len), t, Vector3::zeros())
            }
            Self::Spline { path, alt } => {
                let (p, t, k) = path.eval(s_m);
                // A closed run flown for laps (through a DO_JUMP) is closed in altitude too.
                let len = path.length_m();
                let s = if path.closed() && s_m > len { s_m.rem_euclid(len) } else { s_m.clamp(0.0, len) };
                let j = alt.partition_point(|&(a, _)| a <= s).clamp(1, alt.len() - 1);
                let ((s0, d0), (s1, d1)) = (alt[j - 1], alt[j]);
                let slope = if s1 > s0 { (d1 - d0) / (s1 - s0) } else { 0.0 };
                let d = d0 + slope * (s - s0);
                (Vector3::new(p.x, p.y, d), Vector3::new(t.x, t.y, slope), Vector3::new(k.x, k.y, 0.0))
            }
        }
    }
}

/// A stop before the path: along the reference's velocity from where the leg began.
#[derive(Debug, Clone)]
struct Brake {
    from: Vector3<f64>,
    dir: Vector3<f64>,
    profile: Profile,
}

/// The laps still to fly of a closed run that a DO_JUMP repeats from its first waypoint.
#[derive(Debug, Clone)]
struct Laps {
    /// One lap's length (m) and knots, from its start: the jump, then the run's waypoints.
    lap_m: f64,
    knots: Vec<(f64, u16)>,
    /// Laps left to add (None: forever, a DO_JUMP repeat of -1).
    left: Option<u32>,
}

/// A move along a path. See the module docs.
#[derive(Debug, Clone)]
pub struct Leg {
    path: LegPath,
    limits: Limits,
    brake: Option<Brake>,
    /// When the path's progress profile starts (µs).
    t0_us: u64,
    profile: Profile,
    /// The profile's own time (s): vehicle time since `t0_us`, slowed while the vehicle lags.
    clock_s: f64,
    /// The vehicle time the clock was last advanced to (µs).
    last_us: Option<u64>,
    /// The clock's rate (1: vehicle time; less while the vehicle lags the reference along the path).
    rate: f64,
    /// (arc length, item seq) of each point on the leg after its start, in order; the last is its end.
    knots: Vec<(f64, u16)>,
    /// Knots reported passed so far.
    passed: usize,
    /// The progress (m) at which the leg ends: the path's length, or whole laps of a closed path.
    length_m: f64,
    laps: Option<Laps>,
    /// A landing's floor (NED down, m): the reference descends through the ground at a constant speed
    /// (no braking feed-forward that would lift the vehicle off again) and stops there.
    floor_d_m: Option<f64>,
}

impl Leg {
    /// The leg from `start` (the reference's motion at `now_us`) along the path `make_path` builds from
    /// the point it leaves: `start`'s position, or where it stops first when it moves across the path.
    /// `limits_for` gives the progress's limits for a path.
    pub fn plan(
        start: &Motion3,
        now_us: u64,
        knots: Vec<(f64, u16)>,
        limits_for: impl Fn(&LegPath) -> Limits,
        make_path: impl Fn(Vector3<f64>) -> LegPath,
    ) -> Self {
        Self::plan_continuing(start, now_us, knots, limits_for, make_path, CROSS_MPS)
    }

    /// [`Self::plan`], continuing a start that moves across the path at up to `cross_mps` (its across
    /// component is dropped) instead of braking first: for a target that moves a little at every update
    /// (an offboard position stream along a curve), where braking at each would stall the vehicle.
    pub fn plan_continuing(
        start: &Motion3,
        now_us: u64,
        knots: Vec<(f64, u16)>,
        limits_for: impl Fn(&LegPath) -> Limits,
        make_path: impl Fn(Vector3<f64>) -> LegPath,
        cross_mps: f64,
    ) -> Self {
        let start = if start.finite() {
            *start
        } else {
            Motion3::rest(start.pos_ned_m.map(|x| if x.is_finite() { x } else { 0.0 }))
        };
        let speed = start.vel_ned_mps.norm();
        let path = make_path(start.pos_ned_m);
        if speed <= REST_MPS && start.acc_ned_mps2.norm() <= REST_MPS {
            return Self::new(path, Motion1::rest(0.0), None, now_us, knots, &limits_for);
        }
        let (_, tangent, _) = path.eval(0.0);
        let along = start.vel_ned_mps.dot(&tangent);
        let across = (start.vel_ned_mps - tangent * along).norm();
        if tangent.norm() > 0.5 && across <= cross_mps && along >= 0.0 {
            let m = Motion1 { pos_m: 0.0, vel_mps: along, acc_mps2: start.acc_ned_mps2.dot(&tangent) };
            return Self::new(path, m, None, now_us, knots, &limits_for);
        }
        // Brake along the velocity, then fly the path from where the reference stops.
        let dir = start.vel_ned_mps / speed.max(REST_MPS);
        let brake_line = LegPath::Line { from: start.pos_ned_m, to: start.pos_ned_m + dir };
        let m = Motion1 { pos_m: 0.0, vel_mps: speed, acc_mps2: start.acc_ned_mps2.dot(&dir) };
        let profile = Profile::stop(m, limits_for(&brake_line));
        let stop_at = start.pos_ned_m + dir * profile.target_m();
        let brake = Brake { from: start.pos_ned_m, dir, profile };
        let t0_us = now_us.saturating_add(seconds_to_us(brake.profile.duration_s()));
        Self::new(make_path(stop_at), Motion1::rest(0.0), Some(brake), t0_us, knots, &limits_for)
    }

    fn new(
        path: LegPath,
        start: Motion1,
        brake: Option<Brake>,
        t0_us: u64,
        knots: Vec<(f64, u16)>,
        limits_for: &impl Fn(&LegPath) -> Limits,
    ) -> Self {
        let limits = limits_for(&path);
        let length_m = path.length_m();
        Self {
            profile: Profile::plan(start, length_m, limits),
            path,
            limits,
            brake,
            t0_us,
            clock_s: 0.0,
            last_us: None,
            rate: 1.0,
            knots,
            passed: 0,
            length_m,
            laps: None,
            floor_d_m: None,
        }
    }

    /// This leg, a landing that stops at `floor_d_m` (planned to run on well past it).
    #[must_use]
    pub fn with_floor(mut self, floor_d_m: f64) -> Self {
        self.floor_d_m = Some(floor_d_m);
        self
    }

    /// Progress along the path at the leg's clock.
    fn progress(&self) -> Motion1 {
        self.profile.eval(self.clock_s)
    }

    /// The reference at `now_us` (adding laps as they come due), and the clock's rate for the next step
    /// from where the vehicle is (`vehicle_ned_m`): ArduPilot's track scaling. A vehicle that lags its
    /// reference along the path by more than `LAG_FREE_M` slows the reference's clock, down to a stop at
    /// `LAG_STOP_M`, so it is never asked to catch up a lag at more than the speed limit (an airframe
    /// heavier than the controller's model, a headwind). Landings are not slowed (the ground stops the
    /// vehicle, not a lag).
    pub fn motion(&mut self, now_us: u64, vehicle_ned_m: Vector3<f64>) -> Motion3 {
        if let Some(brake) = &self.brake
            && now_us < self.t0_us
        {
            let at = |t_s: f64| {
                let m = brake.profile.eval(t_s);
                (brake.from + brake.dir * m.pos_m, brake.dir * m.vel_mps, brake.dir * m.acc_mps2)
            };
            let t_s = (brake.profile.duration_s() - (self.t0_us - now_us) as f64 * 1e-6).max(0.0);
            let (p, v, a) = at(t_s);
            let jerk = (at(t_s + JERK_STEP_S / 2.0).2 - at((t_s - JERK_STEP_S / 2.0).max(0.0)).2) / JERK_STEP_S;
            return Motion3 { pos_ned_m: p, vel_ned_mps: v, acc_ned_mps2: a, jerk_ned_mps3: jerk };
        }
        let dt_us = match self.last_us {
            Some(last) if last >= self.t0_us => now_us.saturating_sub(last),
            _ => now_us.saturating_sub(self.t0_us),
        };
        self.last_us = Some(now_us);
        self.clock_s += dt_us as f64 * 1e-6 * self.rate;
        self.extend_laps();
        let c = self.clock_s;
        let (p, v, a) = self.at_clock(c);
        // The jerk by a central difference over 1 ms (exact inside a constant-jerk segment).
        let jerk =
            (self.at_clock(c + JERK_STEP_S / 2.0).2 - self.at_clock((c - JERK_STEP_S / 2.0).max(0.0)).2) / JERK_STEP_S;
        let r = self.rate;
        let m = Motion3 { pos_ned_m: p, vel_ned_mps: v * r, acc_ned_mps2: a * r * r, jerk_ned_mps3: jerk * r * r * r };
        let (_, tangent, _) = self.path.eval(self.progress().pos_m);
        let lag_m = if tangent.norm() > 0.5 && self.floor_d_m.is_none() {
            (p - vehicle_ned_m).dot(&tangent.normalize())
        } else {
            0.0
        };
        self.rate =
            if lag_m.is_finite() { ((LAG_STOP_M - lag_m) / (LAG_STOP_M - LAG_FREE_M)).clamp(0.0, 1.0) } else { 1.0 };
        m
    }

    /// Position, velocity and acceleration at the leg's clock `clock_s` (laps as added so far).
    fn at_clock(&self, clock_s: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let m = self.profile.eval(clock_s);
        let (p, dp, d2p) = self.path.eval(m.pos_m);
        if let Some(floor) = self.floor_d_m
            && p.z >= floor
        {
            return (Vector3::new(p.x, p.y, floor), Vector3::zeros(), Vector3::zeros());
        }
        (p, dp * m.vel_mps, d2p * m.vel_mps * m.vel_mps + dp * m.acc_mps2)
    }

    /// Fly this leg `repeat` more times (-1: forever) through the DO_JUMP `jump_seq` at its end, without
    /// stopping, if it is a spline closed in all three axes (otherwise it stays as it is).
    pub fn repeat_laps(&mut self, jump_seq: u16, repeat: i32) {
        let LegPath::Spline { path, alt } = &self.path else {
            return;
        };
        let closed_d = matches!((alt.first(), alt.last()), (Some(a), Some(b)) if (a.1 - b.1).abs() < MIN_LEG_M);
        if repeat == 0 || !path.closed() || !closed_d {
            return;
        }
        let mut knots = vec![(0.0, jump_seq)];
        knots.extend_from_slice(&self.knots);
        let left = u32::try_from(repeat).ok();
        self.laps = Some(Laps { lap_m: path.length_m(), knots, left });
    }

    /// Adds a lap once the reference is within a lap of the end, replanning the progress from its motion
    /// (which then runs on through the seam).
    fn extend_laps(&mut self) {
        let now = self.progress();
        let Some(laps) = &mut self.laps else { return };
        if laps.left == Some(0) || self.length_m - now.pos_m >= laps.lap_m {
            return;
        }
        if let Some(n) = &mut laps.left {
            *n -= 1;
        }
        self.knots.drain(..self.passed);
        self.passed = 0;
        let base = self.length_m;
        self.knots.extend(laps.knots.iter().map(|&(s, seq)| (base + s, seq)));
        self.length_m += laps.lap_m;
        self.profile = Profile::plan(now, self.length_m, self.limits);
        self.clock_s = 0.0;
    }

    /// The leg's end point.
    #[must_use]
    pub fn end(&self) -> Vector3<f64> {
        self.path.eval(self.length_m).0
    }

    /// The reference has arrived at the end, at rest.
    #[must_use]
    pub fn at_end(&self) -> bool {
        let laps_left = self.laps.as_ref().is_some_and(|l| l.left != Some(0));
        !laps_left && self.last_us.is_some() && self.clock_s >= self.profile.duration_s()
    }

    /// Knots the reference has passed since the last call (all but the end, which needs arrival).
    pub fn newly_passed(&mut self) -> Vec<u16> {
        let s = if self.last_us.is_some() { self.progress().pos_m } else { 0.0 };
        let mut out = Vec::new();
        while self.passed + 1 < self.knots.len() && s >= self.knots[self.passed].0 {
            out.push(self.knots[self.passed].1);
            self.passed += 1;
        }
        out
    }
}
