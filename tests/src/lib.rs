//! Shared pieces of the acceptance tests: the reference prototype's result table (spec section (d)),
//! its golden traces, and a helper that runs a built-in scenario in lockstep.

pub mod repo;
pub mod rig;
pub mod sticks;

use autopilot::core::control::{ControllerKind, LoopRates};
use sitl::scenario::runner::{self, RunOptions, RunOutput};
use sitl::scenario::{ReferenceMode, Scenario};

/// One axis of one row of the reference table: overshoot (%) and settling time (s).
#[derive(Debug, Clone, Copy)]
pub struct Step {
    pub overshoot_pct: f64,
    pub settling_s: Option<f64>,
}

const fn step(overshoot_pct: f64, settling_s: f64) -> Step {
    Step { overshoot_pct, settling_s: Some(settling_s) }
}

/// A row of the paper-scenario tables in spec (d).
#[derive(Debug, Clone, Copy)]
pub struct ReferenceRow {
    pub plant: &'static str,
    pub controller: ControllerKind,
    /// Attitude: roll, pitch, yaw from the initial attitude. Translation: n, e, climb, descent.
    pub steps: &'static [Step],
    /// Worst overshoot on the 6 s and 10 s attitude steps (%); `None` for translation.
    pub worst_later_overshoot_pct: Option<f64>,
    /// Whole-run RMS per axis (rad or m).
    pub rms: [f64; 3],
}

const ACO: ControllerKind = ControllerKind::ACO;
const CA: ControllerKind = ControllerKind::CA;
const PID: ControllerKind = ControllerKind::PID;

/// Spec (d), "Paper attitude scenario".
pub const ATTITUDE_TABLE: &[ReferenceRow] = &[
    ReferenceRow {
        plant: "mismatch",
        controller: ACO,
        steps: &[step(0.0, 1.22), step(0.1, 0.86), step(0.0, 2.89)],
        worst_later_overshoot_pct: Some(0.6),
        rms: [0.066, 0.076, 0.111],
    },
    ReferenceRow {
        plant: "mismatch",
        controller: CA,
        steps: &[step(0.0, 1.10), step(0.0, 1.11), step(0.0, 5.78)],
        worst_later_overshoot_pct: Some(1.8),
        rms: [0.063, 0.076, 0.122],
    },
    ReferenceRow {
        plant: "mismatch",
        controller: PID,
        steps: &[step(0.0, 2.00), step(6.8, 1.77), step(0.0, 4.67)],
        worst_later_overshoot_pct: Some(12.8),
        rms: [0.066, 0.075, 0.112],
    },
    ReferenceRow {
        plant: "nominal",
        controller: ACO,
        steps: &[step(0.0, 1.13), step(0.0, 0.82), step(0.0, 2.36)],
        worst_later_overshoot_pct: Some(0.6),
        rms: [0.062, 0.072, 0.097],
    },
    ReferenceRow {
        plant: "nominal",
        controller: CA,
        steps: &[step(0.4, 0.92), step(0.6, 0.95), step(0.2, 5.91)],
        worst_later_overshoot_pct: Some(2.6),
        rms: [0.061, 0.072, 0.099],
    },
    ReferenceRow {
        plant: "nominal",
        controller: PID,
        steps: &[step(0.0, 1.30), step(0.8, 0.61), step(0.0, 3.89)],
        worst_later_overshoot_pct: Some(3.3),
        rms: [0.061, 0.070, 0.097],
    },
];

/// Spec (d), "Paper translation scenario".
// The nominal CA row's RMS of 0.318 m is a measurement that happens to look like 1/pi.
#[allow(clippy::approx_constant)]
pub const TRANSLATION_TABLE: &[ReferenceRow] = &[
    ReferenceRow {
        plant: "mismatch",
        controller: ACO,
        steps: &[step(0.0, 6.64), step(0.0, 6.84), step(0.1, 5.33), step(0.1, 3.92)],
        worst_later_overshoot_pct: None,
        rms: [0.354, 0.423, 0.923],
    },
    ReferenceRow {
        plant: "mismatch",
        controller: CA,
        steps: &[step(3.1, 5.95), step(6.6, 8.23), step(0.0, 6.40), step(0.2, 3.68)],
        worst_later_overshoot_pct: None,
        rms: [0.332, 0.420, 0.921],
    },
    ReferenceRow {
        plant: "mismatch",
        controller: PID,
        steps: &[step(0.0, 9.23), step(0.0, 7.64), step(0.0, 8.40), step(0.0, 6.24)],
        worst_later_overshoot_pct: None,
        rms: [0.315, 0.444, 0.931],
    },
    ReferenceRow {
        plant: "nominal",
        controller: ACO,
        steps: &[step(0.0, 5.66), step(0.0, 5.65), step(0.1, 4.53), step(0.1, 3.96)],
        worst_later_overshoot_pct: None,
        rms: [0.322, 0.322, 0.798],
    },
    ReferenceRow {
        plant: "nominal",
        controller: CA,
        steps: &[step(4.2, 7.36), step(4.1, 7.33), step(0.2, 3.73), step(0.1, 4.15)],
        worst_later_overshoot_pct: None,
        rms: [0.318, 0.318, 0.790],
    },
    ReferenceRow {
        plant: "nominal",
        controller: PID,
        steps: &[step(0.0, 6.22), step(0.0, 6.24), step(0.0, 7.51), step(0.0, 6.67)],
        worst_later_overshoot_pct: None,
        rms: [0.319, 0.319, 0.801],
    },
];

/// Runs a built-in scenario in lockstep.
///
/// # Panics
/// If the scenario does not exist or cannot run: a test failure.
#[must_use]
pub fn run(
    scenario: &str,
    controller: ControllerKind,
    plant: &str,
    seed: u64,
    inner_hz: u32,
    mode: ReferenceMode,
) -> RunOutput {
    let s = Scenario::load(scenario).unwrap_or_else(|e| panic!("{scenario}: {e}"));
    run_scenario(&s, controller, plant, seed, inner_hz, mode)
}

/// Runs a (possibly modified) scenario in lockstep; the position loop runs at a fifth of `inner_hz`.
///
/// # Panics
/// If the run fails to start: a test failure.
#[must_use]
pub fn run_scenario(
    s: &Scenario,
    controller: ControllerKind,
    plant: &str,
    seed: u64,
    inner_hz: u32,
    mode: ReferenceMode,
) -> RunOutput {
    let opts = RunOptions {
        controller,
        plant: Some(plant.to_owned()),
        seed,
        rates: LoopRates { inner_hz, position_hz: inner_hz / 5 },
        mode,
        trace_hz: 50,
    };
    runner::run(s, &opts).unwrap_or_else(|e| panic!("{}: {e}", s.name))
}

/// A golden trace of the reference prototype: rows of t, pN, pE, pD, roll, pitch, yaw, pwm1..pwm4.
///
/// # Panics
/// If the file is missing or malformed.
#[must_use]
pub fn golden(name: &str) -> Vec<[f64; 11]> {
    let path = format!("{}/golden/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .skip(1)
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|c| c.parse().expect("golden cells are numbers")).collect();
            v.try_into().expect("golden rows have 11 columns")
        })
        .collect()
}

type RunKey = (String, ControllerKind, String, u64, u32, ReferenceMode);
type RunCell = std::sync::Arc<std::sync::OnceLock<std::sync::Arc<RunOutput>>>;

/// [`run`], computed once per test binary for each distinct argument set, so tests that check different
/// properties of one run share it. Runs of different keys proceed in parallel.
#[must_use]
pub fn cached(
    scenario: &str,
    controller: ControllerKind,
    plant: &str,
    seed: u64,
    inner_hz: u32,
    mode: ReferenceMode,
) -> std::sync::Arc<RunOutput> {
    static CACHE: std::sync::OnceLock<std::sync::Mutex<std::collections::HashMap<RunKey, RunCell>>> =
        std::sync::OnceLock::new();
    let key = (scenario.to_owned(), controller, plant.to_owned(), seed, inner_hz, mode);
    let cell = {
        let mut map = CACHE.get_or_init(Default::default).lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        map.entry(key).or_default().clone()
    };
    cell.get_or_init(|| std::sync::Arc::new(run(scenario, controller, plant, seed, inner_hz, mode))).clone()
}

/// The segment of `axis` starting at `t0_s` (s).
///
/// # Panics
/// If the run has no such segment: a test failure.
#[must_use]
pub fn segment<'a>(out: &'a RunOutput, axis: &str, t0_s: f64) -> &'a sitl::scenario::metrics::SegmentMetrics {
    out.metrics
        .segments
        .iter()
        .flatten()
        .find(|s| s.axis == axis && (s.t0_s - t0_s).abs() < 1e-9)
        .unwrap_or_else(|| panic!("{} has no {axis} segment at {t0_s} s", out.metrics.scenario))
}

/// Whole-run RMS of `axis`.
///
/// # Panics
/// If the run has no RMS for the axis.
#[must_use]
pub fn rms(out: &RunOutput, axis: &str) -> f64 {
    *out.metrics.rms.as_ref().and_then(|r| r.get(axis)).unwrap_or_else(|| panic!("no rms for {axis}"))
}
