//! The paper's experiments as scenario files: a TOML format, the built-in scenarios, an in-process
//! lockstep runner (plant + controller on simulated time, no sockets), metrics and plots.
//!
//! A scenario file (all lengths m, angles rad, times s; NED/FRD):
//! ```toml
//! name = "paper-attitude"
//! description = "..."
//! duration_s = 16.0
//! plant = "nominal"               # airframe preset; `--plant` overrides it
//! state_noise = "none"            # "none" | "paper": white noise on the state the controller sees
//! metrics = ["steps"]             # any of "steps", "gust", "track"
//! controllers = ["aco", "ca", "pid"]  # the default set when `--controller` is not given
//! [initial]                       # optional; at rest at the origin with hover lift by default
//! pos_ned_m = [0.0, 0.0, -3.0]
//! euler_rad = [0.4, -0.5, -0.4]
//! [reference]                     # kind = "attitude" | "position" | "track" (see `reference`)
//! kind = "attitude"
//! pos_d_m = -3.0
//! steps = [{ t_s = 0.0, euler_rad = [0.0, 0.0, 0.0] }]
//! [airframe]                      # optional overrides of the preset's values (e.g. mass_kg = 5.3)
//! [wind]                          # optional: gust, turbulence, steady wind (the plant's WindConfig)
//! [controller]                    # optional overrides of the controllers' configuration
//! ```

pub mod gcs;
pub mod metrics;
pub mod path;
pub mod plot;
pub mod reference;
pub mod runner;
pub mod two_process;

use std::path::Path;

use autopilot::core::control::{ControllerConfig, ControllerKind};
use serde::{Deserialize, Serialize};

use crate::plant::{AirframeConfig, WindConfig};
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
    pub metrics: Vec<MetricKind>,
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
}

fn default_plant() -> String {
    "nominal".to_owned()
}

fn default_controllers() -> Vec<ControllerKind> {
    vec![ControllerKind::Aco, ControllerKind::Ca, ControllerKind::Pid]
}

/// The built-in scenarios, one per experiment of the paper (plus the turbulence variant).
pub const BUILT_INS: &[(&str, &str)] = &[
    ("paper-attitude", include_str!("../../scenarios/paper-attitude.toml")),
    ("paper-translation", include_str!("../../scenarios/paper-translation.toml")),
    ("gust-hover", include_str!("../../scenarios/gust-hover.toml")),
    ("turbulence-hover", include_str!("../../scenarios/turbulence-hover.toml")),
    ("figure8", include_str!("../../scenarios/figure8.toml")),
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
            return Err(ScenarioError::Invalid("metrics must name at least one of steps, gust, track".into()));
        }
        self.reference.validate()?;
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
        if self.metrics.contains(&MetricKind::Gust) && self.wind.gust.is_none() {
            return Err(ScenarioError::Invalid("the gust metric needs a [wind.gust]".into()));
        }
        let init = &self.initial;
        if [init.pos_ned_m, init.vel_ned_mps, init.euler_rad, init.rate_frd_radps]
            .iter()
            .flatten()
            .any(|v| !v.is_finite())
        {
            return Err(ScenarioError::Invalid("initial state must be finite".into()));
        }
        Ok(())
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
}
