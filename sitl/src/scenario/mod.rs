//! The paper's experiments as scenario files: a TOML format, the built-in scenarios, an in-process
//! lockstep runner (plant + controller on simulated time, no sockets), metrics and plots.
//!
//! The format, every key with its unit, frame and default, and an example per feature:
//! `docs/scenarios.md`. In short (all lengths m, angles rad, times s; NED/FRD):
//! ```toml
//! name = "paper-attitude"
//! description = "..."
//! duration_s = 16.0
//! plant = "nominal"               # airframe preset; `--plant` overrides it
//! state_noise = "none"            # "none" | "paper": white noise on the state the controller sees
//! state_noise_scale = 1.0         # multiplies the noise's sigmas (>= 0)
//! ground = true                   # the plant's ground contact at D = 0
//! metrics = ["steps"]             # any of "steps", "gust", "track", "fault", "corners", "pulses"
//! controllers = ["aco", "ca", "pid"]  # the default set when `--controller` is not given
//! [initial]                       # optional; at rest at the origin with hover lift by default
//! pos_ned_m = [0.0, 0.0, -3.0]
//! euler_rad = [0.4, -0.5, -0.4]
//! [reference]                     # kind = "attitude" | "position" | "track" (see `reference`);
//!                                 # position steps may carry vel_ned_mps, acc_ned_mps2 feed-forward;
//!                                 # a track's path = "spline" (default) | "polyline"
//! kind = "attitude"
//! pos_d_m = -3.0
//! steps = [{ t_s = 0.0, euler_rad = [0.0, 0.0, 0.0] }]
//! [airframe]                      # optional overrides of the preset's values (e.g. mass_kg = 5.3)
//! [wind]                          # optional: gust, turbulence, steady wind, pulses (the plant's WindConfig)
//! [controller]                    # optional overrides of the controllers' configuration
//! [metric_windows]                # optional: step_sse_s, gust_steady_s, gust_peak_s, gust_rms_s
//! [[event]]                       # optional, any number: SIM_ parameters set at a plant time
//! at_s = 5.0
//! set = { SIM_MOT1_EFF = 0.9 }
//! ```

#[cfg(test)]
pub(crate) mod fixtures;
pub mod flight;
pub mod gcs;
pub mod metrics;
pub mod path;
pub mod plot;
pub mod rc;
pub mod reference;
pub mod runner;
mod steps;
pub mod two_process;

use std::collections::BTreeMap;
use std::path::Path;

use autopilot::core::control::{ControllerConfig, ControllerKind};
use autopilot::core::manual::ManualConfig;
use serde::{Deserialize, Serialize};

use nalgebra::Vector3;

use crate::plant::{AirframeConfig, InitialState, StateNoise, WindConfig};
use crate::sim_params::events::{self, EventSpec, SimEvent};
pub use metrics::MetricWindows;
pub use path::PathKind;
pub use reference::{ReferenceMode, ReferenceSpec};

/// Why a scenario could not be loaded or run.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("no built-in scenario or file named `{0}` (built-ins: {built_ins})", built_ins = BUILT_INS.iter().map(|b| b.0).collect::<Vec<_>>().join(", "))]
    NotFound(String),
    #[error("cannot read scenario file {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("scenario {name}: {source}")]
    Parse { name: String, source: Box<toml::de::Error> },
    #[error("invalid scenario: {0}")]
    Invalid(String),
    #[error("plant: {0}")]
    Plant(#[from] crate::plant::PlantError),
    #[error("controller: {0}")]
    Controller(String),
}

/// Which feedback the controller gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum StateNoiseKind {
    /// Noise-free truth (the paper's simulation runs).
    #[default]
    None,
    /// Truth plus the paper's "hardware" white noise (0.02 m, 0.05 m/s, 0.005 rad, 0.01 rad/s, 0.2 m/s²).
    Paper,
}

/// Which metric groups a scenario computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MetricKind {
    Steps,
    Gust,
    Track,
    /// What a fault did, from its onset (the first `[[event]]`, or 0) to the end ([`metrics::FaultMetrics`]).
    Fault,
    /// A polyline track's turning points: overshoot and return to the path ([`flight::CornerMetrics`]).
    Corners,
    /// A hover's recovery after each pulse of `[wind.pulses]` ([`flight::PulseMetrics`]).
    Pulses,
}

/// An `[airframe]` override's value in the metrics JSON: a number, or an array for vector keys.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum OverrideValue {
    Scalar(f64),
    Array(Vec<f64>),
}

/// The initial state of the plant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct InitialSpec {
    pub pos_ned_m: [f64; 3],
    pub vel_ned_mps: [f64; 3],
    pub euler_rad: [f64; 3],
    pub rate_frd_radps: [f64; 3],
}

impl InitialSpec {
    /// The plant's initial state: this position, velocity, attitude and rates, the rotors at hover lift.
    #[must_use]
    pub fn state(&self) -> InitialState {
        InitialState {
            pos_ned_m: Vector3::from(self.pos_ned_m),
            vel_ned_mps: Vector3::from(self.vel_ned_mps),
            euler_rad: Vector3::from(self.euler_rad),
            rate_frd_radps: Vector3::from(self.rate_frd_radps),
            rotor_lift_n: None,
        }
    }
}

/// A scenario, as read from its TOML file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub duration_s: f64,
    #[serde(default = "default_plant")]
    pub plant: String,
    #[serde(default)]
    pub state_noise: StateNoiseKind,
    /// Multiplies every σ of `state_noise` (>= 0, finite; 0 = no noise, 1 = the paper's). A sweep may set
    /// it after loading; [`Scenario::state_noise`] checks it again.
    #[serde(default = "unit_scale")]
    pub state_noise_scale: f64,
    /// The plant's ground contact at D = 0 (on by default); off, nothing stops the vehicle below D = 0.
    #[serde(default = "ground_on")]
    pub ground: bool,
    pub metrics: Vec<MetricKind>,
    /// The windows the metrics are taken over; the defaults reproduce the fixed windows of `metrics`.
    #[serde(default)]
    pub metric_windows: MetricWindows,
    #[serde(default = "default_controllers")]
    pub controllers: Vec<ControllerKind>,
    #[serde(default)]
    pub initial: InitialSpec,
    pub reference: ReferenceSpec,
    /// Overrides of the preset's values; its own `preset` must be absent or equal `plant`.
    #[serde(default)]
    pub airframe: AirframeConfig,
    #[serde(default)]
    pub wind: WindConfig,
    #[serde(default)]
    pub controller: ControllerConfig,
    /// The pilot's radio: a stick schedule on plant time (see [`rc`]), sent to the autopilot as
    /// `RC_CHANNELS`; two-process runs only (`sitl run --scenario`).
    #[serde(default)]
    pub rc: Vec<rc::RcEntry>,
    /// The autopilot's manual-control settings (its configuration file's `[vehicle.manual]`: the radio's
    /// map RC_MAP_*, calibration RCn_*, COM_FLTMODE1..6, MAN_ARM_GESTURE, ...); two-process runs only.
    #[serde(default)]
    pub manual: Option<ManualConfig>,
    /// Timed SIM_ parameter sets (`[[event]]`: `at_s`, `set = { SIM_MOT1_EFF = 0.9 }`), fired at the first
    /// plant step at or after `at_s` through the SIM_ parameter service, in-process and two-process alike
    /// (see [`crate::sim_params::events`]).
    #[serde(default, rename = "event")]
    pub events: Vec<EventSpec>,
}

fn unit_scale() -> f64 {
    1.0
}

fn ground_on() -> bool {
    true
}

fn default_plant() -> String {
    "nominal".to_owned()
}

fn default_controllers() -> Vec<ControllerKind> {
    vec![ControllerKind::ACO, ControllerKind::CA, ControllerKind::PID]
}

/// The built-in scenarios, one per experiment of the paper (plus the turbulence and fast figure-8 variants),
/// and the fault experiments: a rotor's thrust lost, a payload added (the issue's magnitudes and ones inside
/// the airframe's envelope), the figure-8 on a weak rotor; and the paper's real flights (its Section 6):
/// the figure-8 point by point and the hover under a train of pulses.
pub const BUILT_INS: &[(&str, &str)] = &[
    ("paper-attitude", include_str!("../../scenarios/paper-attitude.toml")),
    ("paper-translation", include_str!("../../scenarios/paper-translation.toml")),
    ("gust-hover", include_str!("../../scenarios/gust-hover.toml")),
    ("turbulence-hover", include_str!("../../scenarios/turbulence-hover.toml")),
    ("figure8", include_str!("../../scenarios/figure8.toml")),
    ("figure8-fast", include_str!("../../scenarios/figure8-fast.toml")),
    ("rotor-degradation", include_str!("../../scenarios/rotor-degradation.toml")),
    ("rotor-degradation-50", include_str!("../../scenarios/rotor-degradation-50.toml")),
    ("rotor-degradation-85", include_str!("../../scenarios/rotor-degradation-85.toml")),
    ("rotor-degradation-90", include_str!("../../scenarios/rotor-degradation-90.toml")),
    ("payload-step", include_str!("../../scenarios/payload-step.toml")),
    ("payload-step-40", include_str!("../../scenarios/payload-step-40.toml")),
    ("payload-step-5", include_str!("../../scenarios/payload-step-5.toml")),
    ("payload-step-10", include_str!("../../scenarios/payload-step-10.toml")),
    ("figure8-rotor80", include_str!("../../scenarios/figure8-rotor80.toml")),
    ("figure8-rotor90", include_str!("../../scenarios/figure8-rotor90.toml")),
    ("rate-steps", include_str!("../../scenarios/rate-steps.toml")),
    ("paper-flight-figure8", include_str!("../../scenarios/paper-flight-figure8.toml")),
    ("paper-flight-hover", include_str!("../../scenarios/paper-flight-hover.toml")),
];

impl Scenario {
    /// Parses and validates a scenario from TOML text.
    ///
    /// # Errors
    /// [`ScenarioError::Parse`] for malformed TOML or unknown fields, [`ScenarioError::Invalid`] for values
    /// that cannot be run.
    pub fn from_toml(name: &str, text: &str) -> Result<Self, ScenarioError> {
        let scenario: Self =
            toml::from_str(text).map_err(|e| ScenarioError::Parse { name: name.to_owned(), source: Box::new(e) })?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// A built-in scenario by name, or else a file path.
    ///
    /// # Errors
    /// As [`Scenario::from_toml`], plus [`ScenarioError::NotFound`] and [`ScenarioError::Io`].
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        if let Some((name, text)) = BUILT_INS.iter().find(|(n, _)| *n == name_or_path) {
            return Self::from_toml(name, text);
        }
        let path = Path::new(name_or_path);
        if !path.exists() {
            return Err(ScenarioError::NotFound(name_or_path.to_owned()));
        }
        let text = std::fs::read_to_string(path)
            .map_err(|source| ScenarioError::Io { path: name_or_path.to_owned(), source })?;
        Self::from_toml(name_or_path, &text)
    }

    fn validate(&self) -> Result<(), ScenarioError> {
        if !(self.duration_s > 0.0 && self.duration_s <= 3600.0) {
            return Err(ScenarioError::Invalid(format!("duration_s must be in (0, 3600], got {}", self.duration_s)));
        }
        if self.metrics.is_empty() {
            return Err(ScenarioError::Invalid(
                "metrics must name at least one of steps, gust, track, fault, corners, pulses".into(),
            ));
        }
        self.reference.validate()?;
        self.rc_schedule()?;
        self.sim_events()?;
        if let Some(manual) = &self.manual {
            manual.validate().map_err(|e| ScenarioError::Invalid(format!("[manual]: {e}")))?;
        }
        self.state_noise()?;
        self.validate_metric_windows()?;
        let unset = AirframeConfig::default().preset;
        if self.airframe.preset != unset && self.airframe.preset != self.plant {
            return Err(ScenarioError::Invalid(format!(
                "[airframe] preset `{}` contradicts plant = `{}`: set the preset with `plant`",
                self.airframe.preset, self.plant
            )));
        }
        let is_track = matches!(self.reference, ReferenceSpec::Track(_));
        if self.metrics.contains(&MetricKind::Track) != is_track {
            return Err(ScenarioError::Invalid("the track metric goes with (and only with) a track reference".into()));
        }
        if self.metrics.contains(&MetricKind::Fault) && matches!(self.reference, ReferenceSpec::Attitude { .. }) {
            return Err(ScenarioError::Invalid(
                "the fault metric judges a position or a track against its reference: not an attitude reference".into(),
            ));
        }
        if self.metrics.contains(&MetricKind::Gust) && self.wind.gust.is_none() {
            return Err(ScenarioError::Invalid("the gust metric needs a [wind.gust]".into()));
        }
        let polyline = matches!(&self.reference, ReferenceSpec::Track(t) if t.path == PathKind::Polyline);
        if self.metrics.contains(&MetricKind::Corners) && !(polyline && self.metrics.contains(&MetricKind::Track)) {
            return Err(ScenarioError::Invalid(
                "the corners metric needs a track with path = \"polyline\" and the track metric".into(),
            ));
        }
        if self.metrics.contains(&MetricKind::Pulses)
            && (self.wind.pulses.is_none() || !matches!(self.reference, ReferenceSpec::Position { .. }))
        {
            return Err(ScenarioError::Invalid(
                "the pulses metric needs a [wind.pulses] and a position reference".into(),
            ));
        }
        let init = &self.initial;
        if [init.pos_ned_m, init.vel_ned_mps, init.euler_rad, init.rate_frd_radps]
            .iter()
            .flatten()
            .any(|v| !v.is_finite())
        {
            return Err(ScenarioError::Invalid("initial state must be finite".into()));
        }
        if self.ground && init.pos_ned_m[2] > 0.0 {
            return Err(ScenarioError::Invalid(format!(
                "initial.pos_ned_m starts below the ground (D = {} m > 0): raise it or set ground = false",
                init.pos_ned_m[2]
            )));
        }
        Ok(())
    }

    fn validate_metric_windows(&self) -> Result<(), ScenarioError> {
        let w = &self.metric_windows;
        w.validate().map_err(ScenarioError::Invalid)?;
        let unset = MetricWindows::default();
        let needs = |key: &str, set: bool, metric: MetricKind, name: &str| {
            if set && !self.metrics.contains(&metric) {
                Err(ScenarioError::Invalid(format!("metric_windows.{key} needs the {name} metric")))
            } else {
                Ok(())
            }
        };
        needs("step_sse_s", w.step_sse_s != unset.step_sse_s, MetricKind::Steps, "steps")?;
        needs("gust_steady_s", w.gust_steady_s != unset.gust_steady_s, MetricKind::Gust, "gust")?;
        needs("gust_peak_s", w.gust_peak_s.is_some(), MetricKind::Gust, "gust")?;
        needs("gust_rms_s", w.gust_rms_s.is_some(), MetricKind::Gust, "gust")?;
        for (key, window) in [("gust_peak_s", w.gust_peak_s), ("gust_rms_s", w.gust_rms_s)] {
            if let Some([from, _]) = window
                && from >= self.duration_s
            {
                return Err(ScenarioError::Invalid(format!(
                    "metric_windows.{key} starts at {from} s, after the run's end (duration_s = {})",
                    self.duration_s
                )));
            }
        }
        Ok(())
    }

    /// The `[[rc]]` stick schedule (empty without one).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad entry.
    pub fn rc_schedule(&self) -> Result<crate::plant::RcSchedule, ScenarioError> {
        rc::schedule(&self.rc, self.duration_s).map_err(ScenarioError::Invalid)
    }

    /// The `[[event]]` schedule, ordered by time (empty without one).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad event and key (see [`events::resolve`]).
    pub fn sim_events(&self) -> Result<Vec<SimEvent>, ScenarioError> {
        events::resolve(&self.events, self.duration_s).map_err(ScenarioError::Invalid)
    }

    /// The time of the scenario's fault (s): its first `[[event]]`, or 0 without one (a fault from the
    /// start, set in `[airframe]`).
    #[must_use]
    pub fn fault_onset_s(&self) -> f64 {
        self.events
            .iter()
            .map(|e| e.at_s)
            .fold(None, |a: Option<f64>, t| Some(a.map_or(t, |a| a.min(t))))
            .unwrap_or(0.0)
    }

    /// The noise on the state the controller sees: `state_noise`'s σ times `state_noise_scale`.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] for a scale that is negative or not finite, or a scale other than 1 with
    /// `state_noise = "none"` (it would scale nothing).
    pub fn state_noise(&self) -> Result<StateNoise, ScenarioError> {
        let scale = self.state_noise_scale;
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(ScenarioError::Invalid(format!("state_noise_scale must be finite and >= 0, got {scale}")));
        }
        match self.state_noise {
            StateNoiseKind::None if scale != 1.0 => Err(ScenarioError::Invalid(format!(
                "state_noise_scale = {scale} scales nothing with state_noise = \"none\": set state_noise = \"paper\""
            ))),
            StateNoiseKind::None => Ok(StateNoise::none()),
            StateNoiseKind::Paper => Ok(StateNoise::paper().scaled(scale)),
        }
    }

    /// The plant's label in metrics and figure titles: the preset (`preset`, or else the scenario's
    /// `plant`), then `+key=value` for each `[airframe]` override (array elements joined by commas), e.g.
    /// `mismatch+mass_kg=5.3`. File names take it through [`file_label`].
    #[must_use]
    pub fn plant_label(&self, preset: Option<&str>) -> String {
        let mut label = preset.unwrap_or(&self.plant).to_owned();
        for (key, values) in self.airframe.overrides() {
            let values: Vec<String> = values.iter().map(f64::to_string).collect();
            label += &format!("+{key}={}", values.join(","));
        }
        label
    }

    /// The `[airframe]` overrides by key, or `None` when there are none.
    #[must_use]
    pub fn airframe_overrides(&self) -> Option<BTreeMap<&'static str, OverrideValue>> {
        let overrides = self.airframe.overrides();
        (!overrides.is_empty()).then(|| {
            overrides
                .into_iter()
                .map(|(key, v)| (key, if let [x] = v[..] { OverrideValue::Scalar(x) } else { OverrideValue::Array(v) }))
                .collect()
        })
    }

    /// The reference modes a run of this scenario covers: each track mode, or one run otherwise.
    #[must_use]
    pub fn reference_modes(&self) -> Vec<ReferenceMode> {
        match &self.reference {
            ReferenceSpec::Track(track) => track.reference_modes.clone(),
            _ => vec![ReferenceMode::FeedForward],
        }
    }
}

/// The longest plant label a file name carries whole (bytes). A run's file name adds at most about 60
/// more (controller, reference mode, seed, rate, kind and extension), well within the 255 bytes a file
/// name may have.
pub const FILE_LABEL_MAX_LEN: usize = 64;

/// A plant label ([`Scenario::plant_label`]) as it goes into a file name: the label itself when it is at
/// most [`FILE_LABEL_MAX_LEN`] bytes, else its preset, `+`, and eight hex digits of a hash of the whole
/// label (64-bit FNV-1a, folded to 32 bits), so distinct overrides keep distinct files. The whole label
/// stays in the JSON metrics and the figure titles.
#[must_use]
pub fn file_label(plant_label: &str) -> String {
    if plant_label.len() <= FILE_LABEL_MAX_LEN {
        return plant_label.to_owned();
    }
    let hash =
        plant_label.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    let preset = plant_label.split('+').next().unwrap_or(plant_label);
    let preset = if preset.len() > FILE_LABEL_MAX_LEN - 9 { &preset[..FILE_LABEL_MAX_LEN - 9] } else { preset };
    format!("{preset}+{:08x}", (hash >> 32) ^ (hash & 0xffff_ffff))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_scenario_parses_and_validates() {
        for (name, _) in BUILT_INS {
            let s = Scenario::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&s.name, name);
        }
    }

    #[test]
    fn given_an_unknown_name_then_the_error_lists_the_built_ins() {
        let e = Scenario::load("no-such-scenario").unwrap_err().to_string();
        assert!(e.contains("paper-attitude") && e.contains("figure8"), "{e}");
    }

    #[test]
    fn given_a_bad_file_then_the_error_names_the_field() {
        let text = "name = \"x\"\nduration_s = 5.0\nmetrics = [\"steps\"]\nbogus = 1\n[reference]\nkind = \"position\"\nsteps = [{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.0] }]\n";
        let e = Scenario::from_toml("x", text).unwrap_err().to_string();
        assert!(e.contains("bogus"), "{e}");
        let text = text.replace("bogus = 1\n", "").replace("duration_s = 5.0", "duration_s = -1.0");
        let e = Scenario::from_toml("x", &text).unwrap_err().to_string();
        assert!(e.contains("duration_s"), "{e}");
    }

    /// A valid hover with a gust, to break one key at a time.
    const HOVER: &str = "name = \"x\"\nduration_s = 10.0\nstate_noise = \"paper\"\nmetrics = [\"gust\"]\n\
                         [initial]\npos_ned_m = [0.0, 0.0, -1.0]\n\
                         [reference]\nkind = \"position\"\nsteps = [{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.0] }]\n\
                         [wind.gust]\namplitude_mps = 3.0\ndirection_ned = [0.0, 1.0, 0.0]\nonset_s = 2.0\n\
                         rise_s = 1.0\nrelease_s = 6.0\nfall_s = 1.0\n";

    #[test]
    fn given_each_new_key_with_a_bad_value_then_the_error_names_it() {
        let s = Scenario::from_toml("x", HOVER).unwrap();
        assert_eq!((s.state_noise_scale, s.ground, s.metric_windows), (1.0, true, MetricWindows::default()));
        let top = |line: &str| HOVER.replacen("metrics =", &format!("{line}\nmetrics ="), 1);
        let cases = [
            (top("state_noise_scale = -0.5"), "state_noise_scale"),
            (top("state_noise_scale = nan"), "state_noise_scale"),
            (top("state_noise_scale = 2.0").replace("\"paper\"", "\"none\""), "state_noise_scale"),
            (top("ground = \"no\""), "ground"),
            (
                HOVER.replace("pos_ned_m = [0.0, 0.0, -1.0]\n[reference]", "pos_ned_m = [0.0, 0.0, 0.5]\n[reference]"),
                "ground = false",
            ),
            (HOVER.replace("-1.0] }", "-1.0], vel_ned_mps = [nan, 0.0, 0.0] }"), "vel_ned_mps"),
            (HOVER.replace("-1.0] }", "-1.0], acc_ned_mps2 = [0.0, inf, 0.0] }"), "acc_ned_mps2"),
            (HOVER.replace("-1.0] }", "-1.0], vel_ned_mps = [1.0, 0.0] }"), "vel_ned_mps"),
            (format!("{HOVER}[metric_windows]\ngust_peak_s = [5.0, 1.0]\n"), "metric_windows.gust_peak_s"),
            (format!("{HOVER}[metric_windows]\ngust_rms_s = [11.0, 12.0]\n"), "metric_windows.gust_rms_s"),
            (format!("{HOVER}[metric_windows]\ngust_steady_s = 0.0\n"), "metric_windows.gust_steady_s"),
            (format!("{HOVER}[metric_windows]\nstep_sse_s = 1.0\n"), "needs the steps metric"),
            (format!("{HOVER}[metric_windows]\npeak_s = [0.0, 1.0]\n"), "peak_s"),
        ];
        for (text, needle) in &cases {
            let e = match Scenario::from_toml("x", text) {
                Ok(_) => panic!("{needle}: accepted"),
                Err(e) => e.to_string(),
            };
            assert!(e.contains(needle), "{needle}: {e}");
        }
        // Below the ground is fine without one.
        let below = top("ground = false")
            .replace("pos_ned_m = [0.0, 0.0, -1.0]\n[reference]", "pos_ned_m = [0.0, 0.0, 0.5]\n[reference]");
        assert!(!Scenario::from_toml("x", &below).unwrap().ground);
    }

    #[test]
    fn given_a_track_path_key_then_spline_is_the_default_and_others_are_refused() {
        let track = BUILT_INS.iter().find(|b| b.0 == "figure8").unwrap().1;
        let spec = |s: &Scenario| match &s.reference {
            ReferenceSpec::Track(t) => t.path,
            _ => unreachable!(),
        };
        assert_eq!(spec(&Scenario::from_toml("f", track).unwrap()), PathKind::Spline);
        let poly = track.replace("kind = \"track\"", "kind = \"track\"\npath = \"polyline\"");
        assert_eq!(spec(&Scenario::from_toml("f", &poly).unwrap()), PathKind::Polyline);
        let e = Scenario::from_toml("f", &poly.replace("polyline", "bezier")).unwrap_err().to_string();
        assert!(e.contains("path") && e.contains("polyline"), "{e}");
    }

    #[test]
    fn given_corners_or_pulses_without_what_they_judge_then_the_scenario_is_refused() {
        let figure8 = BUILT_INS.iter().find(|b| b.0 == "paper-flight-figure8").unwrap().1;
        let e = Scenario::from_toml("f", &figure8.replace("path = \"polyline\"\n", "")).unwrap_err().to_string();
        assert!(e.contains("corners") && e.contains("polyline"), "{e}");
        let e = Scenario::from_toml("f", &figure8.replace("[\"track\", \"corners\"]", "[\"corners\"]")).unwrap_err();
        assert!(e.to_string().contains("track"), "{e}");
        let hover = BUILT_INS.iter().find(|b| b.0 == "paper-flight-hover").unwrap().1;
        let calm = hover.split("[wind.pulses]").next().unwrap();
        let e = Scenario::from_toml("h", calm).unwrap_err().to_string();
        assert!(e.contains("[wind.pulses]"), "{e}");
        let s = Scenario::from_toml("h", hover).unwrap();
        assert_eq!((s.ground, s.initial.pos_ned_m[2]), (true, 0.0), "the hover rises from the ground");
    }

    #[test]
    fn given_no_overrides_then_the_label_is_the_preset() {
        let s = Scenario::load("gust-hover").unwrap();
        assert_eq!((s.plant_label(None), s.plant_label(Some("nominal"))), ("mismatch".into(), "nominal".into()));
        assert!(s.airframe_overrides().is_none());
        let mut s = s;
        s.airframe.disturbance_torque_frd_nm = Some([0.1, 0.0, -0.05]);
        s.airframe.motor_tau_s = Some(0.06);
        assert_eq!(s.plant_label(None), "mismatch+motor_tau_s=0.06+disturbance_torque_frd_nm=0.1,0,-0.05");
        let o = s.airframe_overrides().unwrap();
        assert_eq!(o["motor_tau_s"], OverrideValue::Scalar(0.06));
        assert_eq!(o["disturbance_torque_frd_nm"], OverrideValue::Array(vec![0.1, 0.0, -0.05]));
    }

    #[test]
    fn given_a_label_over_64_bytes_then_its_file_label_is_the_preset_and_a_hash_of_at_most_64_bytes() {
        assert_eq!(file_label("mismatch+mass_kg=5.3"), "mismatch+mass_kg=5.3");
        let long = format!("mismatch+inertia_kgm2={}+mass_kg=5.2512345", ["0.081234567"; 3].join(","));
        let long2 = long.replace("0.081234567", "0.081234568");
        assert!(long.len() > FILE_LABEL_MAX_LEN);
        let (a, b) = (file_label(&long), file_label(&long2));
        assert!(a.starts_with("mismatch+") && a.len() == "mismatch+".len() + 8, "{a}");
        assert_ne!(a, b, "distinct overrides, distinct files");
        assert_eq!(a, file_label(&long), "the same label, the same file");
        assert!(file_label(&"x".repeat(300)).len() <= FILE_LABEL_MAX_LEN);
    }
}
