//! PX4 flight modes and the MAVLink numbers a PX4 vehicle reports, as plain integers (no mavlink types
//! here): `custom_mode = (main << 16) | (sub << 24)`, the HEARTBEAT `base_mode` flags and
//! `system_status`, and EXTENDED_SYS_STATE `landed_state` (see `mavlink-surface.md`).

use std::fmt;

use serde::{Deserialize, Serialize};

/// PX4 main modes (`custom_mode` bits 16-23).
pub mod main_mode {
    pub const MANUAL: u8 = 1;
    pub const ALTCTL: u8 = 2;
    pub const POSCTL: u8 = 3;
    pub const AUTO: u8 = 4;
    pub const ACRO: u8 = 5;
    pub const OFFBOARD: u8 = 6;
    pub const STABILIZED: u8 = 7;
}

/// PX4 AUTO sub-modes (`custom_mode` bits 24-31).
pub mod auto_sub_mode {
    pub const READY: u8 = 1;
    pub const TAKEOFF: u8 = 2;
    pub const LOITER: u8 = 3;
    pub const MISSION: u8 = 4;
    pub const RTL: u8 = 5;
    pub const LAND: u8 = 6;
}

/// HEARTBEAT `base_mode` flags (MAV_MODE_FLAG).
pub mod base_mode_flag {
    pub const CUSTOM_MODE_ENABLED: u8 = 1;
    pub const AUTO_ENABLED: u8 = 4;
    pub const GUIDED_ENABLED: u8 = 8;
    pub const STABILIZE_ENABLED: u8 = 16;
    pub const MANUAL_INPUT_ENABLED: u8 = 64;
    pub const SAFETY_ARMED: u8 = 128;
}

/// HEARTBEAT `system_status` (MAV_STATE).
pub mod system_status {
    pub const STANDBY: u8 = 3;
    pub const ACTIVE: u8 = 4;
    pub const CRITICAL: u8 = 5;
    pub const EMERGENCY: u8 = 6;
}

/// The flight modes this commander can be in. Modes it refuses (MANUAL, ACRO, STABILIZED, AUTO READY) are
/// not here: [`Px4Mode::decode`] names them for the refusal.
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
    /// PX4 (main, sub).
    #[must_use]
    pub const fn px4(self) -> (u8, u8) {
        match self {
            Self::Altitude => (main_mode::ALTCTL, 0),
            Self::Position => (main_mode::POSCTL, 0),
            Self::Takeoff => (main_mode::AUTO, auto_sub_mode::TAKEOFF),
            Self::Hold => (main_mode::AUTO, auto_sub_mode::LOITER),
            Self::Land => (main_mode::AUTO, auto_sub_mode::LAND),
            Self::Mission => (main_mode::AUTO, auto_sub_mode::MISSION),
            Self::ReturnToLaunch => (main_mode::AUTO, auto_sub_mode::RTL),
            Self::Offboard => (main_mode::OFFBOARD, 0),
        }
    }

    /// HEARTBEAT `custom_mode`: `(main << 16) | (sub << 24)`.
    #[must_use]
    pub const fn custom_mode(self) -> u32 {
        let (main, sub) = self.px4();
        custom_mode(main, sub)
    }

    /// HEARTBEAT `base_mode` for this mode, as PX4 sets it: CUSTOM_MODE_ENABLED, the mode's
    /// MANUAL_INPUT / STABILIZE / GUIDED / AUTO flags, and SAFETY_ARMED when armed.
    #[must_use]
    pub const fn base_mode(self, armed: bool) -> u8 {
        use base_mode_flag as f;
        let mode_flags = match self {
            Self::Altitude => f::MANUAL_INPUT_ENABLED | f::STABILIZE_ENABLED,
            Self::Position => f::MANUAL_INPUT_ENABLED | f::STABILIZE_ENABLED | f::GUIDED_ENABLED,
            Self::Takeoff | Self::Hold | Self::Land | Self::Mission | Self::ReturnToLaunch | Self::Offboard => {
                f::AUTO_ENABLED | f::GUIDED_ENABLED | f::STABILIZE_ENABLED
            }
        };
        f::CUSTOM_MODE_ENABLED | mode_flags | if armed { f::SAFETY_ARMED } else { 0 }
    }

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

/// `(main << 16) | (sub << 24)`.
#[must_use]
pub const fn custom_mode(main: u8, sub: u8) -> u32 {
    ((main as u32) << 16) | ((sub as u32) << 24)
}

/// A PX4 (main, sub) pair as a ground station sends it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Px4Mode {
    /// A mode this commander flies.
    Supported(FlightMode),
    /// A known PX4 mode this commander does not fly yet: its name and why.
    Unsupported { name: &'static str, reason: &'static str },
    /// Not a PX4 mode.
    Unknown,
}

impl Px4Mode {
    /// Decodes PX4's (main, sub).
    #[must_use]
    pub const fn decode(main: u8, sub: u8) -> Self {
        use auto_sub_mode as a;
        use main_mode as m;
        match (main, sub) {
            (m::ALTCTL, 0) => Self::Supported(FlightMode::Altitude),
            (m::POSCTL, 0) => Self::Supported(FlightMode::Position),
            (m::AUTO, a::TAKEOFF) => Self::Supported(FlightMode::Takeoff),
            (m::AUTO, a::LOITER) => Self::Supported(FlightMode::Hold),
            (m::AUTO, a::LAND) => Self::Supported(FlightMode::Land),
            (m::AUTO, a::RTL) => Self::Supported(FlightMode::ReturnToLaunch),
            (m::AUTO, a::MISSION) => Self::Supported(FlightMode::Mission),
            (m::AUTO, a::READY) => Self::Unsupported { name: "AUTO READY", reason: "use Hold" },
            (m::OFFBOARD, _) => Self::Supported(FlightMode::Offboard),
            (m::MANUAL, _) => Self::Unsupported { name: "MANUAL", reason: "needs RC sticks" },
            (m::ACRO, _) => Self::Unsupported { name: "ACRO", reason: "needs RC sticks" },
            (m::STABILIZED, _) => Self::Unsupported { name: "STABILIZED", reason: "needs RC sticks" },
            _ => Self::Unknown,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_each_mode_when_encoded_then_custom_mode_is_px4s() {
        assert_eq!(FlightMode::Hold.custom_mode(), 0x0304_0000);
        assert_eq!(FlightMode::Hold.custom_mode(), (4 << 16) | (3 << 24));
        assert_eq!(FlightMode::Takeoff.custom_mode(), 0x0204_0000);
        assert_eq!(FlightMode::Land.custom_mode(), 0x0604_0000);
        assert_eq!(FlightMode::Position.custom_mode(), 0x0003_0000);
        assert_eq!(FlightMode::Altitude.custom_mode(), 0x0002_0000);
        assert_eq!(custom_mode(main_mode::OFFBOARD, 0), 0x0006_0000);
        assert_eq!(custom_mode(main_mode::AUTO, auto_sub_mode::MISSION), 0x0404_0000);
        assert_eq!(custom_mode(main_mode::AUTO, auto_sub_mode::RTL), 0x0504_0000);
    }

    #[test]
    fn given_each_supported_mode_when_decoded_from_its_encoding_then_it_round_trips() {
        for m in [
            FlightMode::Altitude,
            FlightMode::Position,
            FlightMode::Takeoff,
            FlightMode::Hold,
            FlightMode::Land,
            FlightMode::Mission,
            FlightMode::ReturnToLaunch,
            FlightMode::Offboard,
        ] {
            let (main, sub) = m.px4();
            assert_eq!(Px4Mode::decode(main, sub), Px4Mode::Supported(m));
        }
    }

    #[test]
    fn given_modes_not_flown_when_decoded_then_they_are_named_not_supported() {
        assert!(matches!(Px4Mode::decode(1, 0), Px4Mode::Unsupported { name: "MANUAL", .. }));
        assert!(matches!(Px4Mode::decode(4, 1), Px4Mode::Unsupported { name: "AUTO READY", .. }));
        assert_eq!(Px4Mode::decode(4, 4), Px4Mode::Supported(FlightMode::Mission));
        assert_eq!(Px4Mode::decode(4, 5), Px4Mode::Supported(FlightMode::ReturnToLaunch));
        assert_eq!(Px4Mode::decode(6, 0), Px4Mode::Supported(FlightMode::Offboard));
        assert_eq!(Px4Mode::decode(9, 0), Px4Mode::Unknown);
        assert_eq!(Px4Mode::decode(4, 0), Px4Mode::Unknown);
        assert_eq!(Px4Mode::decode(3, 1), Px4Mode::Unknown);
    }

    #[test]
    fn given_armed_or_disarmed_when_base_mode_is_built_then_safety_armed_follows_and_custom_mode_is_set() {
        let armed = FlightMode::Hold.base_mode(true);
        let disarmed = FlightMode::Hold.base_mode(false);
        assert_eq!(armed, 1 | 4 | 8 | 16 | 128);
        assert_eq!(disarmed, 1 | 4 | 8 | 16);
        assert_eq!(FlightMode::Position.base_mode(false), 1 | 8 | 16 | 64);
        assert_eq!(FlightMode::Altitude.base_mode(true), 1 | 16 | 64 | 128);
    }
}
