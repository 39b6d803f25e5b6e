//! The commander's flight modes and health, in its own terms. How a PX4 vehicle puts them on the wire
//! (HEARTBEAT `custom_mode`, `base_mode`, `system_status`, EXTENDED_SYS_STATE `landed_state`) is the
//! MAVLink layer's business (`mavlink::identity`).

use std::fmt;

use serde::{Deserialize, Serialize};

/// The flight modes this commander can be in. Modes it refuses (MANUAL, ACRO, STABILIZED, AUTO READY) are
/// not here: the MAVLink layer (`mavlink::identity::Px4Mode`) names them for the refusal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FlightMode {
    /// ALTCTL without sticks: hold the altitude (and, having no stick input, the position).
    Altitude,
    /// POSCTL without sticks: hold the position.
    Position,
    /// AUTO TAKEOFF.
    Takeoff,
    /// AUTO LOITER, "Hold" in QGroundControl.
    Hold,
    /// AUTO LAND.
    Land,
    /// AUTO MISSION: fly the uploaded mission.
    Mission,
    /// AUTO RTL: climb, return above home, land.
    ReturnToLaunch,
    /// OFFBOARD: fly the setpoints a companion or ground station streams.
    Offboard,
}

impl FlightMode {
    /// Whether this is a position-holding mode (the target of a Hold-like request).
    #[must_use]
    pub const fn is_hold_like(self) -> bool {
        matches!(self, Self::Altitude | Self::Position | Self::Hold)
    }
}

impl fmt::Display for FlightMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Altitude => "Altitude",
            Self::Position => "Position",
            Self::Takeoff => "Takeoff",
            Self::Hold => "Hold",
            Self::Land => "Land",
            Self::Mission => "Mission",
            Self::ReturnToLaunch => "Return",
            Self::Offboard => "Offboard",
        })
    }
}

/// How the vehicle is, for a ground station (HEARTBEAT `system_status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SystemStatus {
    /// Disarmed, ready.
    Standby,
    /// Armed and flying normally.
    Active,
    /// Armed without a usable position.
    Critical,
    /// Killed.
    Emergency,
}
