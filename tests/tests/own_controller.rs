//! A controller of the test's own, defined in this file and registered at run time, flown through the
//! scenario runner, a sweep and a short `sitl tune`: a researcher's controller needs no edit of the
//! autopilot. The law is a small PD: position to a thrust vector (the shared limiter and attitude
//! extraction), attitude PD to the moments (the shared distributor and lift curve).

use std::sync::OnceLock;

use autopilot::core::control::distributor::{self, ActuatorLimits};
use autopilot::core::control::{
    Airframe, ConfigError, ControlInput, Controller, ControllerConfig, ControllerKind, ControllerType, GainScale,
    HeldOutput, Reference, TunableGain, attitude_setpoint_rad, commanded_collective_n, inputs_finite, registry,
};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use sitl::scenario::Scenario;
use sitl::scenario::runner::{RunOptions, run};
use sitl::sweep::Sweep;
use sitl::tune::Tune;

/// The PD's gains, its `[controller.pd_hover]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct PdConfig {
    /// Position gain (m/s² per m).
    kp_pos_per_s2: f64,
    /// Velocity gain (m/s² per m/s).
    kd_vel_per_s: f64,
    /// Attitude gain (rad/s² per rad).
    kp_att_per_s2: f64,
    /// Body-rate damping (rad/s² per rad/s).
    kd_rate_per_s: f64,
}

impl Default for PdConfig {
    fn default() -> Self {
        Self { kp_pos_per_s2: 2.0, kd_vel_per_s: 2.6, kp_att_per_s2: 25.0, kd_rate_per_s: 8.0 }
    }
}

struct PdHover {
    cfg: PdConfig,
    airframe: Airframe,
    limits: ActuatorLimits,
    held: HeldOutput,
    attitude_sp_rad: Vector3<f64>,
}

impl Controller for PdHover {
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4] {
        if !inputs_finite(input, reference) {
            return self.held.pwm_us;
        }
        let (c, a) = (&self.cfg, &self.airframe);
        let acc = (reference.pos_ned_m - input.pos_ned_m) * c.kp_pos_per_s2
            + (reference.vel_ned_mps - input.vel_ned_mps) * c.kd_vel_per_s
            + reference.acc_ned_mps2;
        let force = (acc - Vector3::new(0.0, 0.0, a.gravity_mps2)) * a.mass_kg;
        let limited = distributor::limit_thrust_vector(&force, &self.limits);
        self.attitude_sp_rad = attitude_setpoint_rad(reference, &limited);
        let collective = commanded_collective_n(reference, limited.vertical_n, &input.euler_rad, &self.limits, true);
        let mut e = self.attitude_sp_rad - input.euler_rad;
        e.z = (e.z + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        let alpha = e * c.kp_att_per_s2 - input.rate_frd_radps * c.kd_rate_per_s;
        let moment = a.inertia().component_mul(&alpha);
        self.held.distribute(collective, &moment, a, &self.limits);
        self.held.pwm_us
    }

    fn reconfigure(&mut self, config: &ControllerConfig) {
        if let Ok(cfg) = config.section::<PdConfig>("pd_hover") {
            self.cfg = cfg;
        }
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::of(&PD_HOVER)
    }

    fn telemetry(&self) -> Vec<(&'static str, f64)> {
        vec![("pd_hover.roll_sp_rad", self.attitude_sp_rad.x), ("pd_hover.pitch_sp_rad", self.attitude_sp_rad.y)]
    }

    fn weights_at_bounds(&self) -> bool {
        false
    }

    fn attitude_setpoint_rad(&self) -> Vector3<f64> {
        self.attitude_sp_rad
    }
}

struct PdHoverType;

static PD_HOVER: PdHoverType = PdHoverType;

impl ControllerType for PdHoverType {
    fn name(&self) -> &'static str {
        "pd_hover"
    }
    fn summary(&self) -> &'static str {
        "a PD hover law defined in tests/tests/own_controller.rs"
    }
    fn default_table(&self) -> toml::Table {
        toml::Table::try_from(PdConfig::default()).expect("a table")
    }
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError> {
        let c: PdConfig = config.section("pd_hover")?;
        for (field, value) in [
            ("kp_pos_per_s2", c.kp_pos_per_s2),
            ("kd_vel_per_s", c.kd_vel_per_s),
            ("kp_att_per_s2", c.kp_att_per_s2),
            ("kd_rate_per_s", c.kd_rate_per_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError::NotPositive { name: "pd_hover", field, value });
            }
        }
        Ok(())
    }
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
        let airframe = Airframe::default();
        Ok(Box::new(PdHover {
            cfg: config.section("pd_hover")?,
            airframe,
            limits: ActuatorLimits::default(),
            held: HeldOutput::hover(&airframe),
            attitude_sp_rad: Vector3::zeros(),
        }))
    }
    fn gains(&self) -> &'static [TunableGain] {
        &[
            TunableGain { name: "pd_hover.kp_pos_per_s2", axes: &[], bounds: [0.3, 4.0], scale: GainScale::Log },
            TunableGain { name: "pd_hover.kd_vel_per_s", axes: &[], bounds: [0.5, 5.0], scale: GainScale::Log },
        ]
    }
}

/// Registered once per test binary (the tests run in parallel threads).
fn pd_hover() -> ControllerKind {
    static KIND: OnceLock<ControllerKind> = OnceLock::new();
    *KIND.get_or_init(|| registry::register(&PD_HOVER).expect("pd_hover registers"))
}

#[test]
fn given_a_test_local_controller_when_registered_then_it_is_found_by_name_and_a_second_registration_is_refused() {
    let kind = pd_hover();
    assert_eq!("pd_hover".parse::<ControllerKind>(), Ok(kind));
    assert!(registry::names().ends_with("pd_hover"), "{}", registry::names());
    assert_eq!(
        registry::register(&PD_HOVER).map(|k| k.to_string()),
        Err(registry::RegistryError::Duplicate("pd_hover".into()))
    );
    assert_eq!(registry::check(), Ok(()));
    // Its table is checked by its own rules, and a table no controller owns is refused.
    let mut config = ControllerConfig::default();
    config.set_section("pd_hover", &PdConfig { kd_vel_per_s: -1.0, ..PdConfig::default() }).expect("a table");
    assert!(config.validate().is_err_and(|e| e.to_string().contains("kd_vel_per_s")));
    let mut stray = ControllerConfig::default();
    stray.tables.insert("pd_hoover".into(), toml::Table::new());
    assert!(stray.validate().is_err_and(|e| e.to_string().contains("pd_hoover")));
}

#[test]
fn given_a_test_local_controller_when_flown_on_gust_hover_by_the_runner_and_a_sweep_then_it_holds_its_point() {
    let kind = pd_hover();
    let scenario = Scenario::load("gust-hover").expect("built in");
    let out = run(&scenario, &RunOptions::new(kind)).expect("flies");
    let gust = out.metrics.gust.as_ref().expect("gust metrics");
    println!("pd_hover on gust-hover: peak {:.3} m, steady error {:.3} m", gust.peak_m, gust.steady_err_m);
    assert!(!out.metrics.non_finite);
    assert!(gust.peak_m < 1.0, "peak {} m", gust.peak_m);
    assert_eq!(out.metrics.controller, "pd_hover");
    // A sweep by name, with gust speeds drawn.
    let spec = r#"
name = "own"
scenario = "gust-hover"
controllers = ["pd_hover"]
samples = 2
seed = 1
[vary]
gust_amplitude_mps = { uniform = [2.0, 6.0] }
"#;
    let sweep = Sweep::from_toml(spec, scenario).expect("a sweep of pd_hover");
    assert_eq!(sweep.controllers, vec![kind]);
    for i in 0..sweep.runs() {
        let row = sweep.run(i).expect("a row");
        assert_eq!(row.controller, kind);
    }
}

#[test]
fn given_a_test_local_controller_when_tuned_for_20_evaluations_then_its_declared_gains_are_searched() {
    pd_hover();
    let spec = r#"
name = "own"
controller = "pd_hover"
budget = 20
seed = 3
[optimizer]
population = 5
[[train]]
scenario = "gust-hover"
cost = { gust_peak_m = 10.0, gust_iae_release_m_s = 1.0 }
"#;
    let tune = Tune::from_toml(spec, std::path::Path::new("."), "spec").expect("a tuning of pd_hover");
    let labels: Vec<&str> = tune.gains.iter().map(|g| g.label.as_str()).collect();
    assert_eq!(labels, ["pd_hover.kp_pos_per_s2", "pd_hover.kd_vel_per_s"]);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool");
    let tuning = tune.run(&pool, |_| {});
    let outcome = &tuning.outcomes[0];
    assert_eq!(outcome.evaluations.len(), 20);
    let (start, best) = (outcome.start().verdict.penalised, outcome.result().verdict.penalised);
    println!("pd_hover tune: start cost {start:.4}, best {best:.4} after 20 evaluations");
    assert!(best <= start, "the search keeps the start when it finds nothing better");
}
