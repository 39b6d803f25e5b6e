//! Jerk-limited (S-curve) motion along one coordinate: the time-optimal profile from any position,
//! velocity and acceleration to rest at a target, under limits on speed, acceleration and jerk (as PX4's
//! position smoothing and ArduPilot's SCurve plan theirs). In: a start [`Motion1`] (m, m/s, m/s²), a
//! target (m) and [`Limits`]. Out: a [`Profile`], piecewise-constant jerk, that gives position, velocity
//! and acceleration at any time after its start exactly (cubic in time), so the reference is the same
//! function of vehicle time at any loop rate.
//!
//! The plan: change the velocity to a peak `v_peak` (at most the speed limit), cruise, and change it back
//! to zero, each change a jerk-limited ramp of the acceleration up to at most the acceleration limit and
//! down to zero. `v_peak` is found by bisection so that the profile ends exactly at the target; the
//! result is the time-optimal rest-to-rest S-curve (7 segments at most). When the start moves too fast
//! towards the target to stop before it, the profile brakes to rest past it and comes back. Every
//! segment respects the limits, except the first when the start's acceleration or speed is already
//! beyond them (it is brought back within them as fast as the jerk allows).

/// Limits of a motion (all positive and finite).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub vel_mps: f64,
    pub acc_mps2: f64,
    pub jerk_mps3: f64,
}

impl Limits {
    /// Whether every limit is finite and positive.
    #[must_use]
    pub fn valid(&self) -> bool {
        [self.vel_mps, self.acc_mps2, self.jerk_mps3].iter().all(|x| x.is_finite() && *x > 0.0)
    }
}

/// Position, velocity and acceleration along one coordinate (m, m/s, m/s²).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion1 {
    pub pos_m: f64,
    pub vel_mps: f64,
    pub acc_mps2: f64,
}

impl Motion1 {
    /// At rest at `pos_m`.
    #[must_use]
    pub fn rest(pos_m: f64) -> Self {
        Self { pos_m, vel_mps: 0.0, acc_mps2: 0.0 }
    }

    /// The motion after `t_s` at constant jerk `jerk_mps3`.
    #[must_use]
    pub fn after(&self, jerk_mps3: f64, t_s: f64) -> Self {
        let (p, v, a, j) = (self.pos_m, self.vel_mps, self.acc_mps2, jerk_mps3);
        Self {
            pos_m: p + v * t_s + a * t_s * t_s / 2.0 + j * t_s * t_s * t_s / 6.0,
            vel_mps: v + a * t_s + j * t_s * t_s / 2.0,
            acc_mps2: a + j * t_s,
        }
    }
}

/// One piece of constant jerk.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    /// Start time from the profile's start (s).
    t0_s: f64,
    dur_s: f64,
    jerk_mps3: f64,
    start: Motion1,
}

/// A piecewise-constant-jerk motion from a start to rest at a target. See the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    segments: Vec<Segment>,
    start: Motion1,
    target_m: f64,
    duration_s: f64,
}

/// Segments shorter than this are dropped (s).
const MIN_SEGMENT_S: f64 = 1e-9;
/// Bisection steps for the peak speed (the error halves each step; 60 reach f64 precision).
const BISECTION_STEPS: usize = 60;

/// (duration s, jerk m/s³) pieces.
type Pieces = Vec<(f64, f64)>;

/// The pieces that take the velocity from `v0_mps` (acceleration `a0_mps2`) to `v1_mps` with zero
/// acceleration: the acceleration ramps at the jerk limit to a peak (at most the acceleration limit),
/// holds, and ramps back to zero.
fn velocity_change(v0_mps: f64, a0_mps2: f64, v1_mps: f64, acc_mps2: f64, jerk_mps3: f64) -> Pieces {
    let j = jerk_mps3;
    // The velocity reached by ramping the acceleration straight to zero.
    let v_ramp = v0_mps + a0_mps2 * a0_mps2.abs() / (2.0 * j);
    if (v1_mps - v_ramp).abs() <= 1e-12 {
        return vec![(a0_mps2.abs() / j, -a0_mps2.signum() * j)];
    }
    let sign = (v1_mps - v_ramp).signum();
    let b0 = sign * a0_mps2;
    let dv = sign * (v1_mps - v0_mps);
    // Ramp b0 -> peak -> 0 gains (2 peak² - b0²) / 2j; solve for the peak, then cap it.
    let mut peak = ((2.0 * j * dv + b0 * b0) / 2.0).max(0.0).sqrt().max(b0.max(0.0));
    let mut hold_s = 0.0;
    let cap = acc_mps2.max(b0);
    if peak > cap {
        peak = cap;
        let gained = (2.0 * peak * peak - b0 * b0) / (2.0 * j);
        hold_s = ((dv - gained) / peak).max(0.0);
    }
    vec![((peak - b0) / j, sign * j), (hold_s, 0.0), (peak / j, -sign * j)]
}

/// Where `pieces` take `start`.
fn run(start: Motion1, pieces: &[(f64, f64)]) -> Motion1 {
    pieces.iter().fold(start, |m, &(t, j)| m.after(j, t))
}

impl Profile {
    /// The time-optimal jerk-limited motion from `start` to rest at `target_m` (see the module docs).
    /// Limits that are not finite and positive (callers validate them where they are set) give a profile
    /// at rest where it starts.
    #[must_use]
    pub fn plan(start: Motion1, target_m: f64, limits: Limits) -> Self {
        if !limits.valid() || !target_m.is_finite() || !start.pos_m.is_finite() {
            let at = if start.pos_m.is_finite() { start.pos_m } else { 0.0 };
            return Self::from_pieces(Motion1::rest(at), at, Vec::new());
        }
        let start = Motion1 {
            vel_mps: if start.vel_mps.is_finite() { start.vel_mps } else { 0.0 },
            acc_mps2: if start.acc_mps2.is_finite() { start.acc_mps2 } else { 0.0 },
            ..start
        };
        let pieces = Self::plan_pieces(start, target_m, limits);
        Self::from_pieces(start, target_m, pieces)
    }

    fn plan_pieces(start: Motion1, target_m: f64, lim: Limits) -> Pieces {
        let distance_m = target_m - start.pos_m;
        // Work in the frame where the target is ahead (+).
        let sign = if distance_m < 0.0 { -1.0 } else { 1.0 };
        let (l, v0, a0) = (sign * distance_m, sign * start.vel_mps, sign * start.acc_mps2);
        let (a_max, j) = (lim.acc_mps2, lim.jerk_mps3);
        let flip = |p: Pieces| p.into_iter().map(|(t, jk)| (t, sign * jk)).collect::<Pieces>();
        let stop = velocity_change(v0, a0, 0.0, a_max, j);
        let stop_m = run(Motion1 { pos_m: 0.0, vel_mps: v0, acc_mps2: a0 }, &stop).pos_m;
        if stop_m >= l {
            // Too fast to stop before the target: brake to rest beyond it, then come back from rest.
            let mut pieces = flip(stop);
            let at_rest = run(start, &pieces);
            if (at_rest.pos_m - target_m).abs() > 1e-9 {
                pieces.extend(Self::plan_pieces(Motion1::rest(at_rest.pos_m), target_m, lim));
            }
            return pieces;
        }
        let m0 = Motion1 { pos_m: 0.0, vel_mps: v0, acc_mps2: a0 };
        let covered = |v_peak: f64| -> (Pieces, Pieces, f64) {
            let up = velocity_change(v0, a0, v_peak, a_max, j);
            let down = velocity_change(v_peak, 0.0, 0.0, a_max, j);
            let at_peak = run(m0, &up);
            let d = run(at_peak, &down).pos_m;
            (up, down, d)
        };
        let v_max = lim.vel_mps;
        let (up, down, d) = covered(v_max);
        let (up, cruise_s, down) = if d <= l {
            (up, (l - d) / v_max, down)
        } else {
            // The peak speed that covers exactly the distance (the coverage grows with the peak).
            let (mut lo, mut hi) = (0.0, v_max);
            for _ in 0..BISECTION_STEPS {
                let mid = 0.5 * (lo + hi);
                if covered(mid).2 > l {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            let (up, down, _) = covered(lo);
            (up, 0.0, down)
        };
        let mut pieces = up;
        pieces.push((cruise_s, 0.0));
        pieces.extend(down);
        flip(pieces)
    }

    fn from_pieces(start: Motion1, target_m: f64, pieces: Pieces) -> Self {
        let mut segments = Vec::with_capacity(pieces.len());
        let mut t0_s = 0.0;
        let mut m = start;
        for (dur_s, jerk_mps3) in pieces {
            if dur_s > MIN_SEGMENT_S {
                segments.push(Segment { t0_s, dur_s, jerk_mps3, start: m });
                t0_s += dur_s;
                m = m.after(jerk_mps3, dur_s);
            }
        }
        Self { segments, start, target_m, duration_s: t0_s }
    }

    /// The quickest jerk-limited stop from `start` (to rest wherever that is).
    #[must_use]
    pub fn stop(start: Motion1, limits: Limits) -> Self {
        if !(limits.valid() && start.pos_m.is_finite() && start.vel_mps.is_finite() && start.acc_mps2.is_finite()) {
            return Self::at_rest(if start.pos_m.is_finite() { start.pos_m } else { 0.0 });
        }
        let pieces = velocity_change(start.vel_mps, start.acc_mps2, 0.0, limits.acc_mps2, limits.jerk_mps3);
        let end = run(start, &pieces);
        Self::from_pieces(start, end.pos_m, pieces)
    }

    /// A profile that stays at rest at `pos_m`.
    #[must_use]
    pub fn at_rest(pos_m: f64) -> Self {
        Self::from_pieces(Motion1::rest(pos_m), pos_m, Vec::new())
    }

    /// The motion `t_s` after the start (before it: the start; from the end on: at rest at the target).
    #[must_use]
    pub fn eval(&self, t_s: f64) -> Motion1 {
        if t_s >= self.duration_s {
            return Motion1::rest(self.target_m);
        }
        if t_s <= 0.0 {
            return self.start;
        }
        let i = self.segments.partition_point(|s| s.t0_s <= t_s).saturating_sub(1);
        let s = &self.segments[i];
        s.start.after(s.jerk_mps3, (t_s - s.t0_s).min(s.dur_s))
    }

    /// How long the motion takes (s).
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    #[must_use]
    pub fn target_m(&self) -> f64 {
        self.target_m
    }

    /// The largest |velocity| and |acceleration| over the profile (at the segment ends and the velocity's
    /// turning points).
    #[must_use]
    pub fn peaks(&self) -> (f64, f64) {
        let mut v: f64 = self.start.vel_mps.abs();
        let mut a: f64 = self.start.acc_mps2.abs();
        for s in &self.segments {
            let end = s.start.after(s.jerk_mps3, s.dur_s);
            v = v.max(end.vel_mps.abs());
            a = a.max(end.acc_mps2.abs());
            // The velocity turns where the acceleration crosses zero inside the segment.
            if s.jerk_mps3 != 0.0 {
                let t = -s.start.acc_mps2 / s.jerk_mps3;
                if t > 0.0 && t < s.dur_s {
                    v = v.max(s.start.after(s.jerk_mps3, t).vel_mps.abs());
                }
            }
        }
        (v, a)
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    const LIM: Limits = Limits { vel_mps: 1.0, acc_mps2: 1.0, jerk_mps3: 2.0 };

    /// Samples the profile every millisecond: (max |jerk| by finite differences, overshoot past the
    /// target in the direction of travel, end error).
    fn sample(p: &Profile, dir: f64) -> (f64, f64) {
        let n = (p.duration_s() / 1e-3).ceil() as usize + 10;
        let mut overshoot: f64 = 0.0;
        for k in 0..=n {
            let m = p.eval(k as f64 * 1e-3);
            overshoot = overshoot.max(dir * (m.pos_m - p.target_m()));
        }
        let end = p.eval(p.duration_s());
        (overshoot, (end.pos_m - p.target_m()).abs())
    }

    #[test]
    fn given_a_long_move_from_rest_then_it_reaches_the_speed_limit_and_takes_the_textbook_time() {
        // GIVEN 10 m with v 1, a 1, j 2: the acceleration phase is 0.5 + 0.5 + 0.5 s (ramp, hold, ramp)
        // and covers 0.75 m, as does the deceleration; 8.5 m cruise at 1 m/s.
        let p = Profile::plan(Motion1::rest(0.0), 10.0, LIM);
        assert!((p.duration_s() - (1.5 + 8.5 + 1.5)).abs() < 1e-9, "{}", p.duration_s());
        let (v, a) = p.peaks();
        assert!((v - 1.0).abs() < 1e-9 && (a - 1.0).abs() < 1e-9, "{v} {a}");
        let (overshoot, end) = sample(&p, 1.0);
        assert!(overshoot < 1e-9 && end < 1e-9);
        // Half way the motion is cruising at the speed limit.
        let mid = p.eval(p.duration_s() / 2.0);
        assert!((mid.pos_m - 5.0).abs() < 1e-9 && (mid.vel_mps - 1.0).abs() < 1e-9 && mid.acc_mps2.abs() < 1e-12);
    }

    #[test]
    fn given_a_short_move_then_the_peak_speed_is_lower_and_it_ends_at_rest_exactly_there() {
        // 0.2 m reaches neither 1 m/s nor 1 m/s²: four jerk phases of T each, d = 2 j T³.
        let p = Profile::plan(Motion1::rest(1.0), 0.8, LIM);
        let (v, a) = p.peaks();
        assert!(v < 1.0 && a < 1.0, "{v} {a}");
        let quarter = (0.2 / (2.0 * LIM.jerk_mps3)).cbrt();
        assert!((p.duration_s() - 4.0 * quarter).abs() < 1e-6, "{} vs {}", p.duration_s(), 4.0 * quarter);
        let (overshoot, end) = sample(&p, -1.0);
        assert!(overshoot < 1e-9 && end < 1e-9);
    }

    #[test]
    fn given_a_fast_start_towards_a_near_target_then_it_brakes_past_it_and_comes_back_to_rest() {
        let start = Motion1 { pos_m: 0.0, vel_mps: 1.0, acc_mps2: 0.0 };
        let p = Profile::plan(start, 0.1, LIM);
        let end = p.eval(p.duration_s() + 1.0);
        assert_eq!(end, Motion1::rest(0.1));
        // The start is continuous.
        let first = p.eval(1e-6);
        assert!((first.vel_mps - 1.0).abs() < 1e-5);
    }

    #[test]
    fn given_a_start_cruising_towards_the_target_then_the_profile_continues_it_smoothly() {
        let start = Motion1 { pos_m: 2.0, vel_mps: 1.0, acc_mps2: 0.0 };
        let p = Profile::plan(start, 10.0, LIM);
        assert!((p.duration_s() - (8.0 - 0.75 + 1.5)).abs() < 1e-9, "{}", p.duration_s());
    }

    proptest! {
        #[test]
        fn any_start_and_target_end_at_rest_on_target_within_the_limits(
            p0 in -50.0..50.0f64, v0 in -1.0..1.0f64, a0 in -1.0..1.0f64, target in -50.0..50.0f64,
            vel in 0.1..5.0f64, acc in 0.2..4.0f64, jerk in 0.5..8.0f64,
        ) {
            let lim = Limits { vel_mps: vel, acc_mps2: acc, jerk_mps3: jerk };
            // Starts within the limits.
            let start = Motion1 { pos_m: p0, vel_mps: v0 * vel, acc_mps2: a0 * acc };
            let p = Profile::plan(start, target, lim);
            let end = p.eval(p.duration_s());
            prop_assert_eq!(end, Motion1::rest(target));
            // Continuous at the end: the last segment lands on the target at rest.
            let just_before = p.eval(p.duration_s() - 1e-9);
            prop_assert!((just_before.pos_m - target).abs() < 1e-6, "{:?}", just_before);
            prop_assert!(just_before.vel_mps.abs() < 1e-6 && just_before.acc_mps2.abs() < 1e-5);
            // Within the limits, or within what the start already commits to: its speed plus what its
            // acceleration adds while the jerk brings it to zero.
            let (v, a) = p.peaks();
            let committed = start.vel_mps.abs() + start.acc_mps2 * start.acc_mps2 / (2.0 * jerk);
            prop_assert!(v <= vel.max(committed) * (1.0 + 1e-9) + 1e-9, "{} {}", v, committed);
            prop_assert!(a <= acc * (1.0 + 1e-9) + 1e-9, "{}", a);
        }

        #[test]
        fn from_rest_it_never_overshoots(target in -30.0..30.0f64, vel in 0.1..5.0f64, acc in 0.2..4.0f64) {
            let lim = Limits { vel_mps: vel, acc_mps2: acc, jerk_mps3: 2.0 };
            let p = Profile::plan(Motion1::rest(0.0), target, lim);
            let (overshoot, end) = sample(&p, target.signum());
            prop_assert!(overshoot < 1e-9 && end < 1e-9, "{} {}", overshoot, end);
        }
    }
}
