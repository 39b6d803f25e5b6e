//! A scenario run drawn in the view: the in-process runner stepped tick by tick, with the plant's truth,
//! what the controller saw and asked (its state, reference, attitude setpoint, motors and telemetry) and
//! the reference's path ahead sent as frames at 50 Hz of simulated time. Several runs of one scenario
//! (each controller) are sources of one stream, so the view overlays them on one time axis.

use autopilot::core::control::Controller;

use super::{
    AheadFrame, VehicleFrame, ViewFrame, ViewSampler, ViewSender, arr3, meta_frame, quat, telemetry_of, truth_frame,
};
use crate::plant::rigid_body::attitude_from_euler;
use crate::scenario::runner::{RunOptions, RunOutput, Runner, TickState};
use crate::scenario::{Scenario, ScenarioError};

/// Simulated time between two frames of the path ahead (µs), and how far ahead it reaches (s).
const AHEAD_PERIOD_US: u64 = 200_000;
const AHEAD_HORIZON_S: f64 = 3.0;
const AHEAD_POINTS: usize = 31;

/// The stream's first frame for a scenario flown by `sources` (one per run, in colour order).
#[must_use]
pub fn scenario_meta_frame(scenario: &Scenario, sources: &[String]) -> ViewFrame {
    meta_frame(format!("sitl scenario {}", scenario.name), sources.to_vec())
}

/// What the controller saw and asked at the tick of time `t_us`, as a vehicle frame (`mode`: the
/// scenario's reference mode; always armed).
#[must_use]
pub fn scenario_vehicle_frame(
    src: &str,
    t_us: u64,
    mode: &str,
    state: &TickState,
    controller: &dyn Controller,
) -> VehicleFrame {
    let seen = &state.seen;
    let q = attitude_from_euler(&seen.euler_rad);
    let sp = state.reference.attitude_rad.unwrap_or_else(|| controller.attitude_setpoint_rad());
    VehicleFrame {
        src: src.into(),
        t_us,
        armed: true,
        mode: mode.into(),
        pos_ned_m: arr3(&seen.pos_ned_m),
        vel_ned_mps: arr3(&seen.vel_ned_mps),
        q_ned_frd: quat(&q),
        euler_rad: arr3(&seen.euler_rad),
        sp_pos_ned_m: Some(arr3(&state.reference.pos_ned_m)),
        sp_euler_rad: sp.iter().all(|v| v.is_finite()).then(|| arr3(&sp)),
        pwm_us: state.pwm_us,
        battery_v: None,
        battery_pct: None,
        telemetry: telemetry_of(controller),
        origin: None,
    }
}

/// Runs `scenario` as [`crate::scenario::runner::run`] does, sending source `src`'s frames to `sender`:
/// at every 50 Hz instant of simulated time, the truth before the tick and what the controller saw and
/// asked at it (so a run of D seconds gives D × 50 of each), and the path ahead five times a second. The
/// run's outputs are those of a run without the view.
///
/// # Errors
/// As [`crate::scenario::runner::run`].
pub fn run_viewed(
    scenario: &Scenario,
    opts: &RunOptions,
    src: &str,
    sender: &ViewSender,
) -> Result<RunOutput, ScenarioError> {
    let mut runner = Runner::new(scenario, opts)?;
    let mode = opts.mode.to_string();
    let mut sampler = ViewSampler::default();
    let mut next_ahead_us = 0;
    let closed = || ScenarioError::Invalid("the view closed before the run ended".into());
    while runner.ticks().0 < runner.ticks().1 {
        let truth = runner.plant().truth();
        let due = sampler.due(truth.time_us);
        if due {
            if !sender.send(&truth_frame(src, &truth)) {
                return Err(closed());
            }
            if truth.time_us >= next_ahead_us {
                next_ahead_us = truth.time_us + AHEAD_PERIOD_US;
                let points_ned_m = runner.ahead_ned_m(AHEAD_HORIZON_S, AHEAD_POINTS).iter().map(arr3).collect();
                sender.send(&ViewFrame::Ahead(AheadFrame { src: src.into(), t_us: truth.time_us, points_ned_m }));
            }
        }
        runner.step();
        if due && let Some(state) = runner.state() {
            let frame = scenario_vehicle_frame(src, truth.time_us, &mode, &state, runner.controller());
            sender.send(&ViewFrame::Vehicle(frame));
        }
    }
    runner.finish()
}
