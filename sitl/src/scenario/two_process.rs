//! A scenario flown through the whole stack: the plant served over UDP in lockstep to the real
//! `autopilot` process (`sitl run --scenario`), rather than the in-process runner's controller. In: a
//! hover scenario (a position reference with one step: `gust-hover`, `turbulence-hover`), the controller,
//! seed and instance. Out: the scenario's metrics from the plant's truth, sampled at every plant step as
//! the in-process runner samples it, so the two can be compared number for number.
//!
//! The autopilot is configured to start as the runner does: in the air at the scenario's initial point,
//! armed and holding the reference (`start_airborne`), truth-fed (the plant's truth in
//! `HIL_STATE_QUATERNION`, with the scenario's state noise added by the plant) and with the plant's home as
//! its truth origin, so its NED frame is the plant's. It runs the vehicle core's commander, MAVLink
//! services and telemetry as in any flight.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::vehicle::{AirborneStart, VehicleConfig};
use nalgebra::Vector3;
use serde::Serialize;

use super::metrics::{self, GustMetrics};
use super::reference::ReferenceSpec;
use super::runner::plant_config;
use super::{Scenario, ScenarioError, StateNoiseKind};
use crate::launch::{AutopilotChild, LaunchError, LaunchReport, run_with_child};
use crate::link::{LinkConfig, PlantServer, home_origin};
use crate::plant::{InitialState, Plant, StateNoise};

/// Why a two-process scenario run failed.
#[derive(Debug, thiserror::Error)]
pub enum TwoProcessError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(
        "scenario {0}: only hover scenarios (a position reference with one step, e.g. gust-hover, \
         turbulence-hover) fly through two processes"
    )]
    NotHover(String),
    #[error("cannot write the autopilot configuration {path}: {source}")]
    Config {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot bind the plant on {addr}: {source}")]
    Bind {
        addr: String,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Launch(#[from] LaunchError),
    #[error("stopped before the scenario's end ({0:.1} of its simulated seconds)")]
    Stopped(f64),
}

/// What varies between two-process runs.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoProcessOptions {
    pub controller: ControllerKind,
    /// Airframe preset; `None` keeps the scenario's.
    pub plant: Option<String>,
    pub seed: u64,
    pub instance: u16,
    /// The autopilot's estimator (truth by default, as the paper's runs).
    pub estimator: EstimatorSource,
    /// Extra autopilot arguments (e.g. `--log-dir`).
    pub autopilot_args: Vec<OsString>,
}

/// The metrics of a two-process run (the JSON `sitl run --scenario --json` prints).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwoProcessMetrics {
    pub scenario: String,
    pub controller: String,
    pub plant: String,
    pub seed: u64,
    pub estimator: String,
    pub processes: u8,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gust: Option<GustMetrics>,
    pub non_finite: bool,
    /// Mean |PWM change| per tick over the run and rotors (µs), from the commands the plant applied.
    pub pwm_activity_us: f64,
    pub steps: u64,
    pub sim_s: f64,
    pub wall_s: f64,
    pub realtime_factor: f64,
    /// Sensor datagrams the plant had to resend (0 in a healthy lockstep run).
    pub resends: u64,
}

/// The autopilot configuration file (TOML) for a run of `scenario`.
///
/// # Errors
/// [`TwoProcessError::NotHover`] when the scenario is not a hover.
pub fn autopilot_config(
    scenario: &Scenario,
    opts: &TwoProcessOptions,
    plant: &Plant,
) -> Result<String, TwoProcessError> {
    let ReferenceSpec::Position { steps } = &scenario.reference else {
        return Err(TwoProcessError::NotHover(scenario.name.clone()));
    };
    let [hold] = steps.as_slice() else { return Err(TwoProcessError::NotHover(scenario.name.clone())) };
    let mut vehicle = VehicleConfig {
        controller: opts.controller,
        control: scenario.controller.clone(),
        start_airborne: Some(AirborneStart { hold_ned_m: hold.pos_ned_m, yaw_rad: hold.yaw_rad }),
        ..VehicleConfig::default()
    };
    vehicle.estimator.source = opts.estimator;
    vehicle.estimator.truth_origin = Some(home_origin(&plant.config().sensors.home));
    #[derive(Serialize)]
    struct File<'a> {
        vehicle: &'a VehicleConfig,
    }
    toml::to_string(&File { vehicle: &vehicle })
        .map_err(|e| TwoProcessError::Config { path: PathBuf::from("(memory)"), source: std::io::Error::other(e) })
}

/// Per-axis series of one run, sampled before every plant step.
#[derive(Debug, Default)]
struct Recorded {
    t: Vec<f64>,
    pos: [Vec<f64>; 3],
    ref_pos: [Vec<f64>; 3],
    non_finite: bool,
    last_pwm: Option<[f64; 4]>,
    pwm_change_sum: f64,
    ticks: u64,
}

impl Recorded {
    fn sample(&mut self, t_s: f64, pos_ned_m: &Vector3<f64>, ref_ned_m: &[f64; 3]) {
        self.non_finite |= !pos_ned_m.iter().all(|v| v.is_finite());
        self.t.push(t_s);
        for axis in 0..3 {
            self.pos[axis].push(pos_ned_m[axis]);
            self.ref_pos[axis].push(ref_ned_m[axis]);
        }
    }
}

/// Fly `scenario` through the plant server and the `autopilot` binary at `autopilot`.
///
/// # Errors
/// [`TwoProcessError`]: not a hover scenario, a bad plant, a port in use, the autopilot failing, or
/// `stop` set before the end.
pub fn run(
    scenario: &Scenario,
    opts: &TwoProcessOptions,
    autopilot: &Path,
    stop: &AtomicBool,
) -> Result<TwoProcessMetrics, TwoProcessError> {
    let ReferenceSpec::Position { steps } = &scenario.reference else {
        return Err(TwoProcessError::NotHover(scenario.name.clone()));
    };
    let hold = steps[0].pos_ned_m;
    let config = plant_config(scenario, opts.plant.as_deref())?;
    let init = &scenario.initial;
    let initial = InitialState {
        pos_ned_m: Vector3::from(init.pos_ned_m),
        vel_ned_mps: Vector3::from(init.vel_ned_mps),
        euler_rad: Vector3::from(init.euler_rad),
        rate_frd_radps: Vector3::from(init.rate_frd_radps),
        rotor_lift_n: None,
    };
    let plant = Plant::new(config, &initial, opts.seed).map_err(ScenarioError::from)?;
    let config_text = autopilot_config(scenario, opts, &plant)?;
    let config_path =
        std::env::temp_dir().join(format!("sitl-{}-i{}-autopilot.toml", std::process::id(), opts.instance));
    std::fs::write(&config_path, config_text)
        .map_err(|source| TwoProcessError::Config { path: config_path.clone(), source })?;

    let truth_noise = match scenario.state_noise {
        StateNoiseKind::None => None,
        StateNoiseKind::Paper => Some(StateNoise::paper()),
    };
    let link = LinkConfig {
        truth_noise,
        truth_odometry: true,
        connect_timeout: Some(std::time::Duration::from_secs(30)),
        ..LinkConfig::default()
    };
    let port = 4560 + opts.instance;
    let addr = format!("127.0.0.1:{port}");
    let mut server = PlantServer::bind_udp(plant, addr.as_str(), link)
        .map_err(|source| TwoProcessError::Bind { addr: addr.clone(), source })?;
    let mut args: Vec<OsString> =
        vec!["--plant".into(), format!("udp://{addr}").into(), "-i".into(), opts.instance.to_string().into()];
    args.push("--config".into());
    args.push(config_path.clone().into());
    args.extend(opts.autopilot_args.iter().cloned());
    let child = AutopilotChild::spawn(autopilot, &args);
    let duration_us = (scenario.duration_s * 1e6).round() as u64;
    let mut rec = Recorded::default();
    rec.sample(0.0, &server.plant().truth().pos_ned_m, &hold);
    let report = child.and_then(|child| {
        run_with_child(&mut server, child, Some(duration_us), stop, |plant, cmd| {
            let pwm = cmd.effective_pwm_us();
            rec.non_finite |= !pwm.iter().all(|p| p.is_finite());
            if let Some(prev) = rec.last_pwm {
                rec.pwm_change_sum += prev.iter().zip(&pwm).map(|(a, b)| (a - b).abs()).sum::<f64>() / 4.0;
            }
            rec.last_pwm = Some(pwm);
            rec.ticks += 1;
            let t_us = plant.time_us();
            if t_us < duration_us {
                rec.sample(t_us as f64 * 1e-6, &plant.truth().pos_ned_m, &hold);
            }
        })
    });
    let _ = std::fs::remove_file(&config_path);
    let report: LaunchReport = report?;
    if report.stopped {
        return Err(TwoProcessError::Stopped(report.sim_s));
    }
    let gust = scenario
        .wind
        .gust
        .as_ref()
        .map(|g| metrics::hover_gust_metrics(&rec.t, &rec.pos, &rec.ref_pos, g.onset_s, g.release_s));
    Ok(TwoProcessMetrics {
        scenario: scenario.name.clone(),
        controller: opts.controller.to_string(),
        plant: opts.plant.clone().unwrap_or_else(|| scenario.plant.clone()),
        seed: opts.seed,
        estimator: format!("{:?}", opts.estimator).to_lowercase(),
        processes: 2,
        gust,
        non_finite: rec.non_finite,
        pwm_activity_us: rec.pwm_change_sum / rec.ticks.saturating_sub(1).max(1) as f64,
        steps: report.steps,
        sim_s: report.sim_s,
        wall_s: report.wall_s,
        realtime_factor: report.realtime_factor(),
        resends: report.link.resends,
    })
}
