//! The vehicle's MAVLink microservices as sans-I/O handlers: no sockets, no clocks. In: a received
//! message with its [`MavHeader`] (for commands, answered at once with replies to the sender) and, once per
//! vehicle step, the vehicle time `now_us` (µs, the plant's sensor clock) with a [`TelemetrySnapshot`] and
//! the commander's [`Event`]s. Out: the [`MavMessage`]s to send, and for commands an [`InboundCommand`]
//! whose [`CommandEffect`] the vehicle applies to its commander (the "effect" of the message).
//!
//! - `identity`: HEARTBEAT as PX4 (QUADROTOR, PX4, commander's base/custom mode and status), 1 Hz of
//!   vehicle time and at once on any arm or mode change.
//! - `command`: COMMAND_LONG, COMMAND_INT and SET_MODE -> commander requests; COMMAND_ACK for every
//!   command, STATUSTEXT with the refusal text on DENIED, UNSUPPORTED for anything else.
//! - `failure`: MAV_CMD_INJECT_FAILURE (SYS_FAILURE_EN): forwarded to the plant, or the autopilot's own
//!   ground-station link and manual-control inputs switched off.
//! - `telemetry`: the default streams (SYS_STATUS, ATTITUDE(+_QUATERNION), LOCAL_POSITION_NED,
//!   GLOBAL_POSITION_INT, GPS_RAW_INT, EXTENDED_SYS_STATE, HOME_POSITION, VFR_HUD, BATTERY_STATUS) on
//!   vehicle time, and STATUSTEXT on events.
//! - `link_rate`: per ground-station link, the classes of the outgoing messages, the stream multiplier
//!   (data rate and RADIO_STATUS, as PX4's) and the byte pacer the shell's serial and UDP links write by.
//! - `units`: MAVLink's wire units (degE7, mm, cm/s, centi-units, milli-g, centidegrees), written once for
//!   these messages and the plant protocol (`core::plant_link`).
//! - While the plant link is lost no step comes: [`plant_lost_heartbeat`] and [`sys_status_plant_lost`]
//!   are what the vehicle reports instead, on the shell's wall-clock cadence (`Vehicle::plant_lost_telemetry`).

use ::mavlink::dialects::common::MavMessage;
use nalgebra::Vector3;

use crate::core::commander::Event;

pub mod command;
pub mod failure;
pub mod frame;
pub mod housekeeping;
pub mod identity;
pub mod link_rate;
pub mod manual;
pub mod mission;
pub mod offboard;
pub mod params;
pub mod router;
pub mod signing;
pub mod telemetry;
pub mod units;

/// The wire types of this API (so users need no direct dependency on the same `mavlink` version).
pub use ::mavlink::MavHeader;
pub use ::mavlink::dialects::common;

pub use command::{
    CommandContext, CommandEffect, CommandPoint, InboundCommand, MOTOR_COUNT, MOTOR_TEST_MAX_US, MotorTestRequest,
    VehicleCommand, command_long, command_replies, decode_command,
};
pub use identity::{gcs_heartbeat, heartbeat, plant_lost_heartbeat};
pub use telemetry::{
    Home, LinkErrors, Stream, StreamScheduler, TelemetrySnapshot, estimator_event_message, mission_current,
    nav_event_message, plant_link_event_message, statustext, statustext_chunks, sys_status_plant_lost,
};

/// The autopilot's component id (MAV_COMP_ID_AUTOPILOT1).
pub const AUTOPILOT_COMPONENT_ID: u8 = 1;

/// Interval of the HEARTBEAT (µs of vehicle time): 1 Hz.
pub const HEARTBEAT_INTERVAL_US: u64 = 1_000_000;

/// Whether a message for `(target_system, target_component)` is ours: our system or broadcast (0), and
/// our component or any (0; pymavlink sends 0).
#[must_use]
pub fn addressed_to_us(sysid: u8, target_system: u8, target_component: u8) -> bool {
    (target_system == sysid || target_system == 0)
        && (target_component == AUTOPILOT_COMPONENT_ID || target_component == 0)
}

/// The header of every message the vehicle sends: `sysid`, component 1. The sequence is the transport's.
#[must_use]
pub fn own_header(sysid: u8) -> MavHeader {
    MavHeader { system_id: sysid.into(), component_id: AUTOPILOT_COMPONENT_ID, sequence: 0 }
}

/// The MAVLink side of the vehicle's output: the heartbeat cadence and the stream scheduler. (Messages in
/// go through [`router`].)
#[derive(Debug, Clone, PartialEq)]
pub struct MavlinkService {
    sysid: u8,
    heartbeat_due_us: Option<u64>,
    streams: StreamScheduler,
    /// The home (NED m) last announced with HOME_POSITION.
    announced_home_ned_m: Option<Vector3<f64>>,
}

impl MavlinkService {
    /// A service for system `sysid` with the default stream rates.
    #[must_use]
    pub fn new(sysid: u8) -> Self {
        Self { sysid, heartbeat_due_us: None, streams: StreamScheduler::default(), announced_home_ned_m: None }
    }

    #[must_use]
    pub fn sysid(&self) -> u8 {
        self.sysid
    }

    /// The streams (to change a rate).
    pub fn streams_mut(&mut self) -> &mut StreamScheduler {
        &mut self.streams
    }

    #[must_use]
    pub fn streams(&self) -> &StreamScheduler {
        &self.streams
    }

    /// What is due at `now_us`: a HEARTBEAT (on its cadence, or at once when an event changed it), the
    /// STATUSTEXT of every event, then the telemetry streams that are due. The cadences advance here; the
    /// messages are built from a snapshot by [`Due::messages`].
    pub fn due(&mut self, now_us: u64, events: &[Event]) -> Due {
        let changed = events.iter().any(Event::changes_heartbeat);
        let heartbeat = changed || self.heartbeat_due_us.is_none_or(|due| now_us >= due);
        if heartbeat {
            self.heartbeat_due_us = Some(next_due_us(self.heartbeat_due_us, now_us, HEARTBEAT_INTERVAL_US, changed));
        }
        Due { heartbeat, streams: self.streams.due(now_us), home: false }
    }
}

impl MavlinkService {
    /// Home (NED m) counts as announced: it is news only when it moves from here.
    pub fn home_announced(&mut self, home_ned_m: Option<Vector3<f64>>) {
        self.announced_home_ned_m = home_ned_m;
    }

    /// What is due at `now_us` (see [`Self::due`]), and HOME_POSITION when home (`home_ned_m`, NED m)
    /// moved since it was last announced.
    pub fn due_with_home(&mut self, now_us: u64, events: &[Event], home_ned_m: Option<Vector3<f64>>) -> Due {
        let mut due = self.due(now_us, events);
        if home_ned_m.is_some() && home_ned_m != self.announced_home_ned_m {
            self.announced_home_ned_m = home_ned_m;
            due.home = true;
        }
        due
    }
}

/// The output due at one step (see [`MavlinkService::due`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Due {
    heartbeat: bool,
    streams: Vec<Stream>,
    /// HOME_POSITION, home having moved.
    home: bool,
}

impl Due {
    /// The messages: the HEARTBEAT if due, a STATUSTEXT per event, the due streams' messages, then
    /// HOME_POSITION if home moved.
    #[must_use]
    pub fn messages(&self, snapshot: &TelemetrySnapshot<'_>, events: &[Event]) -> Vec<MavMessage> {
        let mut out = Vec::new();
        if self.heartbeat {
            out.push(heartbeat(snapshot.commander));
        }
        out.extend(events.iter().map(|e| statustext(telemetry::event_severity(e), &e.text())));
        out.extend(self.streams.iter().flat_map(|s| s.messages(snapshot)));
        if self.home {
            out.extend(Stream::HomePosition.message(snapshot));
        }
        out
    }
}

/// The next due time after an emission at `now_us`: one interval after the previous due time (no drift),
/// or after `now_us` when restarting (first emission, an out-of-cadence emission, or having fallen behind
/// by more than one interval).
#[must_use]
pub(crate) fn next_due_us(previous_due_us: Option<u64>, now_us: u64, interval_us: u64, restart: bool) -> u64 {
    match previous_due_us {
        Some(due) if !restart && now_us >= due && now_us - due < interval_us => due + interval_us,
        _ => now_us.saturating_add(interval_us),
    }
}

#[cfg(test)]
mod tests;
