//! The environment's configuration ([`EnvConfig`]), its named choices (task, action mode, observation,
//! track path) and what it resolves to once validated ([`Prepared`]).

use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

use autopilot::core::control::{ControllerConfig, ControllerKind, LoopRates};

use super::GymError;
use crate::scenario::{ReferenceSpec, Scenario};
use crate::sweep::{Distribution, Param, Sweep};

/// The plant's inner rate (Hz): the controller's inner loop and one plant step per tick, as the runner.
pub const INNER_HZ: u32 = 500;
/// One inner tick (µs).
pub const INNER_DT_US: u64 = 1_000_000 / INNER_HZ as u64;
/// How far ahead the track observation looks (s).
pub const LOOKAHEAD_S: f64 = 0.5;

macro_rules! named_enum {
    ($(#[$doc:meta])* $name:ident, $what:literal, { $($(#[$vdoc:meta])* $variant:ident => $text:literal),+ $(,)? }) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name {
            $($(#[$vdoc])* $variant),+
        }

        impl $name {
            /// Every value with its name.
            pub const ALL: &'static [(Self, &'static str)] = &[$((Self::$variant, $text)),+];

            /// The name `FromStr` reads.
            #[must_use]
            pub fn as_str(self) -> &'static str {
                match self {
                    $(Self::$variant => $text),+
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl FromStr for $name {
            type Err = GymError;

            fn from_str(s: &str) -> Result<Self, GymError> {
                Self::ALL.iter().find(|(_, n)| *n == s).map(|(v, _)| *v).ok_or_else(|| GymError::UnknownName {
                    what: $what,
                    name: s.to_owned(),
                    known: Self::ALL.iter().map(|(_, n)| *n).collect::<Vec<_>>().join(", "),
                })
            }
        }
    };
}

named_enum!(
    /// What the vehicle is asked to do.
    Task, "task", {
        /// Hover-v0: hold a point at 1.5 m under wind, a gust and turbulence.
        Hover => "hover",
        /// Track-v0: follow a moving reference along a closed path.
        Track => "track",
    }
);

named_enum!(
    /// What an action is (every mode has four values).
    ActionMode, "action mode", {
        /// Four rotor commands in [0, 1]: PWM 1000 + 1000 a µs, rotors numbered as the plant's.
        Motors => "motors",
        /// Collective thrust [0, 1] and body rates p, q, r (FRD rad/s) for the controller's rate loop.
        Ctbr => "ctbr",
        /// Collective thrust [0, 1], roll, pitch and yaw (rad) for the controller's attitude loop.
        Attitude => "attitude",
        /// Velocity vN, vE, vD (m/s) and yaw rate (rad/s) for the controller's position loop.
        Velocity => "velocity",
    }
);

named_enum!(
    /// Which state the observation is made of.
    Observe, "observation", {
        /// The plant's true state.
        Truth => "truth",
        /// The noisy state the scenario's `state_noise` gives: what the controller sees.
        Estimate => "estimate",
    }
);

named_enum!(
    /// Which path the track task follows.
    TrackPath, "track path", {
        /// The built-in `figure8` scenario's track, with feed-forward.
        Figure8 => "figure8",
        /// A random smooth closed path drawn per reset.
        Random => "random",
    }
);

/// Everything that defines a batch of environments. [`EnvConfig::new`] gives the documented defaults.
#[derive(Clone, Debug)]
pub struct EnvConfig {
    pub task: Task,
    pub action: ActionMode,
    pub observe: Observe,
    /// Flies the ctbr, attitude and velocity actions (unused by `motors`); default ACO.
    pub controller: ControllerKind,
    /// Policy steps per simulated second; must divide the 500 Hz inner rate. Default 100.
    pub policy_hz: u32,
    /// Truncation time (s). Hover: 10. Track: 36, the figure-8 scenario's; a random path's episode also
    /// ends 2 s after its reference comes to rest (at most ~34 s).
    pub episode_s: f64,
    /// Track only.
    pub track_path: TrackPath,
    /// Drawn per reset with the sweep's distributions and applied as the sweep applies them
    /// (`choice`, `uniform` and `scale`; a `values` grid has no meaning here and is refused).
    pub randomize: Vec<(Param, Distribution)>,
    /// Start offset (±0.5 m per axis), attitude (±0.2 rad per Euler angle) and velocity (±0.3 m/s per
    /// axis) drawn per reset; default true.
    pub randomize_start: bool,
    /// The base scenario; `None` = the task's default (`gust-hover` or `figure8`).
    pub scenario: Option<Scenario>,
}

/// The default per-reset randomization of a task (see the module documentation).
#[must_use]
pub fn default_randomize(task: Task) -> Vec<(Param, Distribution)> {
    use Distribution::{Scale, Uniform};
    // The paper's rotors lift 11.3-14.5 N each: the mismatch plant (5.4 kg) hovers at 13.2 N, so its
    // mass may not grow by more than a few per cent and keep room to climb and steer.
    let mut v = vec![
        (Param::MassKg, Scale([0.93, 1.02])),
        (Param::InertiaKgm2, Scale([0.8, 1.2])),
        (Param::WindAzimuthDeg, Uniform([0.0, 360.0])),
    ];
    match task {
        Task::Hover => v.extend([
            (Param::WindSpeedMps, Uniform([0.0, 3.0])),
            (Param::GustAmplitudeMps, Uniform([0.0, 7.9])),
            (Param::GustAzimuthDeg, Uniform([0.0, 360.0])),
            (Param::TurbulenceScale, Uniform([0.0, 0.5])),
        ]),
        Task::Track => {
            v.extend([(Param::WindSpeedMps, Uniform([0.0, 2.0])), (Param::TurbulenceScale, Uniform([0.0, 0.3]))])
        }
    }
    v
}

impl EnvConfig {
    /// The defaults: truth observations, ACO, 100 Hz, the task's episode length, figure-8, the task's
    /// default randomization, randomized start, the task's default scenario.
    #[must_use]
    pub fn new(task: Task, action: ActionMode) -> Self {
        Self {
            task,
            action,
            observe: Observe::Truth,
            controller: ControllerKind::ACO,
            policy_hz: 100,
            episode_s: match task {
                Task::Hover => 10.0,
                Task::Track => 36.0,
            },
            track_path: TrackPath::Figure8,
            randomize: default_randomize(task),
            randomize_start: true,
            scenario: None,
        }
    }

    /// Checks everything a reset will need, by resolving it once.
    ///
    /// # Errors
    /// A rate that does not divide 500 Hz, a non-positive episode, `ctbr` with a controller without a
    /// rate loop, a scenario the task cannot fly, or a randomization the sweep refuses.
    pub fn validate(&self) -> Result<(), GymError> {
        Prepared::new(self).map(|_| ())
    }

    /// 13 for hover, 19 for track (see the module documentation).
    #[must_use]
    pub fn obs_dim(&self) -> usize {
        match self.task {
            Task::Hover => 13,
            Task::Track => 19,
        }
    }

    /// 4 in every mode.
    #[must_use]
    pub fn action_dim(&self) -> usize {
        4
    }

    #[must_use]
    pub fn action_low(&self) -> [f32; 4] {
        use std::f32::consts::PI;
        match self.action {
            ActionMode::Motors => [0.0; 4],
            ActionMode::Ctbr => [0.0, -PI, -PI, -1.4],
            ActionMode::Attitude => [0.0, -0.6, -0.6, -PI],
            ActionMode::Velocity => [-3.0, -3.0, -2.0, -1.4],
        }
    }

    #[must_use]
    pub fn action_high(&self) -> [f32; 4] {
        let low = self.action_low();
        match self.action {
            ActionMode::Motors => [1.0; 4],
            ActionMode::Ctbr | ActionMode::Attitude => [1.0, -low[1], -low[2], -low[3]],
            ActionMode::Velocity => low.map(|x| -x),
        }
    }

    /// The observation's components by index.
    #[must_use]
    pub fn obs_names(&self) -> Vec<&'static str> {
        let mut names = vec![
            "dp_n", "dp_e", "dp_d", "dv_n", "dv_e", "dv_d", "q_w", "q_x", "q_y", "q_z", "rate_p", "rate_q", "rate_r",
        ];
        if self.task == Task::Track {
            names.extend(["vref_n", "vref_e", "vref_d", "ahead_n", "ahead_e", "ahead_d"]);
        }
        names
    }
}

/// A validated configuration, resolved for resets.
#[derive(Debug, Clone)]
pub(super) struct Prepared {
    pub config: EnvConfig,
    /// The base scenario with the randomization as a one-case sweep: a reset sets its seed and takes
    /// case 0 (the sweep's own draws and `apply`).
    pub sweep: Sweep,
    pub controller_config: ControllerConfig,
    pub ticks_per_step: u32,
    /// The default hover scenario: its gust's timing is drawn per reset.
    pub random_gust_timing: bool,
    pub low: [f32; 4],
    pub high: [f32; 4],
    /// The figure-8's path, built once for every env.
    pub shared_path: Option<Arc<crate::scenario::reference::TrackPath>>,
}

impl Prepared {
    pub fn new(config: &EnvConfig) -> Result<Self, GymError> {
        let invalid = |m: String| Err(GymError::Config(m));
        let hz = config.policy_hz;
        if hz == 0 || !INNER_HZ.is_multiple_of(hz) {
            return invalid(format!("policy_hz = {hz} must divide the {INNER_HZ} Hz inner rate"));
        }
        if !(config.episode_s.is_finite() && config.episode_s > 0.0 && config.episode_s <= 3600.0) {
            return invalid(format!("episode_s = {} must be in (0, 3600]", config.episode_s));
        }
        if config.action == ActionMode::Ctbr && !config.controller.flies_rates() {
            return Err(GymError::NoRateLoop { controller: config.controller.to_string() });
        }
        let scenario = match &config.scenario {
            Some(s) => s.clone(),
            None => Scenario::load(match config.task {
                Task::Hover => "gust-hover",
                Task::Track => "figure8",
            })?,
        };
        match (config.task, &scenario.reference) {
            (Task::Hover, ReferenceSpec::Position { .. }) | (Task::Track, ReferenceSpec::Track(_)) => {}
            (task, _) => {
                return invalid(format!(
                    "the {task} task needs a scenario with a {} reference; `{}` has another",
                    if task == Task::Hover { "position" } else { "track" },
                    scenario.name
                ));
            }
        }
        if !scenario.events.is_empty() || !scenario.rc.is_empty() || scenario.manual.is_some() {
            return invalid(format!(
                "scenario `{}` has [[event]], [[rc]] or [manual]: the environment flies none of them",
                scenario.name
            ));
        }
        let mut vary = String::new();
        for (param, dist) in &config.randomize {
            let list = |v: &[f64]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
            let text = match dist {
                Distribution::Uniform(r) => format!("uniform = [{}]", list(r)),
                Distribution::Scale(r) => format!("scale = [{}]", list(r)),
                Distribution::Choice(v) => format!("choice = [{}]", list(v)),
                Distribution::Values(_) => {
                    return invalid(format!("randomize {}: `values` is a sweep's grid; use `choice`", param.name()));
                }
            };
            let (r, c) = match dist {
                Distribution::Uniform(r) | Distribution::Scale(r) => (r.as_slice(), false),
                Distribution::Choice(v) | Distribution::Values(v) => (v.as_slice(), true),
            };
            if r.iter().any(|x| !x.is_finite()) || (c && r.is_empty()) {
                return invalid(format!("randomize {}: values must be finite", param.name()));
            }
            if vary.contains(&format!("\n{} =", param.name())) {
                return invalid(format!("randomize names {} twice", param.name()));
            }
            vary += &format!("\n{} = {{ {text} }}", param.name());
        }
        let spec = format!("name = \"gym\"\nscenario = \"gym\"\nseed = 0\n[vary]{vary}\n");
        let sweep = Sweep::from_toml(&spec, scenario).map_err(|e| GymError::Config(format!("randomize: {e}")))?;
        let mut controller_config = sweep.scenario.controller.clone();
        controller_config.rates = LoopRates::default();
        autopilot::core::control::try_new_controller(config.controller, &controller_config)
            .map_err(|e| GymError::Config(format!("controller {}: {e}", config.controller)))?;
        let shared_path = match (&sweep.scenario.reference, config.track_path) {
            (ReferenceSpec::Track(spec), TrackPath::Figure8) => Some(super::track::Track::path(spec)),
            _ => None,
        };
        Ok(Self {
            shared_path,
            config: config.clone(),
            random_gust_timing: config.task == Task::Hover
                && config.scenario.is_none()
                && sweep.scenario.wind.gust.is_some(),
            sweep,
            controller_config,
            ticks_per_step: INNER_HZ / hz,
            low: config.action_low(),
            high: config.action_high(),
        })
    }
}
