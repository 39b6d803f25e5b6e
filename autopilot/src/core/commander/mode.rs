//! The commander's flight modes and health, in its own terms. How a PX4 vehicle puts them on the wire
//! (HEARTBEAT `custom_mode`, `base_mode`, `system_status`, EXTENDED_SYS_STATE `landed_state`) is the
//! MAVLink layer's business (`mavlink::identity`).

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::core::intent::ManualMode;

/// The flight modes this commander can be in. Modes it refuses (ACRO, AUTO READY) are not here: the
/// MAVLink layer (`mavlink::identity::Px4Mode`) names them for the refusal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FlightMode {
    /// ALTCTL: sticks to attitude, throttle to climb rate, the altitude held at centre.
    Altitude,
    /// POSCTL: sticks to velocity, the position held when centred.
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
    /// MANUAL: on a multicopter flown as Stabilized (as PX4 does).
    Manual,
    /// STABILIZED: sticks to attitude and yaw rate, throttle stick to thrust.
    Stabilized,
    /// ACRO: sticks to body rates, throttle stick to thrust; the attitude is not levelled.
    Acro,
}

impl FlightMode {
    /// How the sticks fly this mode, if it is a manual one (MANUAL, STABILIZED, ALTCTL, POSCTL).
    #[must_use]
    pub const fn manual(self) -> Option<ManualMode> {
        match self {
            Self::Manual | Self::Stabilized => Some(ManualMode::Stabilized),
            Self::Altitude => Some(ManualMode::Altitude),
            Self::Position => Some(ManualMode::Position),
            Self::Acro => Some(ManualMode::Acro),
            _ => None,
        }
    }

    /// Whether the pilot's sticks fly this mode.
    #[must_use]
    pub const fn is_manual(self) -> bool {
        self.manual().is_some()
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
            Self::Manual => "Manual",
            Self::Stabilized => "Stabilized",
            Self::Acro => "Acro",
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
