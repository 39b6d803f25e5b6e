//! The flight log's sampler: on the plant-link thread, after each vehicle step, the topics due on
//! vehicle time, the vehicle's texts as logged strings, parameters changed in flight and sync markers,
//! handed to the writer without ever waiting (a batch the writer has no room for is dropped and counted).

use std::path::PathBuf;
use std::time::{SystemTime, UNIX_EPOCH};

use mavlink::dialects::common::MavSeverity;
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;

use super::LogItem;
use super::topics::{RecordContext, TOPICS, definitions, fields, logged, param_value, px4_nav_state, record};
use crate::core::control::ControllerKind;
use crate::core::vehicle::Vehicle;
use crate::runtime::ulog::{self, Topic};
use crate::runtime::utc::UtcTime;

/// Vehicle time between sync markers.
pub const SYNC_INTERVAL_US: u64 = 1_000_000;
/// Vehicle time between checks for parameters changed in flight.
pub const PARAM_CHECK_INTERVAL_US: u64 = 1_000_000;

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
    /// Sticks have been in use in this flight (`manual_control_setpoint` is logged from then on).
    manual_seen: bool,
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

    /// Before the step's messages are sent: a flight starts when the vehicle is armed, or a motor test
    /// spins a motor of the disarmed vehicle (and SDLOG_MODE is not -1), so that the step's "Armed" text
    /// is its first logged string and a bench test leaves a record of what the motors were told.
    pub fn begin_step(&mut self, now_us: u64, vehicle: &Vehicle) {
        if self.close_pending
            && let Some(tx) = &self.tx
            && tx.try_send(LogItem::Close).is_ok()
        {
            self.close_pending = false;
        }
        if self.tx.is_none() || self.flight.is_some() || !motors_running(vehicle) {
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

    /// After the step's messages: the topics due at `now_us`; when the motors stop (the vehicle disarmed,
    /// or the motor test ended), a last `vehicle_status` and the end of the flight.
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
        if let Some(snap) = snap.as_ref() {
            flight.manual_seen |= snap.manual.sticks.is_some();
        }
        for (i, topic) in flight.topics.iter().enumerate() {
            let Some(snap) = snap.as_ref() else { break };
            if now_us < flight.due_us[i] {
                continue;
            }
            let interval = flight.intervals_us[i];
            flight.due_us[i] =
                if now_us - flight.due_us[i] < interval { flight.due_us[i] + interval } else { now_us + interval };
            if !logged(&topic.name, snap, flight.manual_seen) {
                continue;
            }
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
        let ended = !motors_running(vehicle);
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
        let aco = vehicle.controller().kind() == ControllerKind::ACO;
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
            manual_seen: false,
        });
    }
}

/// Whether the motors run: armed, or a motor test on the disarmed vehicle.
fn motors_running(vehicle: &Vehicle) -> bool {
    vehicle.commander_output().armed || vehicle.motor_test_running()
}

fn wall_us() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

#[cfg(test)]
pub(crate) mod tests;
