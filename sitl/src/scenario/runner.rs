//! The in-process lockstep runner: plant and controller stepped together on simulated time, no sockets,
//! no sleeping, bit-reproducible for a given seed.
//!
//! Per control tick k (period 1/inner_hz): sample the state at t_k (truth, or truth plus the paper's
//! noise) -> controller -> PWM held over [t_k, t_k+1) while the plant integrates (RK4, 1 ms substeps).
//! Out: the run's metrics (JSON-serialisable) and a trace decimated to `trace_hz` for CSV and plots.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::time::Instant;

use autopilot::core::control::distributor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US};
use autopilot::core::control::{
    ControlInput, Controller, ControllerConfig, ControllerKind, LoopRates, Reference, try_new_controller,
};
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use super::flight::{self, CornerMetrics, PulseMetrics};
use super::metrics::{self, EffortAccumulator, EffortMetrics, FaultMetrics, GustMetrics, SegmentMetrics, TrackMetrics};
use super::reference::{ReferenceGen, ReferenceMode, ReferenceSpec, TrackGen};
use super::{MetricKind, OverrideValue, Scenario, ScenarioError};
use crate::plant::sensors::{NoisyState, StateNoise};
use crate::plant::{Airframe, AirframeConfig, GroundConfig, Plant, PlantConfig, Truth, envelope};
use crate::sim_params::{SimEvents, SimParamService};

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
    /// The preset, then `+key=value` per `[airframe]` override ([`Scenario::plant_label`]).
    pub plant: String,
    /// The `[airframe]` overrides by key (absent when there are none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub airframe_overrides: Option<BTreeMap<&'static str, OverrideValue>>,
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
    /// What the scenario's fault did (the `fault` metric).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fault: Option<FaultMetrics>,
    /// A polyline track's turning points (the `corners` metric).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corners: Option<CornerMetrics>,
    /// The recovery after each wind pulse (the `pulses` metric).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pulses: Option<PulseMetrics>,
    pub weights_at_bounds: bool,
    pub non_finite: bool,
    /// Mean |PWM change| per tick over the run and rotors (us): actuator activity.
    pub pwm_activity_us: f64,
    /// Control effort over the run: squared PWM deviation from the plant's hover, PWM rate, saturation.
    pub effort: EffortMetrics,
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
        // Formatted straight into the text: a String per cell cost more than the run it records.
        for row in &self.rows {
            for (i, v) in row.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write!(out, "{v:.6}").expect("writing to a String cannot fail");
            }
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
pub(super) struct Series {
    pub(super) t: Vec<f64>,
    pub(super) pos: [Vec<f64>; 3],
    pub(super) euler: [Vec<f64>; 3],
    pub(super) ref_pos: [Vec<f64>; 3],
    pub(super) ref_euler: [Vec<f64>; 3],
    /// Body rates (FRD rad/s) and their reference: recorded for a rates scenario only.
    pub(super) rate: [Vec<f64>; 3],
    pub(super) ref_rate: [Vec<f64>; 3],
    pub(super) progress_m: Vec<f64>,
}

/// The resolved plant configuration for a scenario and a preset override.
///
/// # Errors
/// An unknown preset or a non-physical override.
pub fn plant_config(scenario: &Scenario, preset: Option<&str>) -> Result<PlantConfig, ScenarioError> {
    let preset = preset.unwrap_or(&scenario.plant).to_owned();
    let airframe = AirframeConfig { preset, ..scenario.airframe.clone() }.resolve()?;
    let ground = GroundConfig { enabled: scenario.ground, ..GroundConfig::default() };
    Ok(PlantConfig { airframe, wind: scenario.wind.clone(), ground, ..PlantConfig::default() })
}

/// [`plant_config`] as the in-process runner flies it: without a battery. No metric or trace reads the
/// pack, and the lift does not depend on it, so draining one every tick would only cost time. (A
/// two-process run keeps it: the autopilot monitors it.)
///
/// # Errors
/// As [`plant_config`].
pub fn lockstep_plant_config(scenario: &Scenario, preset: Option<&str>) -> Result<PlantConfig, ScenarioError> {
    let mut config = plant_config(scenario, preset)?;
    config.battery.enabled = false;
    Ok(config)
}

/// What the controller sees of the paper's truth-fed (optionally noisy) state.
#[must_use]
pub fn control_input(state: &NoisyState) -> ControlInput {
    ControlInput {
        pos_ned_m: state.pos_ned_m,
        vel_ned_mps: state.vel_ned_mps,
        euler_rad: state.euler_rad,
        rate_frd_radps: state.rate_frd_radps,
        specific_force_frd_mps2: state.specific_force_frd_mps2,
    }
}

/// Runs one scenario with one controller on one plant, in lockstep.
///
/// # Errors
/// A bad plant preset or override, or loop rates the controllers cannot run at.
pub fn run(scenario: &Scenario, opts: &RunOptions) -> Result<RunOutput, ScenarioError> {
    let mut runner = Runner::new(scenario, opts)?;
    while runner.step() {}
    runner.finish()
}

/// What the controller saw and was asked at the last tick, and the plant's truth after it.
#[derive(Debug, Clone, Copy)]
pub struct TickState {
    /// The plant's true state now.
    pub truth: Truth,
    /// The state the controller saw at the last tick (truth, or truth plus the scenario's noise).
    pub seen: ControlInput,
    /// The reference of the last tick.
    pub reference: Reference,
    /// The PWM commanded at the last tick (µs).
    pub pwm_us: [f64; 4],
}

/// A lockstep run that advances one control tick at a time ([`run`] steps one to its end): the
/// scenario's plant, its events, its reference and a controller, with the run's metrics and trace
/// collected as it goes. The controller is a registered type's ([`Runner::new`]) or any
/// [`Controller`] the caller built ([`Runner::with_controller`], e.g. one written in Python).
pub struct Runner {
    scenario: Scenario,
    label: String,
    seed: u64,
    rates: LoopRates,
    mode: ReferenceMode,
    controller: Box<dyn Controller>,
    controller_config: ControllerConfig,
    plant: Plant,
    airframe_before: Airframe,
    plant_name: String,
    events: SimEvents,
    sim: SimParamService,
    noise: StateNoise,
    reference: ReferenceGen,
    dt_us: u64,
    ticks: u64,
    k: u64,
    trace_hz: u32,
    trace: Trace,
    series: Series,
    effort: EffortAccumulator,
    non_finite: bool,
    last: Option<(ControlInput, Reference, [f64; 4])>,
    wall_start: Instant,
}

impl Runner {
    /// A run of `scenario` with the registered controller `opts.controller`, at tick 0.
    ///
    /// # Errors
    /// As [`run`].
    pub fn new(scenario: &Scenario, opts: &RunOptions) -> Result<Self, ScenarioError> {
        if matches!(scenario.reference, ReferenceSpec::Rates { .. }) && !opts.controller.flies_rates() {
            return Err(ScenarioError::Controller(format!(
                "scenario `{}` flies the rate level, and controller {} has no rate loop",
                scenario.name, opts.controller
            )));
        }
        let config = Self::controller_config(scenario, opts)?;
        let controller =
            try_new_controller(opts.controller, &config).map_err(|e| ScenarioError::Controller(e.to_string()))?;
        Self::with_controller(scenario, opts, controller, &opts.controller.to_string())
    }

    /// The controller configuration a run of `scenario` builds its controller from: the scenario's
    /// `[controller]` at `opts.rates`.
    ///
    /// # Errors
    /// Loop rates the plant clock cannot hold.
    pub fn controller_config(scenario: &Scenario, opts: &RunOptions) -> Result<ControllerConfig, ScenarioError> {
        let rates = opts.rates;
        if rates.inner_hz == 0 || 1_000_000 % rates.inner_hz != 0 {
            return Err(ScenarioError::Invalid(format!(
                "rate {} Hz must divide 1 MHz (the plant clock is in microseconds)",
                rates.inner_hz
            )));
        }
        let mut config = scenario.controller.clone();
        config.rates = rates;
        Ok(config)
    }

    /// A run of `scenario` flown by `controller`, reported under `label` (the metrics' `controller`);
    /// `opts.controller` is not used.
    ///
    /// # Errors
    /// As [`run`].
    pub fn with_controller(
        scenario: &Scenario,
        opts: &RunOptions,
        controller: Box<dyn Controller>,
        label: &str,
    ) -> Result<Self, ScenarioError> {
        if !scenario.rc.is_empty() || scenario.manual.is_some() {
            return Err(ScenarioError::Invalid(
                "[[rc]] and [manual] are for the autopilot: the in-process runner flies the controller alone; fly \
                 the scenario with `sitl run --scenario`"
                    .into(),
            ));
        }
        let controller_config = Self::controller_config(scenario, opts)?;
        let rates = opts.rates;
        let config = lockstep_plant_config(scenario, opts.plant.as_deref())?;
        let plant_name = scenario.plant_label(opts.plant.as_deref());
        let initial = scenario.initial.state();
        let effort = EffortAccumulator::new(config.airframe.hover_pwm_us(), [MOTOR_PWM_MIN_US, MOTOR_PWM_MAX_US]);
        let airframe_before = config.airframe.clone();
        let plant = Plant::new(config, &initial, opts.seed)?;
        // A scenario's timed SIM_ parameter sets, through a SIM_ parameter service of system 1 as the plant
        // server's would go (none fire without `[[event]]`).
        let events = SimEvents::new(scenario.sim_events()?);
        let sim = SimParamService::new(1, &plant);
        let noise = scenario.state_noise()?;
        let reference = ReferenceGen::new(&scenario.reference, opts.mode);

        let dt_us = u64::from(1_000_000 / rates.inner_hz);
        let ticks = (scenario.duration_s * f64::from(rates.inner_hz)).round() as u64;
        let trace_hz = opts.trace_hz.clamp(1, rates.inner_hz);
        let telemetry_names: Vec<&'static str> = controller.telemetry().iter().map(|(n, _)| *n).collect();
        let trace = Trace {
            columns: CORE_COLUMNS.iter().chain(&telemetry_names).map(|s| (*s).to_owned()).collect(),
            rows: Vec::new(),
        };
        let mut series = Series::default();
        let n = usize::try_from(ticks).unwrap_or(0);
        series.t.reserve(n);
        for v in series.pos.iter_mut().chain(&mut series.euler).chain(&mut series.ref_pos).chain(&mut series.ref_euler)
        {
            v.reserve(n);
        }
        Ok(Self {
            scenario: scenario.clone(),
            label: label.to_owned(),
            seed: opts.seed,
            rates,
            mode: opts.mode,
            controller,
            controller_config,
            plant,
            airframe_before,
            plant_name,
            events,
            sim,
            noise,
            reference,
            dt_us,
            ticks,
            k: 0,
            trace_hz,
            trace,
            series,
            effort,
            non_finite: false,
            last: None,
            wall_start: Instant::now(),
        })
    }

    /// Ticks run so far, and in the whole run.
    #[must_use]
    pub fn ticks(&self) -> (u64, u64) {
        (self.k, self.ticks)
    }

    /// Simulated time (s).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        (self.k * self.dt_us) as f64 * 1e-6
    }

    /// The plant's truth now, with what the controller saw and was asked at the last tick (None before
    /// the first).
    #[must_use]
    pub fn state(&self) -> Option<TickState> {
        self.last.map(|(seen, reference, pwm_us)| TickState { truth: self.plant.truth(), seen, reference, pwm_us })
    }

    /// The trace so far.
    #[must_use]
    pub fn trace(&self) -> &Trace {
        &self.trace
    }

    /// The plant, read-only.
    #[must_use]
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The controller, read-only (its telemetry, its attitude setpoint).
    #[must_use]
    pub fn controller(&self) -> &dyn Controller {
        self.controller.as_ref()
    }

    /// The reference's positions over the next `horizon_s` seconds (from now, `n` points), from a copy
    /// of its generator, so the run is not touched.
    #[must_use]
    pub fn ahead_ned_m(&self, horizon_s: f64, n: usize) -> Vec<Vector3<f64>> {
        let mut reference = self.reference.clone();
        let now_s = self.time_s();
        (0..n).map(|i| reference.at(now_s + horizon_s * i as f64 / n.max(1) as f64).pos_ned_m).collect()
    }

    /// Sets a SIM_ parameter now, as a ground station's PARAM_SET on the SIM_ port would.
    ///
    /// # Errors
    /// An unknown name or a value the parameter refuses; nothing changes then.
    pub fn set_sim_param(&mut self, name: &str, value: f32) -> Result<(), String> {
        self.sim.set(name, value, &mut self.plant).map(|_| ())
    }

    /// The controller configuration in use.
    #[must_use]
    pub fn controller_config_in_use(&self) -> &ControllerConfig {
        &self.controller_config
    }

    /// Reconfigures the controller from the next tick ([`Controller::reconfigure`]: gains change, the
    /// adaptive state stays). The loop rates cannot change during a run.
    ///
    /// # Errors
    /// A configuration that does not validate, or that changes the loop rates; nothing changes then.
    pub fn reconfigure_controller(&mut self, config: ControllerConfig) -> Result<(), ScenarioError> {
        if config.rates != self.controller_config.rates {
            return Err(ScenarioError::Controller("the loop rates are fixed for a run".into()));
        }
        config.validate().map_err(|e| ScenarioError::Controller(e.to_string()))?;
        self.controller.reconfigure(&config);
        self.controller_config = config;
        Ok(())
    }

    /// One control tick: sample, control, record, integrate. False (and nothing done) once the run is over.
    pub fn step(&mut self) -> bool {
        if self.k >= self.ticks {
            return false;
        }
        let (k, dt_us) = (self.k, self.dt_us);
        let t_s = (k * dt_us) as f64 * 1e-6;
        let r = self.reference.at(t_s);
        let truth = self.plant.truth();
        let state = self.plant.sample_state_of(&truth, &self.noise);
        let input = control_input(&state);
        let pwm_us = self.controller.update(&input, &r);
        self.non_finite |= pwm_us.iter().any(|p| !p.is_finite())
            || !(truth
                .pos_ned_m
                .iter()
                .chain(truth.vel_ned_mps.iter())
                .chain(truth.euler_rad.iter())
                .all(|v| v.is_finite()));
        self.effort.add(&pwm_us, dt_us as f64 * 1e-6);

        let ref_euler = r.attitude_rad.unwrap_or_else(|| Vector3::new(0.0, 0.0, r.yaw_rad));
        let series = &mut self.series;
        series.t.push(t_s);
        for i in 0..3 {
            series.pos[i].push(truth.pos_ned_m[i]);
            series.euler[i].push(truth.euler_rad[i]);
            series.ref_pos[i].push(r.pos_ned_m[i]);
            series.ref_euler[i].push(ref_euler[i]);
        }
        if let ReferenceGen::Track(track) = &mut self.reference {
            series.progress_m.push(track.progress_m(t_s));
        }
        if let Some(ref_rate) = r.rate_frd_radps {
            for i in 0..3 {
                series.rate[i].push(truth.rate_frd_radps[i]);
                series.ref_rate[i].push(ref_rate[i]);
            }
        }
        if (k * u64::from(self.trace_hz)) % u64::from(self.rates.inner_hz) == 0 {
            let sp = self.controller.attitude_setpoint_rad();
            let mut row = vec![t_s];
            row.extend(truth.pos_ned_m.iter());
            row.extend(truth.euler_rad.iter());
            row.extend(pwm_us);
            row.extend(r.pos_ned_m.iter());
            row.extend(ref_euler.iter());
            row.extend(truth.vel_ned_mps.iter());
            row.extend(truth.wind_ned_mps.iter());
            row.extend(sp.iter());
            row.extend(self.controller.telemetry().iter().map(|(_, v)| *v));
            self.trace.rows.push(row);
        }
        self.events.step(&mut self.sim, &mut self.plant, pwm_us, dt_us);
        self.last = Some((input, r, pwm_us));
        self.k += 1;
        true
    }

    /// The run's metrics over the ticks run so far (all of them after the last [`Runner::step`]) and its
    /// trace.
    ///
    /// # Errors
    /// A scenario `[[event]]` the plant refused.
    pub fn finish(mut self) -> Result<RunOutput, ScenarioError> {
        if let Some(r) = self.events.refusals().first() {
            return Err(ScenarioError::Invalid(format!(
                "[[event]] at {} s: the plant refused {}: {}",
                r.at_us as f64 * 1e-6,
                r.name,
                r.reason
            )));
        }
        if self.series.t.is_empty() {
            return Err(ScenarioError::Invalid("the run has not run a tick: step it first".into()));
        }
        let trace = std::mem::take(&mut self.trace);
        let Self { scenario, series, effort, controller, plant, airframe_before, .. } = &self;
        let sim_s = self.k as f64 * self.dt_us as f64 * 1e-6;
        let mut m = RunMetrics {
            scenario: scenario.name.clone(),
            controller: self.label.clone(),
            plant: self.plant_name.clone(),
            airframe_overrides: scenario.airframe_overrides(),
            seed: self.seed,
            rate_hz: self.rates.inner_hz,
            reference_mode: matches!(scenario.reference, ReferenceSpec::Track(_)).then(|| self.mode.to_string()),
            segments: None,
            rms: None,
            gust: None,
            track: None,
            fault: None,
            corners: None,
            pulses: None,
            weights_at_bounds: controller.weights_at_bounds(),
            non_finite: self.non_finite,
            pwm_activity_us: effort.pwm_activity_us(),
            effort: effort.metrics(),
            sim_s,
            wall_s: 0.0,
            realtime_factor: 0.0,
        };
        if scenario.metrics.contains(&MetricKind::Steps) {
            let (segments, rms) = super::steps::step_metrics(scenario, series);
            m.segments = Some(segments);
            m.rms = Some(rms);
        }
        if scenario.metrics.contains(&MetricKind::Gust) {
            let gust = scenario.wind.gust.as_ref().expect("validated: the gust metric has a gust");
            let windows = &scenario.metric_windows;
            m.gust = Some(metrics::hover_gust_metrics(
                &series.t,
                &series.pos,
                &series.ref_pos,
                gust.onset_s,
                gust.release_s,
                windows,
            ));
        }
        if scenario.metrics.contains(&MetricKind::Fault) {
            m.fault = Some(metrics::fault_metrics(
                &series.t,
                &series.pos,
                &series.ref_pos,
                &series.euler,
                &series.ref_euler,
                scenario.fault_onset_s(),
                metrics::FaultPhysics {
                    envelope: envelope::hover_envelope(airframe_before),
                    max_payload_within_limiter_kg: envelope::max_payload_within_limiter_kg(airframe_before),
                    feasibility: envelope::feasibility(&plant.config().airframe),
                },
            ));
        }
        if let (true, ReferenceSpec::Track(spec)) = (scenario.metrics.contains(&MetricKind::Track), &scenario.reference)
        {
            let track = TrackGen::new(spec, self.mode);
            let (t0, t1) = (spec.start_s, track.end_s());
            let mut cross = Vec::new();
            let mut alt = Vec::new();
            let mut t_on_track_s = Vec::new();
            // The vehicle's own nearest point is followed along the path (it moves a few mm per tick), so a
            // point near the crossing stays on its branch; the first is sought near the reference.
            let mut nearest_s: Option<f64> = None;
            // The cross-track error of every sample from the start on (the corners metric's runs on past the
            // track's end); NaN before.
            let mut cross_all = vec![f64::NAN; series.t.len()];
            for (k, cross_k) in cross_all.iter_mut().enumerate() {
                if series.t[k] < t0 {
                    continue;
                }
                let p = Vector2::new(series.pos[0][k], series.pos[1][k]);
                let (d, s) = match nearest_s {
                    Some(s) => track.path.nearest_near(p, s, 0.05),
                    None => track.path.nearest_near(p, series.progress_m[k], 0.5),
                };
                nearest_s = Some(s);
                *cross_k = d;
                if series.t[k] > t1 {
                    continue;
                }
                cross.push(d);
                alt.push(series.pos[2][k] - series.ref_pos[2][k]);
                t_on_track_s.push(series.t[k]);
            }
            m.track = Some(metrics::track_metrics(&t_on_track_s, &cross, &alt));
            if scenario.metrics.contains(&MetricKind::Corners) {
                let (t, pos, progress) = (&series.t, &series.pos, &series.progress_m);
                m.corners = Some(flight::corner_metrics(
                    t,
                    &pos[0],
                    &pos[1],
                    progress,
                    &cross_all,
                    &spec.waypoints_ne_m,
                    spec.laps,
                ));
            }
        }
        if scenario.metrics.contains(&MetricKind::Pulses) {
            let (pos, reference) = (&series.pos, &series.ref_pos);
            let err_xy: Vec<f64> =
                (0..series.t.len()).map(|k| (pos[0][k] - reference[0][k]).hypot(pos[1][k] - reference[1][k])).collect();
            m.pulses = Some(flight::pulse_metrics(&series.t, &err_xy, plant.wind().pulses()));
        }
        m.wall_s = self.wall_start.elapsed().as_secs_f64();
        m.realtime_factor = if m.wall_s > 0.0 { sim_s / m.wall_s } else { f64::INFINITY };
        Ok(RunOutput { metrics: m, trace })
    }
}

#[cfg(test)]
mod tests {
    use autopilot::core::control::ControllerKind;
    use nalgebra::Vector2;

    use super::*;
    use crate::plant::InitialState;
    use crate::scenario::MetricWindows;
    use crate::scenario::path::{PathKind, TrackPath};

    /// A scenario from TOML text, validated.
    fn scenario(text: &str) -> Scenario {
        Scenario::from_toml("test", text).unwrap_or_else(|e| panic!("{e}"))
    }

    /// An ACO run that traces every tick.
    fn run_every_tick(s: &Scenario) -> RunOutput {
        let opts = RunOptions { trace_hz: 500, ..RunOptions::new(ControllerKind::ACO) };
        run(s, &opts).unwrap()
    }

    fn column(out: &RunOutput, name: &str) -> Vec<f64> {
        out.trace.column(name).unwrap_or_else(|| panic!("no column {name}"))
    }

    /// The metrics JSON without the wall-clock fields.
    fn metrics_json(m: &RunMetrics) -> serde_json::Value {
        let mut v = serde_json::to_value(m).unwrap();
        let o = v.as_object_mut().unwrap();
        o.remove("wall_s");
        o.remove("realtime_factor");
        v
    }

    const SQUARE_TRACK: &str = r#"
name = "square"
duration_s = 17.0
plant = "mismatch"
metrics = ["track"]
[initial]
pos_ned_m = [0.0, 0.0, -1.5]
[reference]
kind = "track"
path = "PATH"
waypoints_ne_m = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]
pos_d_m = -1.5
speed_mps = 0.3
prefilter_wn_radps = 2.5
start_s = 1.0
reference_modes = ["feed-forward"]
"#;

    /// Distance from `p` to the closed unit square's sides.
    fn distance_to_square(p: Vector2<f64>) -> f64 {
        let corners = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]].map(|c| Vector2::new(c[0], c[1]));
        corners
            .windows(2)
            .map(|w| {
                let (a, ab) = (w[0], w[1] - w[0]);
                let x = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                (p - (a + ab * x)).norm()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn given_a_polyline_square_then_the_reference_runs_on_its_sides_and_cross_track_is_measured_to_them() {
        let s = scenario(&SQUARE_TRACK.replace("PATH", "polyline"));
        let out = run_every_tick(&s);
        let (t, n, e) = (column(&out, "t"), column(&out, "pN"), column(&out, "pE"));
        let (rn, re) = (column(&out, "refN"), column(&out, "refE"));
        let end_s = 1.0 + 4.0 / 0.3;
        let mut cross = Vec::new();
        let mut spline_cross = Vec::new();
        let spline = TrackPath::new(PathKind::Spline, &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]);
        for k in 0..t.len() {
            // The reference never leaves the straight sides.
            assert!(distance_to_square(Vector2::new(rn[k], re[k])) < 1e-9, "t {}: ref ({}, {})", t[k], rn[k], re[k]);
            if t[k] >= 1.0 && t[k] <= end_s {
                let p = Vector2::new(n[k], e[k]);
                cross.push(distance_to_square(p));
                spline_cross.push(spline.nearest_near(p, 0.0, 10.0).0);
            }
        }
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let m = out.metrics.track.unwrap();
        assert!((m.cross_track_rms_m - rms(&cross)).abs() < 1e-12, "{} vs {}", m.cross_track_rms_m, rms(&cross));
        let max = cross.iter().copied().fold(0.0, f64::max);
        assert!((m.cross_track_max_m - max).abs() < 1e-12, "{} vs {max}", m.cross_track_max_m);
        // Against the spline through the same corners the same flight measures something else.
        let spline_rms = rms(&spline_cross);
        assert!((spline_rms - m.cross_track_rms_m).abs() > 0.2 * m.cross_track_rms_m, "{spline_rms} vs {m:?}");
        // It flew the square: the corners (1, 0), (1, 1) and (0, 1) were passed within 10 cm.
        for c in [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] {
            let closest = (0..t.len()).map(|k| (n[k] - c[0]).hypot(e[k] - c[1])).fold(f64::INFINITY, f64::min);
            assert!(closest < 0.1, "corner {c:?}: {closest}");
        }
    }

    #[test]
    fn given_a_spline_track_when_path_is_named_then_nothing_changes() {
        let implicit = scenario(&SQUARE_TRACK.replace("path = \"PATH\"\n", ""));
        let explicit = scenario(&SQUARE_TRACK.replace("PATH", "spline"));
        let (a, b) = (run_every_tick(&implicit), run_every_tick(&explicit));
        assert_eq!(a.trace, b.trace);
        assert_eq!(metrics_json(&a.metrics), metrics_json(&b.metrics));
    }

    /// A hover at 2 m, then from 1 s a ramp along N at 0.5 m/s as 0.1 s steps (FF: their feed-forward),
    /// held at 1 m from 3 s.
    fn ramp(feed_forward: &str) -> Scenario {
        let mut steps = vec!["{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -2.0] }".to_owned()];
        for k in 1..=20 {
            let t = 1.0 + 0.1 * f64::from(k - 1);
            let n = 0.05 * f64::from(k);
            steps.push(format!("{{ t_s = {t:.1}, pos_ned_m = [{n:.2}, 0.0, -2.0]{feed_forward} }}"));
        }
        steps.push("{ t_s = 3.0, pos_ned_m = [1.0, 0.0, -2.0] }".to_owned());
        scenario(&format!(
            "name = \"ramp\"\nduration_s = 8.0\nmetrics = [\"steps\"]\n[initial]\npos_ned_m = [0.0, 0.0, -2.0]\n\
             [reference]\nkind = \"position\"\nsteps = [{}]\n",
            steps.join(", ")
        ))
    }

    #[test]
    fn given_position_steps_with_velocity_feed_forward_then_the_vehicle_lags_less_than_half_as_much() {
        let plain = run_every_tick(&ramp(""));
        let fed = run_every_tick(&ramp(", vel_ned_mps = [0.5, 0.0, 0.0]"));
        // Lag: how far behind the moving target the vehicle is at the end of the ramp (3 s), and when it
        // first comes within 5 cm of the final 1 m.
        let lag = |out: &RunOutput| {
            let (t, n) = (column(out, "t"), column(out, "pN"));
            let k3 = t.iter().position(|&x| x >= 3.0).unwrap();
            let reached = (0..t.len()).find(|&k| (n[k] - 1.0).abs() < 0.05).map_or(f64::INFINITY, |k| t[k]);
            (1.0 - n[k3], reached)
        };
        let ((behind_plain, reached_plain), (behind_fed, reached_fed)) = (lag(&plain), lag(&fed));
        println!(
            "ramp: behind at 3 s {behind_plain:.4} m without feed-forward, {behind_fed:.4} m with; within 5 cm of 1 m \
             at {reached_plain:.3} s without, {reached_fed:.3} s with"
        );
        assert!(behind_fed < 0.5 * behind_plain, "behind at 3 s: {behind_fed} with, {behind_plain} without");
        assert!(reached_fed + 0.5 < reached_plain, "within 5 cm at {reached_fed} s with, {reached_plain} s without");
    }

    #[test]
    fn given_position_steps_with_feed_forward_then_the_reference_carries_it() {
        let s = ramp(", vel_ned_mps = [0.5, 0.0, 0.0], acc_ned_mps2 = [0.0, 0.1, -0.2]");
        let mut g = ReferenceGen::new(&s.reference, ReferenceMode::FeedForward);
        let r = g.at(1.55);
        assert_eq!(r.pos_ned_m, Vector3::new(0.30, 0.0, -2.0));
        assert_eq!(r.vel_ned_mps, Vector3::new(0.5, 0.0, 0.0));
        assert_eq!(r.acc_ned_mps2, Vector3::new(0.0, 0.1, -0.2));
        // The hold before and after carries none.
        assert_eq!((g.at(0.5).vel_ned_mps, g.at(3.5).acc_ned_mps2), (Vector3::zeros(), Vector3::zeros()));
    }

    #[test]
    fn given_a_gust_peak_window_then_the_peak_is_taken_over_it_and_defaults_change_nothing() {
        let base = Scenario::load("gust-hover").unwrap();
        let explicit = scenario(&format!(
            "{}\n[metric_windows]\nstep_sse_s = 0.5\ngust_steady_s = 3.0\n",
            crate::scenario::BUILT_INS.iter().find(|b| b.0 == "gust-hover").unwrap().1
        ));
        let windowed = Scenario {
            metric_windows: MetricWindows { gust_peak_s: Some([0.0, 4.5]), ..base.metric_windows },
            ..base.clone()
        };
        let (a, b, c) = (run_every_tick(&base), run_every_tick(&explicit), run_every_tick(&windowed));
        assert_eq!(metrics_json(&a.metrics), metrics_json(&b.metrics), "explicit defaults");
        let (whole, before_gust) = (a.metrics.gust.clone().unwrap(), c.metrics.gust.clone().unwrap());
        // Before the gust the error is the noise's; the gust's peak is several times that.
        assert!(before_gust.peak_m < 0.5 * whole.peak_m, "{} vs {}", before_gust.peak_m, whole.peak_m);
        let (t, n, e) = (column(&c, "t"), column(&c, "pN"), column(&c, "pE"));
        let expected = (0..t.len()).filter(|&k| t[k] < 4.5 - 1e-9).map(|k| n[k].hypot(e[k])).fold(0.0, f64::max);
        assert!((before_gust.peak_m - expected).abs() < 1e-12, "{} vs {expected}", before_gust.peak_m);
        // Only the peak moved.
        assert_eq!((before_gust.rms_xy_m, before_gust.steady_err_m), (whole.rms_xy_m, whole.steady_err_m));
    }

    #[test]
    fn given_airframe_overrides_then_the_label_and_json_name_them() {
        let text = "name = \"x\"\nduration_s = 0.2\nplant = \"mismatch\"\nmetrics = [\"steps\"]\n\
                    [initial]\npos_ned_m = [0.0, 0.0, -1.0]\n\
                    [reference]\nkind = \"position\"\nsteps = [{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.0] }]\n";
        let plain = run_every_tick(&scenario(text));
        assert_eq!(plain.metrics.plant, "mismatch");
        assert!(metrics_json(&plain.metrics).get("airframe_overrides").is_none());

        let s = scenario(&format!("{text}[airframe]\nmass_kg = 5.3\nrotor_health = [1.0, 1.0, 0.8, 1.0]\n"));
        let out = run_every_tick(&s);
        assert_eq!(out.metrics.plant, "mismatch+mass_kg=5.3+rotor_health=1,1,0.8,1");
        let json = metrics_json(&out.metrics);
        assert_eq!(
            json["airframe_overrides"],
            serde_json::json!({"mass_kg": 5.3, "rotor_health": [1.0, 1.0, 0.8, 1.0]})
        );
        // `--plant` changes the preset, the overrides stay.
        let opts = RunOptions { plant: Some("nominal".into()), ..RunOptions::new(ControllerKind::ACO) };
        assert_eq!(run(&s, &opts).unwrap().metrics.plant, "nominal+mass_kg=5.3+rotor_health=1,1,0.8,1");
    }

    #[test]
    fn given_noise_scale_zero_then_the_run_is_the_noise_free_one_bit_for_bit() {
        let mut paper = Scenario::load("gust-hover").unwrap();
        paper.duration_s = 8.0;
        let none = Scenario { state_noise: super::super::StateNoiseKind::None, ..paper.clone() };
        let zero = Scenario { state_noise_scale: 0.0, ..paper.clone() };
        let (a, b, c) = (run_every_tick(&none), run_every_tick(&zero), run_every_tick(&paper));
        let bits = |t: &Trace| t.rows.iter().flatten().map(|v| v.to_bits()).collect::<Vec<u64>>();
        assert_eq!(bits(&a.trace), bits(&b.trace));
        assert_eq!(metrics_json(&a.metrics), metrics_json(&b.metrics));
        assert_ne!(bits(&a.trace), bits(&c.trace), "the paper's noise does change the run");
    }

    #[test]
    fn given_noise_scale_two_then_the_sampled_state_has_twice_the_sigma() {
        let paper = Scenario::load("gust-hover").unwrap();
        let doubled = Scenario { state_noise_scale: 2.0, ..paper.clone() };
        let sample_sigma = |s: &Scenario| {
            let config = plant_config(s, None).unwrap();
            let initial = InitialState { pos_ned_m: Vector3::new(0.0, 0.0, -1.5), ..InitialState::default() };
            let mut plant = Plant::new(config, &initial, 7).unwrap();
            let noise = s.state_noise().unwrap();
            let truth = plant.truth();
            let x: Vec<f64> = (0..20_000).map(|_| plant.sample_state_of(&truth, &noise).pos_ned_m.x).collect();
            let mean = x.iter().sum::<f64>() / x.len() as f64;
            (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (x.len() - 1) as f64).sqrt()
        };
        let (one, two) = (sample_sigma(&paper), sample_sigma(&doubled));
        assert!((one - 0.02).abs() < 0.02 * 0.03, "{one}");
        assert!((two / one - 2.0).abs() < 1e-9, "{two} / {one}");
    }

    /// From hover at 0.5 m, a step to 1 m below the ground plane.
    const INTO_THE_GROUND: &str = "name = \"dig\"\nduration_s = 6.0\nmetrics = [\"steps\"]\nGROUND\n\
                                   [initial]\npos_ned_m = [0.0, 0.0, -0.5]\n\
                                   [reference]\nkind = \"position\"\n\
                                   steps = [{ t_s = 0.0, pos_ned_m = [0.0, 0.0, 1.0] }]\n";

    #[test]
    fn given_the_ground_off_then_the_vehicle_passes_below_d_0_freely() {
        let on = run_every_tick(&scenario(&INTO_THE_GROUND.replace("GROUND", "")));
        let off = run_every_tick(&scenario(&INTO_THE_GROUND.replace("GROUND", "ground = false")));
        let lowest = |out: &RunOutput| column(out, "pD").into_iter().fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(lowest(&on), 0.0, "the ground stops it at D = 0");
        assert!(lowest(&off) > 0.9, "{}", lowest(&off));
        // No contact acted: the plant of a ground-off scenario has none.
        let s = scenario(&INTO_THE_GROUND.replace("GROUND", "ground = false"));
        assert!(!plant_config(&s, None).unwrap().ground.enabled);
        assert!(plant_config(&Scenario { ground: true, ..s }, None).unwrap().ground.enabled);
    }

    /// rotor-degradation-90 shortened to `duration_s`, its event at `at_s`.
    fn degradation(duration_s: f64, at_s: &str) -> Scenario {
        let text = crate::scenario::BUILT_INS.iter().find(|b| b.0 == "rotor-degradation-90").unwrap().1;
        scenario(
            &text
                .replace("duration_s = 20.0", &format!("duration_s = {duration_s}"))
                .replace("at_s = 5.0", &format!("at_s = {at_s}")),
        )
    }

    #[test]
    fn given_an_event_between_ticks_then_it_acts_from_the_next_tick_exactly_as_one_set_there() {
        // At 500 Hz the ticks are 2 ms apart: an event at 1.0035 s acts from the tick at 1.004 s.
        let bits = |t: &Trace| t.rows.iter().flatten().map(|v| v.to_bits()).collect::<Vec<u64>>();
        let between = run_every_tick(&degradation(1.5, "1.0035"));
        let on_next = run_every_tick(&degradation(1.5, "1.004"));
        let on_previous = run_every_tick(&degradation(1.5, "1.002"));
        assert_eq!(bits(&between.trace), bits(&on_next.trace));
        assert_ne!(bits(&between.trace), bits(&on_previous.trace), "a tick earlier is another run");
        // Up to the tick at 1.004 s the PWM the controller sent is the healthy hover's; from the next on it
        // reacts to the lost thrust.
        let (t, pwm1) = (column(&between, "t"), column(&between, "pwm1"));
        let healthy = run_every_tick(&degradation(1.5, "1.5"));
        let k = t.iter().position(|&x| x > 1.004 - 1e-9).unwrap();
        assert_eq!(pwm1[..=k], column(&healthy, "pwm1")[..=k]);
        assert_ne!(pwm1[k + 1..], column(&healthy, "pwm1")[k + 1..]);
    }

    #[test]
    fn given_a_fault_scenario_run_twice_then_the_trace_and_metrics_are_bit_identical() {
        let s = degradation(7.0, "5.0");
        let (a, b) = (run_every_tick(&s), run_every_tick(&s));
        let bits = |t: &Trace| t.rows.iter().flatten().map(|v| v.to_bits()).collect::<Vec<u64>>();
        assert_eq!(bits(&a.trace), bits(&b.trace));
        assert_eq!(metrics_json(&a.metrics), metrics_json(&b.metrics));
        // The fault metric is there, judged from 5 s, and says what physics allows: 90 % holds every moment.
        let f = a.metrics.fault.unwrap();
        assert_eq!((f.onset_s, f.feasibility), (5.0, crate::plant::Feasibility::Full));
        assert!((f.envelope.min_health_full_control - 0.8809).abs() < 1e-4);
    }

    #[test]
    fn given_a_payload_step_then_the_vehicle_sinks_after_the_event_and_not_before() {
        let text = crate::scenario::BUILT_INS.iter().find(|b| b.0 == "payload-step-5").unwrap().1;
        let out = run_every_tick(&scenario(&text.replace("duration_s = 20.0", "duration_s = 6.0")));
        let (t, d) = (column(&out, "t"), column(&out, "pD"));
        let before = (0..t.len()).filter(|&k| t[k] < 5.0).map(|k| d[k] + 1.5).fold(0.0, f64::max);
        let after = (0..t.len()).filter(|&k| t[k] >= 5.0).map(|k| d[k] + 1.5).fold(0.0, f64::max);
        // 0.26 kg is 5 % of the weight: it pulls the vehicle down by centimetres until the controller lifts.
        assert!(before < 0.01 && after > 0.01, "before {before} m, after {after} m");
        let f = out.metrics.fault.unwrap();
        assert!((f.altitude_drop_m - after).abs() < 1e-12, "{f:?}");
    }
}
