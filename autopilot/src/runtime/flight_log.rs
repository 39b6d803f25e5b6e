//! The onboard flight log: one ULog file per armed flight, from arming to disarming, as PX4's logger
//! writes with `SDLOG_MODE` 0, at `<root>/<YYYY-MM-DD>/<HH_MM_SS>.ulg` (the wall clock's UTC date and
//! time at arming; the root is the state directory's `log/`).
//!
//! Two halves, so that the lockstep loop never waits on a disk:
//! - [`FlightLogger`] lives on the plant-link thread beside the vehicle. After each step it samples the
//!   vehicle's [`LogSnapshot`] and its controller's telemetry on VEHICLE time at the rates of
//!   [`TOPICS`], encodes the records with the pure encoder of [`super::ulog`] and hands them, one batch
//!   per step at most, to a bounded channel with `try_send`. When the writer is behind, a batch is
//!   dropped and counted, and a dropout marker ('O') with the vehicle time lost goes in its place.
//!   Every STATUSTEXT the vehicle sends (mode changes, failsafes, refusals) becomes a logged string
//!   ('L') at its severity.
//! - [`UlogWriter`], on a blocking thread of its own ([`spawn_writer`]), writes `<name>.ulg.tmp` and,
//!   when the flight ends (disarm, or the autopilot stopping: Ctrl-C, SIGTERM, standard input closed),
//!   flushes, syncs and renames it to `<name>.ulg`: a file under its final name is complete.
//!
//! The header's timestamp and every record's are vehicle time (µs since the plant started), as PX4's
//! are time since boot. The definitions carry every parameter ('P', `int32_t` or `float` as PX4 types
//! them) and the default of each one that differs from it ('Q'); a parameter changed in flight is
//! logged again in the data section.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use mavlink::dialects::common::MavSeverity;
use nalgebra::{UnitQuaternion, Vector3};
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;

use super::ulog::{self, Field, FieldType, Record, Topic, Value};
use super::utc::UtcTime;
// Standard gravity (m/s²), to turn the specific force into an acceleration.
use crate::core::battery::BatteryWarning;
use crate::core::commander::FlightMode;
use crate::core::control::ControllerKind;
use crate::core::estimator::eskf::GRAVITY_MPS2 as G_MPS2;
use crate::core::params::{ParamKind, ParamStore};
use crate::core::vehicle::{LogSnapshot, Vehicle};

/// Batches the writer may lag behind before one is dropped (a batch is one vehicle step's records).
pub const ULOG_CHANNEL_CAPACITY: usize = 4096;
/// Vehicle time between sync markers.
pub const SYNC_INTERVAL_US: u64 = 1_000_000;
/// Vehicle time between checks for parameters changed in flight.
pub const PARAM_CHECK_INTERVAL_US: u64 = 1_000_000;
/// Wall time between flushes of the file.
const FLUSH_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// The logged topics and the interval (µs of vehicle time) each is sampled at. PX4's topic names, and
/// the fields of PX4's messages that this vehicle has, with their names and types; `controller_status`
/// (every value of [`crate::core::control::Controller::telemetry`]) and `aco_weights` (ACO only) are
/// this autopilot's own. `vehicle_status` is also logged whenever the arming state or the mode changes.
/// PX4's default logger profile takes attitude and setpoints at 20-50 Hz and positions at 10 Hz; the
/// control-side topics are taken at 50 Hz here because the controller is what this autopilot studies.
pub const TOPICS: [(&str, u64); 10] = [
    ("vehicle_status", 1_000_000),
    ("vehicle_attitude", 20_000),
    ("vehicle_local_position", 20_000),
    ("vehicle_local_position_setpoint", 20_000),
    ("vehicle_attitude_setpoint", 20_000),
    ("actuator_outputs", 20_000),
    ("controller_status", 20_000),
    ("estimator_innovations", 100_000),
    ("battery_status", 200_000),
    ("aco_weights", 100_000),
];

/// `aco_weights`: the ACO weight vectors and the telemetry names of their N/E/D or x/y/z values.
const ACO_WEIGHTS: [(&str, [&str; 3]); 5] = [
    ("w_t", ["aco.w_t_n", "aco.w_t_e", "aco.w_t_d"]),
    ("b_t", ["aco.b_t_n_mps2", "aco.b_t_e_mps2", "aco.b_t_d_mps2"]),
    ("c_r", ["aco.c_r_x", "aco.c_r_y", "aco.c_r_z"]),
    ("d_r", ["aco.d_r_x_radps2", "aco.d_r_y_radps2", "aco.d_r_z_radps2"]),
    ("mass_est", ["aco.mass_est_n_kg", "aco.mass_est_e_kg", "aco.mass_est_d_kg"]),
];

/// What the sampler hands to the writer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LogItem {
    /// A flight starts: `<dir>/<name>.ulg.tmp`, beginning with `bytes` (header and definitions).
    Open { dir: PathBuf, name: String, bytes: Vec<u8> },
    /// More of the flight's messages.
    Append(Vec<u8>),
    /// The flight ended: finalize the file under its `.ulg` name.
    Close,
}

/// Why a flight log could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FlightLogError {
    #[error("cannot create ULog {path}: {source}")]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write ULog {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot rename ULog {from} to {to}: {source}")]
    Rename {
        from: PathBuf,
        to: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Counts of the sampler, for the summary at shutdown.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FlightLogStats {
    /// Flights logged (files opened).
    pub flights: u64,
    /// Bytes handed to the writer.
    pub bytes: u64,
    /// Batches dropped because the writer was behind.
    pub dropped: u64,
}

/// PX4's `vehicle_status.nav_state` of a mode.
#[must_use]
pub const fn px4_nav_state(mode: FlightMode) -> u8 {
    match mode {
        FlightMode::Altitude => 1,
        FlightMode::Position => 2,
        FlightMode::Mission => 3,
        FlightMode::Hold => 4,
        FlightMode::ReturnToLaunch => 5,
        FlightMode::Offboard => 14,
        FlightMode::Takeoff => 17,
        FlightMode::Land => 18,
    }
}

/// PX4's `battery_status.warning` of a level.
const fn px4_battery_warning(level: BatteryWarning) -> u8 {
    match level {
        BatteryWarning::None => 0,
        BatteryWarning::Low => 1,
        BatteryWarning::Critical => 2,
        BatteryWarning::Emergency => 3,
    }
}

/// A telemetry name as a ULog field name: without the controller's prefix, dots as underscores
/// (`ca.roll.k1` -> `roll_k1`).
fn field_name(telemetry: &str) -> String {
    let bare = telemetry.split_once('.').map_or(telemetry, |(_, rest)| rest);
    bare.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
}

/// The fields (after `timestamp`) of topic `name`; `telemetry` names the controller's values.
fn fields(name: &str, telemetry: &[&'static str]) -> Vec<Field> {
    use FieldType::{Bool, F32, F64, U8, U32, U64};
    let f = |n: &str| Field::scalar(F32, n);
    match name {
        "vehicle_status" => vec![
            Field::scalar(U64, "armed_time"),
            Field::scalar(U8, "arming_state"),
            Field::scalar(U8, "nav_state"),
            Field::scalar(U8, "vehicle_type"),
            Field::scalar(U8, "system_type"),
            Field::scalar(U8, "system_id"),
            Field::scalar(U8, "component_id"),
            Field::scalar(Bool, "is_vtol"),
        ],
        "vehicle_attitude" => vec![Field::scalar(U64, "timestamp_sample"), Field::array(F32, 4, "q")],
        "vehicle_local_position" => {
            let mut v = vec![Field::scalar(U64, "timestamp_sample"), Field::scalar(F64, "ref_lat")];
            v.push(Field::scalar(F64, "ref_lon"));
            v.extend(["x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az", "heading", "ref_alt"].map(f));
            v.extend(
                ["xy_valid", "z_valid", "v_xy_valid", "v_z_valid", "xy_global", "z_global"]
                    .map(|n| Field::scalar(Bool, n)),
            );
            v
        }
        "vehicle_local_position_setpoint" => {
            let mut v: Vec<Field> = ["x", "y", "z", "yaw", "vx", "vy", "vz"].map(f).into();
            v.push(Field::array(F32, 3, "acceleration"));
            v.push(Field::array(F32, 3, "jerk"));
            v
        }
        "vehicle_attitude_setpoint" => {
            let mut v: Vec<Field> = ["roll_body", "pitch_body", "yaw_body"].map(f).into();
            v.push(Field::array(F32, 4, "q_d"));
            v
        }
        "actuator_outputs" => vec![Field::scalar(U32, "noutputs"), Field::array(F32, 16, "output")],
        "controller_status" => telemetry.iter().map(|n| f(&field_name(n))).collect(),
        "estimator_innovations" => vec![
            Field::scalar(U64, "timestamp_sample"),
            Field::array(F32, 2, "gps_hvel"),
            f("gps_vvel"),
            Field::array(F32, 2, "gps_hpos"),
            f("gps_vpos"),
            f("baro_vpos"),
            f("heading"),
        ],
        "battery_status" => {
            let mut v: Vec<Field> = ["voltage_v", "current_a", "discharged_mah", "remaining"].map(f).into();
            v.extend([Field::scalar(U8, "warning"), Field::scalar(U8, "cell_count"), Field::scalar(Bool, "connected")]);
            v
        }
        "aco_weights" => ACO_WEIGHTS.iter().map(|(n, _)| Field::array(F32, 3, n)).collect(),
        _ => Vec::new(),
    }
}

/// What a record needs besides the vehicle's snapshot.
struct RecordContext<'a> {
    sysid: u8,
    /// Vehicle time of arming (`vehicle_status.armed_time`).
    armed_at_us: u64,
    /// The controller's telemetry now.
    telemetry: &'a [(&'static str, f64)],
    /// The telemetry names `controller_status` declared when the flight started.
    telemetry_names: &'a [&'static str],
}

/// One record of topic `name` at `now_us`.
fn record(name: &str, now_us: u64, snap: &LogSnapshot, ctx: &RecordContext<'_>) -> Record {
    let r = Record::new(now_us);
    let telemetry = ctx.telemetry;
    let est = &snap.estimate;
    let value = |n: &str| telemetry.iter().find(|(t, _)| *t == n).map_or(f64::NAN, |&(_, v)| v);
    let nan3 = [f64::NAN; 3];
    match name {
        "vehicle_status" => r
            .u64(ctx.armed_at_us)
            .u8(if snap.armed { 2 } else { 1 })
            .u8(px4_nav_state(snap.mode))
            .u8(1) // rotary wing
            .u8(2) // MAV_TYPE_QUADROTOR
            .u8(ctx.sysid)
            .u8(1)
            .bool(false),
        "vehicle_attitude" => {
            let q = est.q_ned_frd;
            r.u64(est.time_us).f32s(&[q.w, q.i, q.j, q.k])
        }
        "vehicle_local_position" => {
            let (lat, lon, alt) =
                est.origin.map_or((f64::NAN, f64::NAN, f64::NAN), |o| (o.lat_deg, o.lon_deg, o.alt_amsl_m));
            let acc = est.q_ned_frd * est.specific_force_frd_mps2 + Vector3::new(0.0, 0.0, G_MPS2);
            let (p, v, flags) = (est.pos_ned_m, est.vel_ned_mps, est.flags);
            r.u64(est.time_us)
                .f64(lat)
                .f64(lon)
                .f32s(&[p.x, p.y, p.z, v.x, v.y, v.z, acc.x, acc.y, acc.z, est.euler_rad.z, alt])
                .bool(flags.position_valid)
                .bool(flags.position_valid)
                .bool(flags.velocity_valid)
                .bool(flags.velocity_valid)
                .bool(est.origin.is_some())
                .bool(est.origin.is_some())
        }
        "vehicle_local_position_setpoint" => match &snap.reference {
            Some(rf) => {
                let (x, y) =
                    if rf.attitude_rad.is_some() { (f64::NAN, f64::NAN) } else { (rf.pos_ned_m.x, rf.pos_ned_m.y) };
                let (v, a, j) = (rf.vel_ned_mps, rf.acc_ned_mps2, rf.jerk_ned_mps3);
                r.f32s(&[x, y, rf.pos_ned_m.z, rf.yaw_rad, v.x, v.y, v.z, a.x, a.y, a.z, j.x, j.y, j.z])
            }
            None => r.f32s(&[f64::NAN; 13]),
        },
        "vehicle_attitude_setpoint" => {
            let sp = if snap.reference.is_some() { snap.attitude_setpoint_rad } else { Vector3::from(nan3) };
            let q = UnitQuaternion::from_euler_angles(sp.x, sp.y, sp.z);
            let q_d = if sp.iter().all(|x| x.is_finite()) { [q.w, q.i, q.j, q.k] } else { [f64::NAN; 4] };
            r.f32s(&[sp.x, sp.y, sp.z]).f32s(&q_d)
        }
        "actuator_outputs" => {
            let mut out = [0.0; 16];
            out[..4].copy_from_slice(&snap.pwm_us);
            r.u32(4).f32s(&out)
        }
        "controller_status" => ctx.telemetry_names.iter().fold(r, |r, n| r.f32(value(n))),
        "estimator_innovations" => {
            let i = &snap.innovations;
            r.u64(est.time_us).f32s(&i.gps_vel_ned_mps).f32s(&i.gps_pos_ned_m).f32(i.baro_alt_m).f32(i.heading_rad)
        }
        "battery_status" => {
            let s = snap.battery.sample;
            r.f32(s.map_or(0.0, |s| s.voltage_v))
                .f32(s.and_then(|s| s.current_a).unwrap_or(-1.0))
                .f32(s.and_then(|s| s.consumed_mah).unwrap_or(-1.0))
                .f32(s.and_then(|s| s.remaining).unwrap_or(-1.0))
                .u8(px4_battery_warning(snap.battery.level))
                .u8(s.map_or(0, |s| s.cells))
                .bool(s.is_some())
        }
        "aco_weights" => ACO_WEIGHTS.iter().fold(r, |r, (_, names)| r.f32s(&names.map(value))),
        _ => r,
    }
}

/// A flight being logged.
#[derive(Debug)]
struct Flight {
    topics: Vec<Topic>,
    intervals_us: Vec<u64>,
    due_us: Vec<u64>,
    /// The controller's telemetry names, in the order `controller_status` declares them.
    telemetry_names: Vec<&'static str>,
    /// (armed, nav_state) last logged.
    status: (bool, u8),
    params: Vec<f32>,
    next_sync_us: u64,
    next_param_check_us: u64,
    armed_at_us: u64,
}

/// The sampler: see the module docs. The default logs nothing.
#[derive(Debug)]
pub struct FlightLogger {
    tx: Option<mpsc::Sender<LogItem>>,
    root: PathBuf,
    sysid: u8,
    flight: Option<Flight>,
    pending: Vec<u8>,
    /// Vehicle time of the first batch dropped since the last one delivered.
    dropped_since_us: Option<u64>,
    /// A Close that found the queue full, sent again at the next step.
    close_pending: bool,
    stats: FlightLogStats,
}

impl Default for FlightLogger {
    fn default() -> Self {
        Self::off()
    }
}

impl FlightLogger {
    /// A logger writing flights under `root` through `tx`; `None`: logging off.
    #[must_use]
    pub fn new(tx: Option<mpsc::Sender<LogItem>>, root: PathBuf, sysid: u8) -> Self {
        Self {
            tx,
            root,
            sysid,
            flight: None,
            pending: Vec::new(),
            dropped_since_us: None,
            close_pending: false,
            stats: FlightLogStats::default(),
        }
    }

    /// A logger that logs nothing.
    #[must_use]
    pub fn off() -> Self {
        Self::new(None, PathBuf::new(), 1)
    }

    #[must_use]
    pub fn stats(&self) -> FlightLogStats {
        self.stats
    }

    /// Whether a flight is being logged.
    #[must_use]
    pub fn logging(&self) -> bool {
        self.flight.is_some()
    }

    /// Before the step's messages are sent: a flight starts when the vehicle is armed (and SDLOG_MODE is
    /// not -1), so that the step's "Armed" text is its first logged string.
    pub fn begin_step(&mut self, now_us: u64, vehicle: &Vehicle) {
        if self.close_pending
            && let Some(tx) = &self.tx
            && tx.try_send(LogItem::Close).is_ok()
        {
            self.close_pending = false;
        }
        if self.tx.is_none() || self.flight.is_some() || !vehicle.commander_output().armed {
            return;
        }
        if vehicle.params().sdlog_mode() < 0 {
            return;
        }
        self.open(now_us, vehicle, wall_us());
    }

    /// A STATUSTEXT the vehicle sent at `now_us`, as a logged string of its severity (while a flight is
    /// logged).
    pub fn text(&mut self, now_us: u64, severity: MavSeverity, text: &str) {
        if self.flight.is_none() {
            return;
        }
        if let Ok(bytes) = ulog::logged_string(severity as u8, now_us, text) {
            self.pending.extend(bytes);
        }
    }

    /// After the step's messages: the topics due at `now_us`; when the vehicle has disarmed, a last
    /// `vehicle_status` and the end of the flight.
    pub fn end_step(&mut self, now_us: u64, vehicle: &Vehicle) {
        let Some(flight) = self.flight.as_mut() else { return };
        let out = vehicle.commander_output();
        let status = (out.armed, px4_nav_state(out.mode));
        if status != flight.status {
            flight.status = status;
            flight.due_us[0] = now_us;
        }
        // Most steps (9 in 10 at 500 Hz) have nothing due: copy nothing out of the vehicle then.
        let due = |i: usize| now_us >= flight.due_us[i];
        let any_due = (0..flight.topics.len()).any(due);
        let wants_telemetry = flight
            .topics
            .iter()
            .enumerate()
            .any(|(i, t)| due(i) && matches!(t.name.as_str(), "controller_status" | "aco_weights"));
        let snap = if any_due { Some(vehicle.log_snapshot()) } else { None };
        let telemetry = if wants_telemetry { vehicle.controller().telemetry() } else { Vec::new() };
        for (i, topic) in flight.topics.iter().enumerate() {
            let Some(snap) = snap.as_ref() else { break };
            if now_us < flight.due_us[i] {
                continue;
            }
            let interval = flight.intervals_us[i];
            flight.due_us[i] =
                if now_us - flight.due_us[i] < interval { flight.due_us[i] + interval } else { now_us + interval };
            let ctx = RecordContext {
                sysid: self.sysid,
                armed_at_us: flight.armed_at_us,
                telemetry: &telemetry,
                telemetry_names: &flight.telemetry_names,
            };
            if let Ok(bytes) = topic.data(&record(&topic.name, now_us, snap, &ctx)) {
                self.pending.extend(bytes);
            }
        }
        if now_us >= flight.next_param_check_us {
            flight.next_param_check_us = now_us + PARAM_CHECK_INTERVAL_US;
            let store = vehicle.params();
            for (i, (def, value)) in store.iter().enumerate() {
                if flight.params.get(i).is_some_and(|old| old.to_bits() != value.to_bits()) {
                    flight.params[i] = value;
                    if let Ok(bytes) = ulog::parameter(def.name, &param_value(def.kind, value)) {
                        self.pending.extend(bytes);
                    }
                }
            }
        }
        if now_us >= flight.next_sync_us {
            flight.next_sync_us = now_us + SYNC_INTERVAL_US;
            self.pending.extend(ulog::sync());
        }
        let ended = !status.0;
        self.send(now_us, false);
        if ended {
            self.close();
        }
    }

    /// The end of the flight being logged, if any (the vehicle disarmed, was rebuilt, or the autopilot
    /// stops).
    pub fn close(&mut self) {
        if self.flight.take().is_none() {
            return;
        }
        self.send(0, true);
        if let Some(tx) = &self.tx {
            // Blocking would stall the lockstep loop: with the queue full, the close goes at a later step
            // (and the writer closes the file at the next Open or when the autopilot stops in any case).
            self.close_pending = tx.try_send(LogItem::Close).is_err();
        }
    }

    /// Hands the pending bytes to the writer (`force`: even when there is nothing new, to push a dropout
    /// marker out).
    fn send(&mut self, now_us: u64, force: bool) {
        let Some(tx) = &self.tx else { return };
        if self.pending.is_empty() && !force {
            return;
        }
        let mut bytes = Vec::new();
        if let Some(since) = self.dropped_since_us {
            let lost_ms = u16::try_from(now_us.saturating_sub(since) / 1000).unwrap_or(u16::MAX);
            bytes.extend(ulog::dropout(lost_ms));
        }
        bytes.append(&mut self.pending);
        if bytes.is_empty() {
            return;
        }
        let len = bytes.len() as u64;
        match tx.try_send(LogItem::Append(bytes)) {
            Ok(()) => {
                self.dropped_since_us = None;
                self.stats.bytes += len;
            }
            Err(TrySendError::Full(_) | TrySendError::Closed(_)) => {
                self.stats.dropped += 1;
                self.dropped_since_us.get_or_insert(now_us);
            }
        }
    }

    fn open(&mut self, now_us: u64, vehicle: &Vehicle, wall_us: u64) {
        let Some(tx) = &self.tx else { return };
        let when = UtcTime::from_unix_us(wall_us);
        let telemetry = vehicle.controller().telemetry();
        let telemetry_names: Vec<&'static str> = telemetry.iter().map(|(n, _)| *n).collect();
        let aco = vehicle.controller().kind() == ControllerKind::Aco;
        let mut topics = Vec::new();
        let mut intervals_us = Vec::new();
        for (name, interval) in TOPICS {
            if name == "aco_weights" && !aco {
                continue;
            }
            let msg_id = u16::try_from(topics.len()).unwrap_or(u16::MAX);
            topics.push(Topic::new(name, msg_id, fields(name, &telemetry_names)));
            intervals_us.push(interval);
        }
        let params: Vec<f32> = vehicle.params().iter().map(|(_, v)| v).collect();
        let bytes = definitions(now_us, wall_us, vehicle, &topics);
        let item = LogItem::Open { dir: self.root.join(when.date()), name: when.time('_'), bytes };
        if tx.try_send(item).is_err() {
            self.stats.dropped += 1;
            return;
        }
        self.stats.flights += 1;
        self.close_pending = false;
        self.pending.clear();
        self.dropped_since_us = None;
        let n = topics.len();
        self.flight = Some(Flight {
            topics,
            intervals_us,
            due_us: vec![now_us; n],
            telemetry_names,
            status: (true, px4_nav_state(vehicle.commander_output().mode)),
            params,
            next_sync_us: now_us + SYNC_INTERVAL_US,
            next_param_check_us: now_us + PARAM_CHECK_INTERVAL_US,
            armed_at_us: now_us,
        });
    }
}

/// A parameter's value as PX4 types it in a log.
fn param_value(kind: ParamKind, value: f32) -> Value {
    match kind {
        ParamKind::Real => Value::F32(value),
        ParamKind::Integer | ParamKind::Boolean => Value::I32(value as i32),
    }
}

/// The header and definitions of a flight starting at `now_us` (vehicle time) and `wall_us` (Unix
/// time): flag bits, formats, information, parameters and their defaults, subscriptions.
fn definitions(now_us: u64, wall_us: u64, vehicle: &Vehicle, topics: &[Topic]) -> Vec<u8> {
    let mut out = ulog::header(now_us).to_vec();
    out.extend(ulog::flag_bits());
    for t in topics {
        out.extend(t.format_message().unwrap_or_default());
    }
    let controller = vehicle.controller().kind().as_str().to_owned();
    let infos = [
        ("sys_name", Value::Str("ACO autopilot".into())),
        ("ver_hw", Value::Str("ACO_QUADROTOR".into())),
        ("ver_sw", Value::Str(env!("CARGO_PKG_VERSION").into())),
        ("sys_toolchain", Value::Str("rustc".into())),
        ("time_ref_utc", Value::I32(0)),
        ("controller", Value::Str(controller)),
        ("estimator", Value::Str(format!("{:?}", vehicle.config().estimator.source).to_lowercase())),
        (
            "log_start_utc",
            Value::Str(format!(
                "{} {} UTC",
                UtcTime::from_unix_us(wall_us).date(),
                UtcTime::from_unix_us(wall_us).time(':')
            )),
        ),
    ];
    for (name, value) in &infos {
        out.extend(ulog::info(name, value).unwrap_or_default());
    }
    let store: &ParamStore = vehicle.params();
    for (def, value) in store.iter() {
        out.extend(ulog::parameter(def.name, &param_value(def.kind, value)).unwrap_or_default());
    }
    for (def, value) in store.iter() {
        if value.to_bits() != def.default.to_bits() {
            let default = param_value(def.kind, def.default);
            out.extend(ulog::default_parameter(ulog::DEFAULT_TYPE_SYSTEM, def.name, &default).unwrap_or_default());
        }
    }
    for t in topics {
        out.extend(t.subscription(0).unwrap_or_default());
    }
    out
}

fn wall_us() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// An open `.ulg.tmp`.
#[derive(Debug)]
struct OpenLog {
    file: BufWriter<File>,
    temp_path: PathBuf,
    final_path: PathBuf,
    last_flush: Instant,
}

/// The writer: see the module docs. Synchronous; [`spawn_writer`] runs it on a thread.
#[derive(Debug, Default)]
pub struct UlogWriter {
    current: Option<OpenLog>,
}

impl UlogWriter {
    /// Carries out one item; returns the path of a file it finalized.
    ///
    /// # Errors
    /// [`FlightLogError`] when a file cannot be created, written or renamed; the flight is then given up
    /// (what was written stays as `.ulg.tmp`) and the next `Open` starts afresh.
    pub fn handle(&mut self, item: LogItem) -> Result<Option<PathBuf>, FlightLogError> {
        match item {
            LogItem::Open { dir, name, bytes } => {
                let closed = self.close()?;
                let mut log = create(&dir, &name)?;
                write(&mut log, &bytes)?;
                self.current = Some(log);
                Ok(closed)
            }
            LogItem::Append(bytes) => {
                let Some(log) = self.current.as_mut() else { return Ok(None) };
                if let Err(e) = write(log, &bytes) {
                    self.current = None;
                    return Err(e);
                }
                if log.last_flush.elapsed() >= FLUSH_INTERVAL {
                    log.last_flush = Instant::now();
                    if let Err(source) = log.file.flush() {
                        let path = log.temp_path.clone();
                        self.current = None;
                        return Err(FlightLogError::Write { path, source });
                    }
                }
                Ok(None)
            }
            LogItem::Close => self.close(),
        }
    }

    /// Flush, sync and rename the open file, if any; returns its final path.
    ///
    /// # Errors
    /// [`FlightLogError::Write`] or [`FlightLogError::Rename`] (the `.ulg.tmp` stays).
    pub fn close(&mut self) -> Result<Option<PathBuf>, FlightLogError> {
        let Some(mut log) = self.current.take() else { return Ok(None) };
        let write_err = |source| FlightLogError::Write { path: log.temp_path.clone(), source };
        log.file.flush().map_err(write_err)?;
        log.file.get_ref().sync_all().map_err(write_err)?;
        std::fs::rename(&log.temp_path, &log.final_path).map_err(|source| FlightLogError::Rename {
            from: log.temp_path.clone(),
            to: log.final_path.clone(),
            source,
        })?;
        Ok(Some(log.final_path))
    }
}

/// `<dir>/<name>.ulg.tmp`, or `<name>_1`, `<name>_2`... when a flight of that second exists already.
fn create(dir: &Path, name: &str) -> Result<OpenLog, FlightLogError> {
    std::fs::create_dir_all(dir).map_err(|source| FlightLogError::Create { path: dir.to_owned(), source })?;
    let mut last_err = None;
    for n in 0..100 {
        let stem = if n == 0 { name.to_owned() } else { format!("{name}_{n}") };
        let final_path = dir.join(format!("{stem}.ulg"));
        let temp_path = dir.join(format!("{stem}.ulg.tmp"));
        if final_path.exists() {
            continue;
        }
        match OpenOptions::new().write(true).create_new(true).open(&temp_path) {
            Ok(file) => {
                let file = BufWriter::with_capacity(64 * 1024, file);
                return Ok(OpenLog { file, temp_path, final_path, last_flush: Instant::now() });
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(source) => {
                last_err = Some(FlightLogError::Create { path: temp_path, source });
                break;
            }
        }
    }
    Err(last_err.unwrap_or_else(|| FlightLogError::Create {
        path: dir.join(format!("{name}.ulg")),
        source: std::io::Error::new(std::io::ErrorKind::AlreadyExists, "100 logs of the same second"),
    }))
}

fn write(log: &mut OpenLog, bytes: &[u8]) -> Result<(), FlightLogError> {
    log.file.write_all(bytes).map_err(|source| FlightLogError::Write { path: log.temp_path.clone(), source })
}

/// The writer on a blocking thread: handles items until the channel closes (every sender dropped: the
/// autopilot is stopping), then finalizes the open file. Failures are logged, never fatal: the vehicle
/// flies on without its log.
pub fn spawn_writer(mut rx: mpsc::Receiver<LogItem>) -> tokio::task::JoinHandle<()> {
    tokio::task::spawn_blocking(move || {
        let mut writer = UlogWriter::default();
        let report = |r: Result<Option<PathBuf>, FlightLogError>| match r {
            Ok(Some(path)) => tracing::info!(path = %path.display(), "flight log (ULog) closed"),
            Ok(None) => {}
            Err(e) => tracing::error!("{e}"),
        };
        while let Some(item) = rx.blocking_recv() {
            let opening = matches!(item, LogItem::Open { .. });
            report(writer.handle(item));
            if opening && let Some(log) = &writer.current {
                tracing::info!(path = %log.temp_path.display(), "flight log (ULog) open");
            }
        }
        report(writer.close());
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::commander::State;
    use crate::core::config::VehicleConfig;
    use crate::core::estimator::{EstimatorSource, GeoOrigin};
    use crate::core::mavlink::MavHeader;
    use crate::core::mavlink::command_long;
    use crate::core::mavlink::common::{MavCmd, MavMessage};
    use crate::core::vehicle::VehicleInputs;
    use crate::runtime::ulog::read_messages;

    const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

    fn scratch(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("autopilot-ulog-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn vehicle() -> Vehicle {
        let mut config = VehicleConfig::default();
        config.estimator.source = EstimatorSource::Truth;
        config.estimator.truth_origin = Some(GeoOrigin { lat_deg: 47.4, lon_deg: 8.5, alt_amsl_m: 488.0 });
        Vehicle::new(config).expect("valid")
    }

    fn at_rest(time_us: u64) -> VehicleInputs {
        VehicleInputs::at_rest_truth(time_us)
    }

    /// Steps the vehicle for `seconds` as the plant link does, the logger around each step.
    fn fly(v: &mut Vehicle, log: &mut FlightLogger, t_us: &mut u64, seconds: f64) {
        let end = *t_us + (seconds * 1e6) as u64;
        while *t_us < end {
            let out = v.step(*t_us, &at_rest(*t_us));
            log.begin_step(*t_us, v);
            for m in &out.messages {
                if let MavMessage::STATUSTEXT(s) = m {
                    log.text(*t_us, s.severity, s.text.to_str().unwrap_or(""));
                }
            }
            log.end_step(*t_us, v);
            *t_us += 2_000;
        }
    }

    fn drain(rx: &mut mpsc::Receiver<LogItem>, writer: &mut UlogWriter) -> Vec<PathBuf> {
        let mut closed = Vec::new();
        while let Ok(item) = rx.try_recv() {
            closed.extend(writer.handle(item).expect("written"));
        }
        closed
    }

    /// Data messages of a file, per topic name: (timestamp, payload).
    fn topics_of(bytes: &[u8]) -> std::collections::HashMap<String, Vec<Vec<u8>>> {
        let (_, msgs) = read_messages(bytes).expect("parses");
        let mut names = std::collections::HashMap::new();
        let mut data: std::collections::HashMap<String, Vec<Vec<u8>>> = std::collections::HashMap::new();
        for m in &msgs {
            match m.kind {
                b'A' => {
                    let id = u16::from_le_bytes([m.body[1], m.body[2]]);
                    names.insert(id, String::from_utf8(m.body[3..].to_vec()).expect("utf8"));
                }
                b'D' => {
                    let id = u16::from_le_bytes([m.body[0], m.body[1]]);
                    data.entry(names[&id].clone()).or_default().push(m.body[2..].to_vec());
                }
                _ => {}
            }
        }
        data
    }

    #[test]
    fn an_armed_flight_is_one_file_with_every_topic_at_its_rate_and_the_texts_as_logged_strings() {
        let root = scratch("flight");
        let (tx, mut rx) = mpsc::channel(ULOG_CHANNEL_CAPACITY);
        let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
        let mut writer = UlogWriter::default();
        let (mut v, mut t) = (vehicle(), 0);
        // GIVEN a vehicle on the ground: nothing is written while it is disarmed.
        fly(&mut v, &mut log, &mut t, 1.0);
        assert!(!log.logging());
        assert!(drain(&mut rx, &mut writer).is_empty() && !root.exists());
        // WHEN it arms, idles 2 s and disarms.
        let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        v.handle_message(t, &GCS, &arm);
        let armed_at = t;
        fly(&mut v, &mut log, &mut t, 2.0);
        assert!(log.logging());
        assert_eq!(v.commander().state(), State::ArmedIdle);
        let disarm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]);
        v.handle_message(t, &GCS, &disarm);
        fly(&mut v, &mut log, &mut t, 0.5);
        // THEN one file, finalized, under <root>/<date>/<time>.ulg.
        let closed = drain(&mut rx, &mut writer);
        assert_eq!(closed.len(), 1, "{closed:?}");
        assert!(!log.logging());
        let path = &closed[0];
        assert_eq!(path.extension().and_then(|e| e.to_str()), Some("ulg"));
        let date_dir = path.parent().expect("dir");
        assert_eq!(date_dir.parent(), Some(root.as_path()));
        assert_eq!(date_dir.file_name().and_then(|n| n.to_str()).map(str::len), Some(10), "YYYY-MM-DD");
        assert!(!path.with_extension("ulg.tmp").exists());
        let bytes = std::fs::read(path).expect("read");
        let (start_us, msgs) = read_messages(&bytes).expect("parses");
        assert_eq!(start_us, armed_at);
        assert_eq!(msgs[0].kind, b'B', "flag bits right after the header");
        let first_a = msgs.iter().position(|m| m.kind == b'A').expect("subscriptions");
        assert!(msgs[..first_a].iter().all(|m| b"BFIPQ".contains(&m.kind)), "definitions first");
        let params = msgs.iter().filter(|m| m.kind == b'P').count();
        assert_eq!(params, v.params().len(), "every parameter");
        let key = |m: &ulog::ReadMessage| String::from_utf8_lossy(&m.body[1..1 + usize::from(m.body[0])]).into_owned();
        assert!(msgs.iter().any(|m| m.kind == b'P' && key(m) == "int32_t SDLOG_MODE"));
        assert!(msgs.iter().any(|m| m.kind == b'P' && key(m) == "float MPC_XY_CRUISE"));
        let data = topics_of(&bytes);
        let count = |name: &str| data.get(name).map_or(0, Vec::len);
        // 2 s armed (and the disarming step): 50 Hz topics about 100 records, 10 Hz about 20, 5 Hz about 10.
        for (name, hz) in [("vehicle_attitude", 50), ("actuator_outputs", 50), ("controller_status", 50)] {
            assert!((2 * hz..=2 * hz + 2).contains(&count(name)), "{name}: {}", count(name));
        }
        for (name, hz) in [("aco_weights", 10), ("estimator_innovations", 10), ("battery_status", 5)] {
            assert!((2 * hz..=2 * hz + 2).contains(&count(name)), "{name}: {}", count(name));
        }
        // vehicle_status: at arming, once a second, and at the disarm: armed then disarmed (1).
        let status = &data["vehicle_status"];
        assert!(status.len() >= 3, "{}", status.len());
        assert_eq!(status[0][16], 2, "armed");
        assert_eq!(u64::from_le_bytes(status[0][8..16].try_into().expect("8")), armed_at, "armed_time");
        assert_eq!(status.last().map(|s| s[16]), Some(1), "disarmed at the end");
        // Every record is its format's size; attitude is the identity quaternion (w first).
        assert!(data["vehicle_attitude"].iter().all(|r| r[16..20] == 1.0f32.to_le_bytes()));
        let texts: Vec<String> = msgs
            .iter()
            .filter(|m| m.kind == b'L')
            .map(|m| String::from_utf8_lossy(&m.body[9..]).into_owned())
            .collect();
        assert_eq!(texts.first().map(String::as_str), Some("Armed"), "{texts:?}");
        assert!(texts.iter().any(|t| t == "Disarmed"), "{texts:?}");
        assert!(msgs.iter().any(|m| m.kind == b'S'), "sync markers");
        // A second flight is a second file.
        v.handle_message(t, &GCS, &arm);
        fly(&mut v, &mut log, &mut t, 0.2);
        log.close();
        assert_eq!(drain(&mut rx, &mut writer).len(), 1);
        assert_eq!(log.stats().flights, 2);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn sdlog_mode_minus_one_logs_nothing() {
        let root = scratch("off");
        let (tx, mut rx) = mpsc::channel(16);
        let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
        let (mut v, mut t) = (vehicle(), 0);
        let set = MavMessage::PARAM_SET(crate::core::mavlink::common::PARAM_SET_DATA {
            param_value: f32::from_le_bytes((-1i32).to_le_bytes()),
            target_system: 1,
            target_component: 1,
            param_id: "SDLOG_MODE".into(),
            param_type: crate::core::mavlink::common::MavParamType::MAV_PARAM_TYPE_INT32,
        });
        v.handle_message(t, &GCS, &set);
        assert_eq!(v.params().sdlog_mode(), -1);
        fly(&mut v, &mut log, &mut t, 0.5);
        let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        v.handle_message(t, &GCS, &arm);
        fly(&mut v, &mut log, &mut t, 0.5);
        assert!(v.commander_output().armed && !log.logging());
        assert!(rx.try_recv().is_err());
    }

    #[test]
    fn a_writer_that_falls_behind_costs_records_not_the_loop_and_says_so_with_a_dropout() {
        let root = scratch("behind");
        let (tx, mut rx) = mpsc::channel(4);
        let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
        let (mut v, mut t) = (vehicle(), 0);
        fly(&mut v, &mut log, &mut t, 0.5);
        let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        v.handle_message(t, &GCS, &arm);
        // Nobody drains the queue for 1 s: of the 50 batches (one per step with a 50 Hz topic due), all but
        // the four the queue holds are dropped, and no step waits.
        fly(&mut v, &mut log, &mut t, 1.0);
        assert!(log.stats().dropped >= 45, "{:?}", log.stats());
        let mut writer = UlogWriter::default();
        assert!(drain(&mut rx, &mut writer).is_empty());
        fly(&mut v, &mut log, &mut t, 0.04);
        log.close();
        let closed = drain(&mut rx, &mut writer);
        let bytes = std::fs::read(&closed[0]).expect("read");
        let (_, msgs) = read_messages(&bytes).expect("a file with a gap still parses");
        assert!(msgs.iter().any(|m| m.kind == b'O'), "a dropout marker");
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn two_flights_in_the_same_second_get_two_names() {
        let root = scratch("same-second");
        let mut writer = UlogWriter::default();
        let open =
            || LogItem::Open { dir: root.join("2026-12-02"), name: "14_31_05".into(), bytes: ulog::header(0).to_vec() };
        writer.handle(open()).expect("open");
        let a = writer.handle(LogItem::Close).expect("close").expect("path");
        writer.handle(open()).expect("open");
        let b = writer.handle(LogItem::Close).expect("close").expect("path");
        assert_eq!(a.file_name().and_then(|n| n.to_str()), Some("14_31_05.ulg"));
        assert_eq!(b.file_name().and_then(|n| n.to_str()), Some("14_31_05_1.ulg"));
        // Appending with no file open is ignored; a root that cannot be created is an error.
        assert!(writer.handle(LogItem::Append(vec![1, 2, 3])).expect("ignored").is_none());
        std::fs::write(root.join("file"), b"").expect("write");
        let bad = LogItem::Open { dir: root.join("file").join("x"), name: "n".into(), bytes: Vec::new() };
        assert!(matches!(writer.handle(bad), Err(FlightLogError::Create { .. })));
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn field_names_drop_the_controller_prefix_and_dots() {
        assert_eq!(field_name("aco.w_t_n"), "w_t_n");
        assert_eq!(field_name("ca.roll.k1"), "roll_k1");
        assert_eq!(field_name("plain"), "plain");
        // Every controller's telemetry gives distinct, plain field names.
        for kind in [ControllerKind::Aco, ControllerKind::Ca, ControllerKind::Pid] {
            let c = crate::core::control::new_controller(kind, &VehicleConfig::default().control);
            let names: Vec<String> = c.telemetry().iter().map(|(n, _)| field_name(n)).collect();
            let unique: std::collections::HashSet<&String> = names.iter().collect();
            assert_eq!(unique.len(), names.len(), "{kind}: {names:?}");
            assert!(names.iter().all(|n| !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')));
        }
        // Each topic's record matches its format for every controller.
        let v = vehicle();
        let snap = v.log_snapshot();
        let telemetry = v.controller().telemetry();
        let names: Vec<&'static str> = telemetry.iter().map(|(n, _)| *n).collect();
        let ctx = RecordContext { sysid: 1, armed_at_us: 0, telemetry: &telemetry, telemetry_names: &names };
        for (i, (name, _)) in TOPICS.iter().enumerate() {
            let topic = Topic::new(name, i as u16, fields(name, &names));
            assert!(topic.data(&record(name, 0, &snap, &ctx)).is_ok(), "{name}");
        }
    }
}
