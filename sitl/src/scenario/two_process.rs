//! A scenario flown through the whole stack: the plant served over UDP in lockstep to the real
//! `autopilot` process (`sitl run --scenario`), rather than the in-process runner's controller. In: a
//! scenario, the controller, seed and instance. Out: the scenario's metrics from the plant's truth, so the
//! two can be compared number for number.
//!
//! - **Hover scenarios** (a position reference with one step: `gust-hover`, `turbulence-hover`): the
//!   autopilot starts as the runner does, in the air at the scenario's initial point, armed and holding
//!   the reference (`start_airborne`); truth-fed (the plant's truth in `HIL_STATE_QUATERNION` and
//!   `ODOMETRY`, with the scenario's state noise added by the plant) and with the plant's home as its
//!   truth origin, so its NED frame is the plant's. Truth is sampled before every plant step, as the
//!   runner samples it.
//! - **Track scenarios** (`figure8`): flown as a real mission by a ground station (`gcs`) over the
//!   autopilot's UDP port: from the ground, the fused estimator on the plant's sensors, the track's
//!   waypoints uploaded with the mission protocol (takeoff to its altitude, DO_CHANGE_SPEED to its speed,
//!   the waypoints relative to home, land at the last), armed, AUTO MISSION, until landed and disarmed.
//!   The scenario's state noise becomes sensor noise: the paper's 2 cm on position is the GPS's
//!   (σ 0.02 m, eph 0.02 m) and the estimator is told so; the other sensors carry `sitl run`'s modest
//!   noise. Cross-track and altitude errors are measured from truth against the scenario's spline while
//!   the mission is between its first and last waypoint, as the runner measures its reference's lap.
//!   A polyline track (`path = "polyline"`) is uploaded as straight waypoints (NAV_WAYPOINT, which stop
//!   at each corner) and measured against its straight segments. A track run starts on the ground, so it
//!   needs the ground on, and its noise is sensor noise, which `state_noise_scale` does not scale.
//! - **Pilot scenarios** (a hover with a `[[rc]]` stick schedule): the vehicle starts where `[initial]`
//!   puts it (on the ground at D = 0), disarmed, in the autopilot's boot mode (Hold), and the schedule is
//!   the pilot: the plant sends it as the airframe's radio (`RC_CHANNELS`), so the mode switch, the
//!   arming gesture and the sticks fly it, with the scenario's `[manual]` settings (the channel map, the
//!   mode switch's modes). Truth-fed by default, as a hover; measured as a hover (against its step's
//!   point) and reported as when the autopilot's actuator commands armed and disarmed and how high the
//!   plant's truth climbed ([`PilotMetrics`]).
//! - A hover's step is held as a point: feed-forward on it cannot reach the autopilot and is refused.
//!
//! Either way the autopilot runs its commander, MAVLink services and telemetry as in any flight, with no
//! state directory (no saved parameters or mission).

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use autopilot::core::config::{AirborneStart, VehicleConfig};
use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::estimator::GeoOrigin;
use autopilot::core::mavlink::common::{MISSION_ITEM_INT_DATA, MavCmd, MavFrame};
use autopilot::core::mavlink::units::deg_to_dege7;
use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use super::gcs::Gcs;
use super::metrics::{self, GustMetrics, TrackMetrics};
use super::path::{PathKind, TrackPath};
use super::reference::{ReferenceSpec, TrackSpec};
use super::runner::plant_config;
use super::{OverrideValue, Scenario, ScenarioError, StateNoiseKind};
use crate::launch::{AutopilotChild, LaunchError, LaunchReport, TempConfig, run_with_child};
use crate::link::rc::RcInPort;
use crate::link::{LinkConfig, PlantServer, UdpTransport, home_origin};
use crate::plant::{InitialState, Plant, SensorConfig};

/// Why a two-process scenario run failed.
#[derive(Debug, thiserror::Error)]
pub enum TwoProcessError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(
        "scenario {0}: only hover scenarios (a position reference with one step, e.g. gust-hover, \
         turbulence-hover) and tracks (figure8) fly through two processes"
    )]
    NotHover(String),
    #[error("the ground station: {0}")]
    Gcs(#[from] super::gcs::GcsError),
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
    /// The autopilot's estimator; `None`: truth for hovers (as the paper's runs), fused for tracks.
    pub estimator: Option<EstimatorSource>,
    /// Extra autopilot arguments (e.g. `--log-dir`).
    pub autopilot_args: Vec<OsString>,
    /// The plant's RC input port on 127.0.0.1 (`crate::link::rc`), or `None` for none. The scenario's
    /// `[[rc]]` schedule wins over it from its first entry on.
    pub rc_in_port: Option<u16>,
}

/// The metrics of a two-process run (the JSON `sitl run --scenario --json` prints).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwoProcessMetrics {
    pub scenario: String,
    pub controller: String,
    /// As the runner's: the preset, then `+key=value` per `[airframe]` override.
    pub plant: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub airframe_overrides: Option<std::collections::BTreeMap<&'static str, OverrideValue>>,
    pub seed: u64,
    pub estimator: String,
    pub processes: u8,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gust: Option<GustMetrics>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub track: Option<TrackMetrics>,
    /// Track scenarios: the mission items reported reached, and how many the mission had.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub items_reached: Option<(usize, usize)>,
    /// Pilot scenarios (`[[rc]]`): when the autopilot armed and disarmed, how high the vehicle climbed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pilot: Option<PilotMetrics>,
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

/// What a pilot-flown run ([`Scenario::rc`]) did, from the actuator commands the autopilot sent (their
/// armed flag) and the plant's truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PilotMetrics {
    /// Plant time (s) of the first armed actuator command, if the vehicle armed.
    pub armed_at_s: Option<f64>,
    /// Plant time (s) of the first disarmed command after that, if it disarmed again.
    pub disarmed_at_s: Option<f64>,
    /// The highest the truth rose above its start (m).
    pub max_climb_m: f64,
}

/// The estimator a run uses.
fn estimator_of(scenario: &Scenario, opts: &TwoProcessOptions) -> EstimatorSource {
    opts.estimator.unwrap_or(match scenario.reference {
        ReferenceSpec::Track(_) => EstimatorSource::Fused,
        _ => EstimatorSource::Truth,
    })
}

/// The autopilot configuration file (TOML) for a run of `scenario`: the scenario's controller
/// configuration; hovers start airborne at their hold point; truth-fed runs take the plant's home as
/// their origin; track runs with the paper's noise trust the 2 cm GPS.
///
/// # Errors
/// [`TwoProcessError::NotHover`] when the scenario is neither a hover nor a track.
pub fn autopilot_config(
    scenario: &Scenario,
    opts: &TwoProcessOptions,
    plant: &Plant,
) -> Result<String, TwoProcessError> {
    let mut vehicle =
        VehicleConfig { controller: opts.controller, control: scenario.controller.clone(), ..VehicleConfig::default() };
    match &scenario.reference {
        ReferenceSpec::Position { steps } => {
            let [hold] = steps.as_slice() else { return Err(TwoProcessError::NotHover(scenario.name.clone())) };
            // A pilot's scenario starts as a pilot does: on the ground, disarmed.
            if scenario.rc.is_empty() {
                vehicle.start_airborne = Some(AirborneStart { hold_ned_m: hold.pos_ned_m, yaw_rad: hold.yaw_rad });
            }
        }
        ReferenceSpec::Track(_) => {
            if scenario.state_noise == StateNoiseKind::Paper {
                vehicle.estimator.gps_pos_noise_m = PAPER_GPS_SIGMA_M;
                vehicle.estimator.gps_hgt_noise_m = PAPER_GPS_SIGMA_M * 1.5;
            }
        }
        ReferenceSpec::Attitude { .. } | ReferenceSpec::Rates { .. } => {
            return Err(TwoProcessError::NotHover(scenario.name.clone()));
        }
    }
    if let Some(manual) = scenario.manual {
        vehicle.manual = manual;
    }
    vehicle.estimator.source = estimator_of(scenario, opts);
    vehicle.estimator.truth_origin = Some(home_origin(&plant.config().sensors.home));
    #[derive(Serialize)]
    struct File<'a> {
        vehicle: &'a VehicleConfig,
    }
    toml::to_string(&File { vehicle: &vehicle })
        .map_err(|e| TwoProcessError::Config { path: PathBuf::from("(memory)"), source: std::io::Error::other(e) })
}

/// The paper's position noise (m) as the GPS's, for track runs through the estimator.
pub const PAPER_GPS_SIGMA_M: f64 = 0.02;

/// The plant's sensors for a track run: `sitl run`'s modest noise, the GPS at the paper's 2 cm (or no
/// noise at all without state noise).
fn track_sensors(noise: StateNoiseKind) -> SensorConfig {
    match noise {
        StateNoiseKind::None => SensorConfig::default(),
        StateNoiseKind::Paper => {
            let mut s = SensorConfig::modest_noise();
            s.gps.position.white_sigma = PAPER_GPS_SIGMA_M;
            s.gps.eph_m = PAPER_GPS_SIGMA_M;
            s.gps.epv_m = PAPER_GPS_SIGMA_M * 1.5;
            s
        }
    }
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
/// [`TwoProcessError`]: not a hover or track scenario, a bad plant, a port in use, the autopilot or the
/// ground station failing, or `stop` set before the end.
pub fn run(
    scenario: &Scenario,
    opts: &TwoProcessOptions,
    autopilot: &Path,
    stop: &AtomicBool,
) -> Result<TwoProcessMetrics, TwoProcessError> {
    match &scenario.reference {
        ReferenceSpec::Track(track) => run_track(scenario, track, opts, autopilot, stop),
        _ => run_hover(scenario, opts, autopilot, stop),
    }
}

/// A launched run: the plant server, the autopilot child (or why it did not start) and its configuration
/// file (removed at the end).
type Launched = (PlantServer<UdpTransport>, Result<AutopilotChild, LaunchError>, TempConfig);

/// The plant server on 127.0.0.1:4560+N and the autopilot child configured for `scenario`.
fn launch(
    scenario: &Scenario,
    opts: &TwoProcessOptions,
    autopilot: &Path,
    mut plant: Plant,
    link: LinkConfig,
) -> Result<Launched, TwoProcessError> {
    let config_text = autopilot_config(scenario, opts, &plant)?;
    plant.radio_mut().set_schedule(scenario.rc_schedule()?);
    let schedule = scenario.sim_events()?;
    let rc_in = opts
        .rc_in_port
        .map(|port| {
            let addr = format!("127.0.0.1:{port}");
            RcInPort::bind(addr.as_str()).map_err(|source| TwoProcessError::Bind { addr, source })
        })
        .transpose()?;
    let config = TempConfig::write(&format!("i{}-autopilot", opts.instance), &config_text)
        .map_err(|(path, source)| TwoProcessError::Config { path, source })?;
    let addr = format!("127.0.0.1:{}", 4560 + opts.instance);
    let mut server = PlantServer::bind_udp(plant, addr.as_str(), link)
        .map_err(|source| TwoProcessError::Bind { addr: addr.clone(), source })?;
    server.set_sim_events(schedule);
    if let Some(port) = rc_in {
        server.set_rc_in(port);
    }
    let mut args: Vec<OsString> =
        vec!["--plant".into(), format!("udp://{addr}").into(), "-i".into(), opts.instance.to_string().into()];
    args.push("--config".into());
    args.push(config.path().into());
    // A scenario runs on the defaults and its own configuration, never on parameters saved by a flight.
    args.push("--state-dir".into());
    args.push("off".into());
    args.extend(opts.autopilot_args.iter().cloned());
    let child = AutopilotChild::spawn(autopilot, &args);
    Ok((server, child, config))
}

fn run_hover(
    scenario: &Scenario,
    opts: &TwoProcessOptions,
    autopilot: &Path,
    stop: &AtomicBool,
) -> Result<TwoProcessMetrics, TwoProcessError> {
    let ReferenceSpec::Position { steps } = &scenario.reference else {
        return Err(TwoProcessError::NotHover(scenario.name.clone()));
    };
    let hold = steps[0].pos_ned_m;
    if steps[0].vel_ned_mps != [0.0; 3] || steps[0].acc_ned_mps2 != [0.0; 3] {
        return Err(ScenarioError::Invalid(
            "a two-process hover holds its step's position: its vel_ned_mps and acc_ned_mps2 feed-forward \
             cannot reach the autopilot"
                .into(),
        )
        .into());
    }
    let config = plant_config(scenario, opts.plant.as_deref())?;
    let initial = scenario.initial.state();
    let plant = Plant::new(config, &initial, opts.seed).map_err(ScenarioError::from)?;
    let noise = scenario.state_noise()?;
    let truth_noise = (scenario.state_noise == StateNoiseKind::Paper).then_some(noise);
    let link = LinkConfig {
        truth_noise,
        truth_odometry: true,
        connect_timeout: Some(std::time::Duration::from_secs(30)),
        ..LinkConfig::default()
    };
    let (mut server, child, config) = launch(scenario, opts, autopilot, plant, link)?;
    let duration_us = (scenario.duration_s * 1e6).round() as u64;
    let mut rec = Recorded::default();
    rec.sample(0.0, &server.plant().truth().pos_ned_m, &hold);
    let start_d_m = server.plant().truth().pos_ned_m.z;
    let mut pilot = PilotMetrics { armed_at_s: None, disarmed_at_s: None, max_climb_m: 0.0 };
    let report = child.and_then(|child| {
        run_with_child(&mut server, child, Some(duration_us), stop, |plant, cmd| {
            let cmd_s = cmd.time_us as f64 * 1e-6;
            match (cmd.armed, pilot.armed_at_s, pilot.disarmed_at_s) {
                (true, None, _) => pilot.armed_at_s = Some(cmd_s),
                (false, Some(_), None) => pilot.disarmed_at_s = Some(cmd_s),
                _ => {}
            }
            pilot.max_climb_m = pilot.max_climb_m.max(start_d_m - plant.truth().pos_ned_m.z);
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
    drop(config);
    let report: LaunchReport = report?;
    if report.stopped {
        return Err(TwoProcessError::Stopped(report.sim_s));
    }
    let gust = scenario.wind.gust.as_ref().map(|g| {
        metrics::hover_gust_metrics(&rec.t, &rec.pos, &rec.ref_pos, g.onset_s, g.release_s, &scenario.metric_windows)
    });
    Ok(TwoProcessMetrics {
        scenario: scenario.name.clone(),
        controller: opts.controller.to_string(),
        plant: scenario.plant_label(opts.plant.as_deref()),
        airframe_overrides: scenario.airframe_overrides(),
        seed: opts.seed,
        estimator: format!("{:?}", estimator_of(scenario, opts)).to_lowercase(),
        processes: 2,
        gust,
        track: None,
        items_reached: None,
        pilot: (!scenario.rc.is_empty()).then_some(pilot),
        non_finite: rec.non_finite,
        pwm_activity_us: rec.pwm_change_sum / rec.ticks.saturating_sub(1).max(1) as f64,
        steps: report.steps,
        sim_s: report.sim_s,
        wall_s: report.wall_s,
        realtime_factor: report.realtime_factor(),
        resends: report.link.resends,
    })
}

/// A mission item of a track run: `command` at `ne_m` from the plant's home (NaN: unset) and `alt_m` above
/// home, params 1-4.
#[allow(deprecated)]
fn track_item(
    seq: u16,
    command: MavCmd,
    params: [f32; 4],
    home: &GeoOrigin,
    ne_m: Option<[f64; 2]>,
    alt_m: f32,
) -> MISSION_ITEM_INT_DATA {
    let (x, y) = match ne_m {
        Some([n, e]) => {
            let (lat, lon, _) = home.geodetic_from_ned(&Vector3::new(n, e, 0.0));
            (deg_to_dege7(lat), deg_to_dege7(lon))
        }
        None => (i32::MAX, i32::MAX),
    };
    let frame = if command == MavCmd::MAV_CMD_DO_CHANGE_SPEED {
        MavFrame::MAV_FRAME_MISSION
    } else {
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    };
    MISSION_ITEM_INT_DATA {
        param1: params[0],
        param2: params[1],
        param3: params[2],
        param4: params[3],
        x,
        y,
        z: alt_m,
        seq,
        command,
        target_system: 1,
        target_component: 1,
        frame,
        current: 0,
        autocontinue: 1,
        ..Default::default()
    }
}

/// The track as a mission: takeoff, speed, every waypoint of every lap, land at the last. Returns the
/// items and the sequence numbers of the first and last waypoint.
fn track_mission(track: &TrackSpec, home: &GeoOrigin) -> (Vec<MISSION_ITEM_INT_DATA>, u16, u16) {
    let waypoint = match track.path {
        PathKind::Spline => MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT,
        PathKind::Polyline => MavCmd::MAV_CMD_NAV_WAYPOINT,
    };
    let alt_m = (-track.pos_d_m) as f32;
    let nan = f32::NAN;
    let mut items = vec![
        track_item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan], home, None, alt_m),
        track_item(1, MavCmd::MAV_CMD_DO_CHANGE_SPEED, [1.0, track.speed_mps as f32, -1.0, 0.0], home, None, 0.0),
    ];
    let first = 2;
    for lap in 0..track.laps {
        for (i, w) in track.waypoints_ne_m.iter().enumerate() {
            // A closed track's laps share their seam point.
            if lap > 0 && i == 0 {
                continue;
            }
            let seq = u16::try_from(items.len()).unwrap_or(u16::MAX);
            items.push(track_item(seq, waypoint, [0.0, 0.0, 0.0, nan], home, Some(*w), alt_m));
        }
    }
    let last = u16::try_from(items.len() - 1).unwrap_or(u16::MAX);
    let end = *track.waypoints_ne_m.last().unwrap_or(&[0.0, 0.0]);
    let seq = last + 1;
    items.push(track_item(seq, MavCmd::MAV_CMD_NAV_LAND, [0.0, 0.0, 0.0, nan], home, Some(end), 0.0));
    (items, first, last)
}

/// Fly the mission with the ground station: wait for the estimator, upload, arm, AUTO MISSION, until
/// every item is reached and the vehicle has disarmed. `reached` follows MISSION_ITEM_REACHED.
fn fly_mission(
    instance: u16,
    items: &[MISSION_ITEM_INT_DATA],
    reached: &AtomicU32,
    timeout_s: f64,
) -> Result<usize, TwoProcessError> {
    let sysid = u8::try_from(instance + 1).unwrap_or(u8::MAX);
    let autopilot = std::net::SocketAddr::from(([127, 0, 0, 1], 18570 + instance));
    let mut gcs = Gcs::new(autopilot, sysid)?;
    gcs.wait_until(60.0, "estimator convergence", |s| s.converged)?;
    gcs.upload(items)?;
    gcs.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])?;
    gcs.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 4.0, 0.0, 0.0, 0.0, 0.0])?;
    let mut last_len = 0;
    let start = gcs.seen.time_ms;
    loop {
        gcs.wait_until(timeout_s, "mission progress", |s| s.reached.len() > last_len || !s.armed)?;
        last_len = gcs.seen.reached.len();
        if let Some(&seq) = gcs.seen.reached.last() {
            reached.store(u32::from(seq), Ordering::Relaxed);
        }
        if !gcs.seen.armed {
            break;
        }
        if f64::from(gcs.seen.time_ms - start) > timeout_s * 1e3 {
            return Err(super::gcs::GcsError::Timeout("the mission".into(), timeout_s).into());
        }
    }
    Ok(gcs.seen.reached.len())
}

/// No MISSION_ITEM_REACHED yet.
const NONE_REACHED: u32 = u32::MAX;

fn run_track(
    scenario: &Scenario,
    track: &TrackSpec,
    opts: &TwoProcessOptions,
    autopilot: &Path,
    stop: &AtomicBool,
) -> Result<TwoProcessMetrics, TwoProcessError> {
    if !scenario.ground {
        return Err(ScenarioError::Invalid(
            "a two-process track run starts on the ground: it needs ground = true".into(),
        )
        .into());
    }
    if scenario.state_noise_scale != 1.0 {
        return Err(ScenarioError::Invalid(
            "a two-process track run's noise is sensor noise, which state_noise_scale does not scale".into(),
        )
        .into());
    }
    let mut config = plant_config(scenario, opts.plant.as_deref())?;
    config.sensors = track_sensors(scenario.state_noise);
    let plant = Plant::new(config, &InitialState::default(), opts.seed).map_err(ScenarioError::from)?;
    let home = home_origin(&plant.config().sensors.home);
    let truth_fed = estimator_of(scenario, opts) == EstimatorSource::Truth;
    let link = LinkConfig {
        truth_odometry: truth_fed,
        connect_timeout: Some(std::time::Duration::from_secs(30)),
        ..LinkConfig::default()
    };
    let (mut server, child, config) = launch(scenario, opts, autopilot, plant, link)?;
    let (items, first_wp, last_wp) = track_mission(track, &home);
    let path = TrackPath::new(track.path, &track.waypoints_ne_m);
    let lap_m = path.length_m();
    let reached = AtomicU32::new(NONE_REACHED);
    let finished = AtomicBool::new(false);
    let mut cross = Vec::new();
    let mut alt = Vec::new();
    let mut track_t_s = Vec::new();
    let mut nearest_s: Option<f64> = None;
    let mut non_finite = false;
    let mut last_pwm: Option<[f64; 4]> = None;
    let (mut pwm_change_sum, mut ticks) = (0.0, 0_u64);
    let timeout_s = scenario.duration_s + 120.0;
    let halt = AtomicBool::new(false);
    let outcome = std::thread::scope(|scope| {
        let gcs = scope.spawn(|| {
            let result = fly_mission(opts.instance, &items, &reached, timeout_s);
            finished.store(true, Ordering::Relaxed);
            result
        });
        let watch = scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                if stop.load(Ordering::Relaxed) {
                    halt.store(true, Ordering::Relaxed);
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            halt.store(true, Ordering::Relaxed);
        });
        let report = child.and_then(|child| {
            run_with_child(&mut server, child, None, &halt, |plant, cmd| {
                let pwm = cmd.effective_pwm_us();
                non_finite |= !pwm.iter().all(|p| p.is_finite());
                if let Some(prev) = last_pwm {
                    pwm_change_sum += prev.iter().zip(&pwm).map(|(a, b)| (a - b).abs()).sum::<f64>() / 4.0;
                }
                last_pwm = Some(pwm);
                ticks += 1;
                let seq = reached.load(Ordering::Relaxed);
                let on_track = seq != NONE_REACHED && seq >= u32::from(first_wp) && seq < u32::from(last_wp);
                if on_track {
                    let p = plant.truth().pos_ned_m;
                    non_finite |= !p.iter().all(|v| v.is_finite());
                    let ne = Vector2::new(p.x, p.y);
                    let (d, s) = match nearest_s {
                        Some(s) => path.nearest_near(ne, s, 0.05),
                        None => path.nearest_near(ne, 0.0, 0.3),
                    };
                    nearest_s = Some(s.min(lap_m * f64::from(track.laps)));
                    cross.push(d);
                    alt.push(p.z - track.pos_d_m);
                    track_t_s.push(plant.time_us() as f64 * 1e-6);
                }
            })
        });
        finished.store(true, Ordering::Relaxed);
        let gcs_result = gcs.join();
        let _ = watch.join();
        (report, gcs_result)
    });
    drop(config);
    let (report, gcs_result) = outcome;
    let report: LaunchReport = report?;
    let items_reached = match gcs_result {
        Ok(Ok(n)) => n,
        Ok(Err(e)) => return Err(e),
        Err(_) => {
            return Err(TwoProcessError::Gcs(super::gcs::GcsError::Timeout("ground station panicked".into(), 0.0)));
        }
    };
    if stop.load(Ordering::Relaxed) {
        return Err(TwoProcessError::Stopped(report.sim_s));
    }
    Ok(TwoProcessMetrics {
        scenario: scenario.name.clone(),
        controller: opts.controller.to_string(),
        plant: scenario.plant_label(opts.plant.as_deref()),
        airframe_overrides: scenario.airframe_overrides(),
        seed: opts.seed,
        estimator: format!("{:?}", estimator_of(scenario, opts)).to_lowercase(),
        processes: 2,
        gust: None,
        track: (!cross.is_empty()).then(|| metrics::track_metrics(&track_t_s, &cross, &alt)),
        items_reached: Some((items_reached, items.len())),
        pilot: None,
        non_finite,
        pwm_activity_us: pwm_change_sum / ticks.saturating_sub(1).max(1) as f64,
        steps: report.steps,
        sim_s: report.sim_s,
        wall_s: report.wall_s,
        realtime_factor: report.realtime_factor(),
        resends: report.link.resends,
    })
}
