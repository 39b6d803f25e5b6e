//! The in-process lockstep runner: plant and controller stepped together on simulated time, no sockets,
//! no sleeping, bit-reproducible for a given seed.
//!
//! Per control tick k (period 1/inner_hz): sample the state at t_k (truth, or truth plus the paper's
//! noise) -> controller -> PWM held over [t_k, t_k+1) while the plant integrates (RK4, 1 ms substeps).
//! Out: the run's metrics (JSON-serialisable) and a trace decimated to `trace_hz` for CSV and plots.

use std::collections::BTreeMap;
use std::time::Instant;

use autopilot::core::control::{ControlInput, ControllerKind, LoopRates, new_controller};
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use super::metrics::{self, GustMetrics, SegmentMetrics, StepSegment, TrackMetrics};
use super::reference::{ReferenceGen, ReferenceMode, ReferenceSpec, TrackGen};
use super::{MetricKind, Scenario, ScenarioError, StateNoiseKind};
use crate::plant::{AirframeConfig, InitialState, Plant, PlantConfig, StateNoise};

/// What varies between runs of one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    pub controller: ControllerKind,
    /// Airframe preset; `None` keeps the scenario's.
    pub plant: Option<String>,
    pub seed: u64,
    pub rates: LoopRates,
    pub mode: ReferenceMode,
    /// Trace decimation (rows per simulated second); the metrics always use every tick.
    pub trace_hz: u32,
}

impl RunOptions {
    #[must_use]
    pub fn new(controller: ControllerKind) -> Self {
        Self {
            controller,
            plant: None,
            seed: 1,
            rates: LoopRates::default(),
            mode: ReferenceMode::FeedForward,
            trace_hz: 50,
        }
    }
}

/// One run's metrics: the JSON object `sitl scenario` prints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunMetrics {
    pub scenario: String,
    pub controller: String,
    pub plant: String,
    pub seed: u64,
    pub rate_hz: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_mode: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<Vec<SegmentMetrics>>,
    /// Whole-run RMS tracking error per axis (m or rad).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms: Option<BTreeMap<&'static str, f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gust: Option<GustMetrics>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub track: Option<TrackMetrics>,
    pub weights_at_bounds: bool,
    pub non_finite: bool,
    /// Mean |PWM change| per tick over the run and rotors (us): actuator activity.
    pub pwm_activity_us: f64,
    pub sim_s: f64,
    pub wall_s: f64,
    pub realtime_factor: f64,
}

/// A decimated trace: named columns, one row per sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    pub columns: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Trace {
    /// The values of a named column.
    #[must_use]
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }

    /// CSV text with a header row; the first eleven columns match the golden traces'.
    #[must_use]
    pub fn to_csv(&self) -> String {
        let mut out = self.columns.join(",");
        out.push('\n');
        for row in &self.rows {
            let cells: Vec<String> = row.iter().map(|v| format!("{v:.6}")).collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    }
}

/// A finished run.
#[derive(Debug, Clone)]
pub struct RunOutput {
    pub metrics: RunMetrics,
    pub trace: Trace,
}

const CORE_COLUMNS: [&str; 26] = [
    "t",
    "pN",
    "pE",
    "pD",
    "roll",
    "pitch",
    "yaw",
    "pwm1",
    "pwm2",
    "pwm3",
    "pwm4",
    "refN",
    "refE",
    "refD",
    "ref_roll",
    "ref_pitch",
    "ref_yaw",
    "vN",
    "vE",
    "vD",
    "windN",
    "windE",
    "windD",
    "sp_roll",
    "sp_pitch",
    "sp_yaw",
];

/// Full-rate series the metrics need.
#[derive(Default)]
struct Series {
    t: Vec<f64>,
    pos: [Vec<f64>; 3],
    euler: [Vec<f64>; 3],
    ref_pos: [Vec<f64>; 3],
    ref_euler: [Vec<f64>; 3],
    progress_m: Vec<f64>,
}

/// The resolved plant configuration for a scenario and a preset override.
///
/// # Errors
/// An unknown preset or a non-physical override.
pub fn plant_config(scenario: &Scenario, preset: Option<&str>) -> Result<PlantConfig, ScenarioError> {
    let preset = preset.unwrap_or(&scenario.plant).to_owned();
    let airframe = AirframeConfig { preset, ..scenario.airframe.clone() }.resolve()?;
    Ok(PlantConfig { airframe, wind: scenario.wind.clone(), ..PlantConfig::default() })
}

/// Runs one scenario with one controller on one plant, in lockstep.
///
/// # Errors
/// A bad plant preset or override, or loop rates the controllers cannot run at.
pub fn run(scenario: &Scenario, opts: &RunOptions) -> Result<RunOutput, ScenarioError> {
    let wall_start = Instant::now();
    let rates = opts.rates;
    if rates.inner_hz == 0 || 1_000_000 % rates.inner_hz != 0 {
        return Err(ScenarioError::Invalid(format!(
            "rate {} Hz must divide 1 MHz (the plant clock is in microseconds)",
            rates.inner_hz
        )));
    }
    let mut controller_config = scenario.controller.clone();
    controller_config.rates = rates;
    controller_config.rates.validate().map_err(|e| ScenarioError::Controller(e.to_string()))?;
    let mut controller = new_controller(opts.controller, &controller_config);

    let config = plant_config(scenario, opts.plant.as_deref())?;
    let plant_name = opts.plant.clone().unwrap_or_else(|| scenario.plant.clone());
    let init = &scenario.initial;
    let initial = InitialState {
        pos_ned_m: Vector3::from(init.pos_ned_m),
        vel_ned_mps: Vector3::from(init.vel_ned_mps),
        euler_rad: Vector3::from(init.euler_rad),
        rate_frd_radps: Vector3::from(init.rate_frd_radps),
        rotor_lift_n: None,
    };
    let mut plant = Plant::new(config, &initial, opts.seed)?;
    let noise = match scenario.state_noise {
        StateNoiseKind::None => StateNoise::none(),
        StateNoiseKind::Paper => StateNoise::paper(),
    };
    let mut reference = ReferenceGen::new(&scenario.reference, opts.mode);

    let dt_us = u64::from(1_000_000 / rates.inner_hz);
    let ticks = (scenario.duration_s * f64::from(rates.inner_hz)).round() as u64;
    let trace_hz = opts.trace_hz.clamp(1, rates.inner_hz);
    let telemetry_names: Vec<&'static str> = controller.telemetry().iter().map(|(n, _)| *n).collect();
    let mut trace = Trace {
        columns: CORE_COLUMNS.iter().chain(&telemetry_names).map(|s| (*s).to_owned()).collect(),
        rows: Vec::new(),
    };
    let mut series = Series::default();
    let n = usize::try_from(ticks).unwrap_or(0);
    series.t.reserve(n);
    for v in series.pos.iter_mut().chain(&mut series.euler).chain(&mut series.ref_pos).chain(&mut series.ref_euler) {
        v.reserve(n);
    }
    let mut non_finite = false;
    let mut last_pwm: Option<[f64; 4]> = None;
    let mut pwm_change_sum = 0.0;

    for k in 0..ticks {
        let t_s = (k * dt_us) as f64 * 1e-6;
        let r = reference.at(t_s);
        let truth = plant.truth();
        let state = plant.sample_state_of(&truth, &noise);
        let input = ControlInput {
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            euler_rad: state.euler_rad,
            rate_frd_radps: state.rate_frd_radps,
            specific_force_frd_mps2: state.specific_force_frd_mps2,
        };
        let pwm_us = controller.update(&input, &r);
        non_finite |= pwm_us.iter().any(|p| !p.is_finite())
            || !(truth
                .pos_ned_m
                .iter()
                .chain(truth.vel_ned_mps.iter())
                .chain(truth.euler_rad.iter())
                .all(|v| v.is_finite()));
        if let Some(prev) = last_pwm {
            pwm_change_sum += prev.iter().zip(&pwm_us).map(|(a, b)| (a - b).abs()).sum::<f64>() / 4.0;
        }
        last_pwm = Some(pwm_us);

        let ref_euler = r.attitude_rad.unwrap_or_else(|| Vector3::new(0.0, 0.0, r.yaw_rad));
        series.t.push(t_s);
        for i in 0..3 {
            series.pos[i].push(truth.pos_ned_m[i]);
            series.euler[i].push(truth.euler_rad[i]);
            series.ref_pos[i].push(r.pos_ned_m[i]);
            series.ref_euler[i].push(ref_euler[i]);
        }
        if let ReferenceGen::Track(track) = &mut reference {
            series.progress_m.push(track.progress_m(t_s));
        }
        if (k * u64::from(trace_hz)) % u64::from(rates.inner_hz) == 0 {
            let sp = controller.attitude_setpoint_rad();
            let mut row = vec![t_s];
            row.extend(truth.pos_ned_m.iter());
            row.extend(truth.euler_rad.iter());
            row.extend(pwm_us);
            row.extend(r.pos_ned_m.iter());
            row.extend(ref_euler.iter());
            row.extend(truth.vel_ned_mps.iter());
            row.extend(truth.wind_ned_mps.iter());
            row.extend(sp.iter());
            row.extend(controller.telemetry().iter().map(|(_, v)| *v));
            trace.rows.push(row);
        }
        plant.step(pwm_us, dt_us);
    }

    let sim_s = ticks as f64 * dt_us as f64 * 1e-6;
    let mut m = RunMetrics {
        scenario: scenario.name.clone(),
        controller: opts.controller.to_string(),
        plant: plant_name,
        seed: opts.seed,
        rate_hz: rates.inner_hz,
        reference_mode: matches!(scenario.reference, ReferenceSpec::Track(_)).then(|| opts.mode.to_string()),
        segments: None,
        rms: None,
        gust: None,
        track: None,
        weights_at_bounds: controller.weights_at_bounds(),
        non_finite,
        pwm_activity_us: pwm_change_sum / (ticks.saturating_sub(1).max(1)) as f64,
        sim_s,
        wall_s: 0.0,
        realtime_factor: 0.0,
    };
    if scenario.metrics.contains(&MetricKind::Steps) {
        let (segments, rms) = step_metrics(scenario, &series);
        m.segments = Some(segments);
        m.rms = Some(rms);
    }
    if scenario.metrics.contains(&MetricKind::Gust) {
        let gust = scenario.wind.gust.as_ref().expect("validated: the gust metric has a gust");
        m.gust =
            Some(metrics::hover_gust_metrics(&series.t, &series.pos, &series.ref_pos, gust.onset_s, gust.release_s));
    }
    if let (true, ReferenceSpec::Track(spec)) = (scenario.metrics.contains(&MetricKind::Track), &scenario.reference) {
        let track = TrackGen::new(spec, opts.mode);
        let (t0, t1) = (spec.start_s, track.end_s());
        let mut cross = Vec::new();
        let mut alt = Vec::new();
        // The vehicle's own nearest point is followed along the path (it moves a few mm per tick), so a
        // point near the crossing stays on its branch; the first is sought near the reference.
        let mut nearest_s: Option<f64> = None;
        for k in 0..series.t.len() {
            if series.t[k] < t0 || series.t[k] > t1 {
                continue;
            }
            let p = Vector2::new(series.pos[0][k], series.pos[1][k]);
            let (d, s) = match nearest_s {
                Some(s) => track.path.nearest_near(p, s, 0.05),
                None => track.path.nearest_near(p, series.progress_m[k], 0.5),
            };
            nearest_s = Some(s);
            cross.push(d);
            alt.push(series.pos[2][k] - series.ref_pos[2][k]);
        }
        m.track = Some(metrics::track_metrics(&cross, &alt));
    }
    m.wall_s = wall_start.elapsed().as_secs_f64();
    m.realtime_factor = if m.wall_s > 0.0 { sim_s / m.wall_s } else { f64::INFINITY };
    Ok(RunOutput { metrics: m, trace })
}

/// The three axes a step schedule moves: their names, recorded values and references, initial values,
/// and the schedule as (time, targets).
struct StepAxes<'a> {
    names: [&'static str; 3],
    values: &'a [Vec<f64>; 3],
    refs: &'a [Vec<f64>; 3],
    starts: [f64; 3],
    schedule: Vec<(f64, [f64; 3])>,
}

/// Step segments of every axis that the schedule moves, and whole-run RMS per axis.
fn step_metrics(scenario: &Scenario, s: &Series) -> (Vec<SegmentMetrics>, BTreeMap<&'static str, f64>) {
    let end = scenario.duration_s;
    let axes = match &scenario.reference {
        ReferenceSpec::Attitude { steps, .. } => StepAxes {
            names: ["roll", "pitch", "yaw"],
            values: &s.euler,
            refs: &s.ref_euler,
            starts: scenario.initial.euler_rad,
            schedule: steps.iter().map(|st| (st.t_s, st.euler_rad)).collect(),
        },
        ReferenceSpec::Position { steps } => StepAxes {
            names: ["n", "e", "d"],
            values: &s.pos,
            refs: &s.ref_pos,
            starts: scenario.initial.pos_ned_m,
            schedule: steps.iter().map(|st| (st.t_s, st.pos_ned_m)).collect(),
        },
        ReferenceSpec::Track(_) => return (Vec::new(), BTreeMap::new()),
    };
    let StepAxes { names, values, refs, starts, schedule } = axes;
    let mut segments = Vec::new();
    let mut previous = starts;
    for (i, (t0, target)) in schedule.iter().enumerate() {
        for axis in 0..3 {
            if (target[axis] - previous[axis]).abs() <= 1e-9 {
                continue;
            }
            // An axis's step lasts until that axis's setpoint changes again.
            let later = &schedule[i + 1..];
            let t1 = later.iter().find(|next| (next.1[axis] - target[axis]).abs() > 1e-9).map_or(end, |next| next.0);
            let wrap = names[axis] == "yaw";
            let seg = StepSegment {
                axis: names[axis],
                t0_s: *t0,
                t1_s: t1,
                start: previous[axis],
                target: target[axis],
                wrap,
            };
            segments.push(metrics::step_metrics(&s.t, &values[axis], &seg));
        }
        previous = *target;
    }
    let rms = (0..3)
        .map(|axis| (names[axis], metrics::tracking_rms(&values[axis], &refs[axis], names[axis] == "yaw")))
        .collect();
    (segments, rms)
}
