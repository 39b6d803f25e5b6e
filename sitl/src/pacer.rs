//! Real-time pacing of the plant's lockstep steps: given the plant time a step would reach and the wall
//! clock, whether to step now or until when to sleep. In: `speed` (plant seconds per wall second), the
//! plant time before and after the step (µs), `now`. Out: `None` (step now) or the wall instant to sleep
//! until. No I/O and no clock of its own: [`crate::link::PlantServer`] calls it between the autopilot's
//! reply and the plant step.
//!
//! Three rules, each with its bound:
//! - **Absolute deadlines.** Plant time `t` is due at `wall0 + (t - t0) / speed`, from the origin
//!   `(wall0, t0)` taken at the first step (when the autopilot has answered, so both processes are up):
//!   sleeping late or a slow step never shifts a later deadline, and no time is ever dropped. Plant time
//!   is never ahead of `speed` times wall time.
//! - **Batches.** When it is on time the plant sleeps until [`PACE_BATCH`] of wall time is due and then
//!   takes those steps back to back (10 steps of 2 ms at 1x), rather than sleeping before every step. A
//!   paced step is a wake-up of each process (the plant's timer, the autopilot's receive, the plant's
//!   receive), and on a machine whose cores are taken by other work every wake-up waits its turn on the
//!   run queue (measured: 0.7 ms on average, 3 s of a 10 s run, with two CPU-bound processes in the
//!   SITL's session on 2 cores), so 500 wake-ups per second could not keep up and the vehicle's clock fell
//!   behind the wall clock by seconds. In a batch both ends poll their sockets (see
//!   `autopilot::runtime::transport::SpinReceiver`) and pay for one wake-up per batch. The vehicle's
//!   clock then trails the wall clock by between 0 and [`PACE_BATCH`] (times `speed`), never more on an
//!   idle machine.
//! - **Bounded catch-up.** Behind its deadline by more than [`CATCH_UP_AFTER`] (a stall: the autopilot or
//!   this process was not scheduled, or a resend), the plant catches up at most [`CATCH_UP_FACTOR`] times
//!   `speed`, still in batches, until it is on time again: a 1 s stall is made up in 0.11 s, and a ground
//!   station sees at most ten times the usual telemetry rate meanwhile, not the hundredfold burst of an
//!   unpaced lockstep.

use std::time::{Duration, Instant};

/// Wall time the plant sleeps at once when it is on time; it then takes this much wall time's worth of
/// steps back to back.
pub const PACE_BATCH: Duration = Duration::from_millis(20);

/// How many times `speed` the plant may run while it makes up a stall.
pub const CATCH_UP_FACTOR: f64 = 10.0;

/// Behind its deadline by more than this, the plant is catching up (at most [`CATCH_UP_FACTOR`] times
/// `speed`); less is the ordinary lag of a batch and a wake-up.
pub const CATCH_UP_AFTER: Duration = Duration::from_millis(50);

/// The pacing state of one plant (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Pacer {
    speed: f64,
    /// Wall time and plant time (µs) of the first step.
    origin: Option<(Instant, u64)>,
    /// Wall time and plant time (µs) at which the current catch-up began.
    catch_up: Option<(Instant, u64)>,
}

impl Pacer {
    /// A pacer at `speed` times real time (finite and positive; anything else never waits).
    #[must_use]
    pub fn new(speed: f64) -> Self {
        Self { speed, origin: None, catch_up: None }
    }

    /// Whether a catch-up after a stall is under way.
    #[must_use]
    pub fn catching_up(&self) -> bool {
        self.catch_up.is_some()
    }

    /// Plant time (µs) due at wall time `at`.
    fn due_us(&self, wall0: Instant, t0: u64, at: Instant) -> f64 {
        t0 as f64 + at.saturating_duration_since(wall0).as_secs_f64() * 1e6 * self.speed
    }

    /// Wall time at which plant time `t_us` is due (never before `wall0`).
    fn wall_of(&self, wall0: Instant, t0: u64, t_us: f64) -> Instant {
        wall0 + Duration::from_secs_f64(((t_us - t0 as f64) * 1e-6 / self.speed).max(0.0))
    }

    /// The step from plant time `from_us` to `to_us`: `None` to take it now, or the wall instant to sleep
    /// until (then ask again: the answer may be `None` or a later instant).
    pub fn wait(&mut self, from_us: u64, to_us: u64, now: Instant) -> Option<Instant> {
        if !(self.speed.is_finite() && self.speed > 0.0) {
            return None;
        }
        let (wall0, t0) = *self.origin.get_or_insert((now, from_us));
        let due_now_us = self.due_us(wall0, t0, now);
        let batch_us = PACE_BATCH.as_secs_f64() * 1e6 * self.speed;
        let step_us = to_us.saturating_sub(from_us) as f64;
        let behind_us = due_now_us - to_us as f64;
        if behind_us < 0.0 {
            // On time: sleep until a batch is due (the steps up to `to_us + batch - step`).
            self.catch_up = None;
            return Some(self.wall_of(wall0, t0, to_us as f64 + (batch_us - step_us).max(0.0)));
        }
        if behind_us <= CATCH_UP_AFTER.as_secs_f64() * 1e6 * self.speed && self.catch_up.is_none() {
            return None;
        }
        // Catching up: at most CATCH_UP_FACTOR x speed from where the catch-up began.
        let (wall_c, t_c) = *self.catch_up.get_or_insert((now, from_us));
        let rate = CATCH_UP_FACTOR * self.speed;
        let allowed_us = t_c as f64 + now.saturating_duration_since(wall_c).as_secs_f64() * 1e6 * rate;
        if to_us as f64 <= allowed_us {
            return None;
        }
        let next_us = (to_us as f64 + (batch_us - step_us).max(0.0)).min(due_now_us);
        Some(wall_c + Duration::from_secs_f64(((next_us - t_c as f64) * 1e-6 / rate).max(0.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT_US: u64 = 2_000;

    /// Steps a plant of `dt` through `wall_s` of a simulated wall clock at `speed`, each step taking
    /// `step_cost(k)` of wall time (a stall is a long one); returns (wall s, plant s) after every step.
    fn simulate(speed: f64, wall_s: f64, step_cost: impl Fn(u64) -> Duration) -> Vec<(f64, f64)> {
        let start = Instant::now();
        let mut pacer = Pacer::new(speed);
        let mut now = start;
        let mut t = 0_u64;
        let mut trace = Vec::new();
        let mut k = 0;
        while now.duration_since(start).as_secs_f64() < wall_s {
            now += step_cost(k);
            while let Some(wake) = pacer.wait(t, t + DT_US, now) {
                assert!(wake > now, "a wake-up that is not in the future");
                now = now.max(wake);
            }
            t += DT_US;
            k += 1;
            trace.push((now.duration_since(start).as_secs_f64(), t as f64 * 1e-6));
        }
        trace
    }

    #[test]
    fn on_time_the_plant_never_leads_the_wall_clock_and_trails_it_by_at_most_one_batch() {
        // GIVEN a plant whose round trip costs 20 µs, paced at 1x and at 4x.
        for speed in [1.0, 4.0] {
            let trace = simulate(speed, 10.0, |_| Duration::from_micros(20));
            // THEN plant time is never ahead of speed x wall time (1 µs of float rounding), and trails it by
            // at most a batch (at speed) plus a step.
            let batch_s = PACE_BATCH.as_secs_f64() * speed;
            for &(wall, plant) in &trace {
                assert!(plant <= speed * wall + 1e-6, "{plant} s ahead of {wall} s at {speed}x");
                assert!(speed * wall - plant <= batch_s + 0.002 + 1e-6, "{plant} s behind {wall} s at {speed}x");
            }
            // AND over 10 s the ratio is speed within 0.3 %.
            let &(wall, plant) = trace.last().expect("steps");
            assert!((plant / wall / speed - 1.0).abs() < 0.003, "{plant} in {wall} at {speed}x");
        }
    }

    #[test]
    fn after_a_stall_the_plant_catches_up_at_most_ten_times_speed_and_loses_no_time() {
        // GIVEN a 1 s stall at step 1000 (2 s of plant time), at 1x.
        let trace = simulate(1.0, 5.0, |k| Duration::from_micros(if k == 1000 { 1_000_000 } else { 20 }));
        // THEN no stretch of plant time runs faster than 10x wall time, beyond one batch.
        for (i, &(w0, p0)) in trace.iter().enumerate() {
            for &(w1, p1) in &trace[i + 1..] {
                if w1 - w0 > 0.05 {
                    assert!(p1 - p0 <= CATCH_UP_FACTOR * (w1 - w0) + 0.020 + 1e-6, "{p0}..{p1} in {w0}..{w1}");
                    break;
                }
            }
        }
        // AND the stall is made up within 1 s / (10 - 1) = 0.11 s, after which plant time is on the wall
        // clock again (within a batch): nothing was dropped.
        let stall_end = trace.iter().find(|(_, p)| *p > 2.0).expect("after the stall").0;
        for &(wall, plant) in trace.iter().filter(|(w, _)| *w > stall_end + 0.12) {
            assert!(wall - plant <= 0.022 + 1e-6 && plant <= wall + 1e-6, "{plant} s at {wall} s");
        }
    }

    #[test]
    fn the_origin_is_the_first_step_and_a_speed_that_is_not_positive_never_waits() {
        let now = Instant::now();
        let mut pacer = Pacer::new(1.0);
        // The first step from 4 s of plant time: due one step later, slept in a batch.
        let wake = pacer.wait(4_000_000, 4_002_000, now).expect("waits");
        assert_eq!(wake, now + PACE_BATCH);
        assert_eq!(pacer.wait(4_002_000, 4_004_000, now + Duration::from_millis(20)), None);
        for speed in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(Pacer::new(speed).wait(0, DT_US, now), None, "{speed}");
        }
    }
}
