//! The vehicle's identity on the wire: a PX4 quadrotor. In: the commander's output (flight mode, armed,
//! health, landed state). Out: the HEARTBEAT (type QUADROTOR 2, autopilot PX4 12, MAVLink version 3, PX4's
//! `custom_mode = (main << 16) | (sub << 24)` and `base_mode` flags, MAV_STATE), EXTENDED_SYS_STATE's
//! landed state, and the decoding of the PX4 (main, sub) a ground station asks for. These encodings live
//! here only; the commander knows modes, not numbers. The cadence (1 Hz of vehicle time, at once on a
//! change) is kept by `MavlinkService`. While the plant link is lost the shell sends
//! [`plant_lost_heartbeat`] on its own wall-clock cadence instead (`system_status` CRITICAL, EMERGENCY
//! when armed).

use ::mavlink::dialects::common::{
    HEARTBEAT_DATA, MavAutopilot, MavLandedState, MavMessage, MavModeFlag, MavState, MavType,
};

use crate::core::commander::{CommanderOutput, FlightMode, LandedState, SystemStatus};

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

/// PX4's (main, sub) of a flight mode.
#[must_use]
pub const fn px4_mode(mode: FlightMode) -> (u8, u8) {
    use auto_sub_mode as a;
    use main_mode as m;
    match mode {
        FlightMode::Altitude => (m::ALTCTL, 0),
        FlightMode::Position => (m::POSCTL, 0),
        FlightMode::Takeoff => (m::AUTO, a::TAKEOFF),
        FlightMode::Hold => (m::AUTO, a::LOITER),
        FlightMode::Land => (m::AUTO, a::LAND),
        FlightMode::Mission => (m::AUTO, a::MISSION),
        FlightMode::ReturnToLaunch => (m::AUTO, a::RTL),
        FlightMode::Offboard => (m::OFFBOARD, 0),
        FlightMode::Manual => (m::MANUAL, 0),
        FlightMode::Stabilized => (m::STABILIZED, 0),
        FlightMode::Acro => (m::ACRO, 0),
    }
}

/// `(main << 16) | (sub << 24)`.
#[must_use]
pub const fn custom_mode_of(main: u8, sub: u8) -> u32 {
    ((main as u32) << 16) | ((sub as u32) << 24)
}

/// HEARTBEAT `custom_mode` of a flight mode.
#[must_use]
pub const fn custom_mode(mode: FlightMode) -> u32 {
    let (main, sub) = px4_mode(mode);
    custom_mode_of(main, sub)
}

/// HEARTBEAT `base_mode` as PX4 sets it: CUSTOM_MODE_ENABLED, the mode's MANUAL_INPUT / STABILIZE /
/// GUIDED / AUTO flags, and SAFETY_ARMED when armed.
#[must_use]
pub fn base_mode(mode: FlightMode, armed: bool) -> MavModeFlag {
    use MavModeFlag as F;
    let mode_flags = match mode {
        FlightMode::Manual | FlightMode::Acro => F::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
        FlightMode::Stabilized | FlightMode::Altitude => {
            F::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | F::MAV_MODE_FLAG_STABILIZE_ENABLED
        }
        FlightMode::Position => {
            F::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | F::MAV_MODE_FLAG_STABILIZE_ENABLED | F::MAV_MODE_FLAG_GUIDED_ENABLED
        }
        FlightMode::Takeoff
        | FlightMode::Hold
        | FlightMode::Land
        | FlightMode::Mission
        | FlightMode::ReturnToLaunch
        | FlightMode::Offboard => {
            F::MAV_MODE_FLAG_AUTO_ENABLED | F::MAV_MODE_FLAG_GUIDED_ENABLED | F::MAV_MODE_FLAG_STABILIZE_ENABLED
        }
    };
    let armed = if armed { F::MAV_MODE_FLAG_SAFETY_ARMED } else { F::empty() };
    F::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mode_flags | armed
}

/// A PX4 (main, sub) pair as a ground station sends it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Px4Mode {
    /// A mode this vehicle flies.
    Supported(FlightMode),
    /// A known PX4 mode this vehicle does not fly: its name and why.
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
            (m::MANUAL, _) => Self::Supported(FlightMode::Manual),
            (m::ACRO, _) => Self::Supported(FlightMode::Acro),
            (m::STABILIZED, _) => Self::Supported(FlightMode::Stabilized),
            _ => Self::Unknown,
        }
    }
}

/// MAV_STATE of the vehicle's health.
#[must_use]
pub const fn mav_state(status: SystemStatus) -> MavState {
    match status {
        SystemStatus::Standby => MavState::MAV_STATE_STANDBY,
        SystemStatus::Active => MavState::MAV_STATE_ACTIVE,
        SystemStatus::Critical => MavState::MAV_STATE_CRITICAL,
        SystemStatus::Emergency => MavState::MAV_STATE_EMERGENCY,
    }
}

/// MAV_LANDED_STATE of the landed state.
#[must_use]
pub const fn mav_landed_state(landed: LandedState) -> MavLandedState {
    match landed {
        LandedState::Undefined => MavLandedState::MAV_LANDED_STATE_UNDEFINED,
        LandedState::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
        LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
        LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
        LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
    }
}

/// The HEARTBEAT for the commander's current output.
#[must_use]
pub fn heartbeat(commander: &CommanderOutput) -> MavMessage {
    MavMessage::HEARTBEAT(heartbeat_data(commander))
}

/// MAV_STATE while the plant link is lost (no sensor sample, no step, the motors commanded to their
/// minimum by the shell): EMERGENCY when armed, as the vehicle may be in the air with no sensors and no
/// motors; CRITICAL when disarmed, as it can neither sense nor fly until the plant returns. Never STANDBY
/// or ACTIVE: a ground station must see that the vehicle is not usable.
#[must_use]
pub const fn plant_lost_state(armed: bool) -> MavState {
    if armed { MavState::MAV_STATE_EMERGENCY } else { MavState::MAV_STATE_CRITICAL }
}

/// The HEARTBEAT a ground station sends once a second (MAV_TYPE_GCS, autopilot INVALID): what the vehicle
/// counts as a ground station for the datalink failsafe (`router::GcsHeartbeats`).
#[must_use]
pub fn gcs_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// The HEARTBEAT while the plant link is lost: the commander's last mode and armed flag as
/// [`heartbeat`] sends them, with `system_status` from [`plant_lost_state`].
#[must_use]
pub fn plant_lost_heartbeat(commander: &CommanderOutput) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        system_status: plant_lost_state(commander.armed),
        ..heartbeat_data(commander)
    })
}

fn heartbeat_data(commander: &CommanderOutput) -> HEARTBEAT_DATA {
    HEARTBEAT_DATA {
        custom_mode: custom_mode(commander.mode),
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: base_mode(commander.mode, commander.armed),
        system_status: mav_state(commander.status),
        mavlink_version: 3,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [FlightMode; 10] = [
        FlightMode::Stabilized,
        FlightMode::Acro,
        FlightMode::Altitude,
        FlightMode::Position,
        FlightMode::Takeoff,
        FlightMode::Hold,
        FlightMode::Land,
        FlightMode::Mission,
        FlightMode::ReturnToLaunch,
        FlightMode::Offboard,
    ];

    #[test]
    fn given_each_mode_when_encoded_then_custom_mode_is_px4s() {
        assert_eq!(custom_mode(FlightMode::Hold), 0x0304_0000);
        assert_eq!(custom_mode(FlightMode::Hold), (4 << 16) | (3 << 24));
        assert_eq!(custom_mode(FlightMode::Takeoff), 0x0204_0000);
        assert_eq!(custom_mode(FlightMode::Land), 0x0604_0000);
        assert_eq!(custom_mode(FlightMode::Position), 0x0003_0000);
        assert_eq!(custom_mode(FlightMode::Altitude), 0x0002_0000);
        assert_eq!(custom_mode(FlightMode::Offboard), 0x0006_0000);
        assert_eq!(custom_mode(FlightMode::Mission), 0x0404_0000);
        assert_eq!(custom_mode(FlightMode::ReturnToLaunch), 0x0504_0000);
        assert_eq!(custom_mode(FlightMode::Acro), 0x0005_0000);
    }

    #[test]
    fn given_each_supported_mode_when_decoded_from_its_encoding_then_it_round_trips() {
        for m in ALL {
            let (main, sub) = px4_mode(m);
            assert_eq!(Px4Mode::decode(main, sub), Px4Mode::Supported(m));
        }
    }

    #[test]
    fn given_modes_not_flown_when_decoded_then_they_are_named_not_supported() {
        assert_eq!(Px4Mode::decode(5, 0), Px4Mode::Supported(FlightMode::Acro));
        assert_eq!(Px4Mode::decode(1, 0), Px4Mode::Supported(FlightMode::Manual));
        assert_eq!(Px4Mode::decode(7, 0), Px4Mode::Supported(FlightMode::Stabilized));
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
        assert_eq!(base_mode(FlightMode::Hold, true).bits(), 1 | 4 | 8 | 16 | 128);
        assert_eq!(base_mode(FlightMode::Hold, false).bits(), 1 | 4 | 8 | 16);
        assert_eq!(base_mode(FlightMode::Position, false).bits(), 1 | 8 | 16 | 64);
        assert_eq!(base_mode(FlightMode::Altitude, true).bits(), 1 | 16 | 64 | 128);
    }

    #[test]
    fn given_the_landed_states_and_health_then_mavlinks_numbers() {
        let landed = [LandedState::Undefined, LandedState::OnGround, LandedState::InAir, LandedState::Takeoff];
        let numbers: Vec<u8> = landed.iter().map(|l| mav_landed_state(*l) as u8).collect();
        assert_eq!(numbers, [0, 1, 2, 3]);
        assert_eq!(mav_landed_state(LandedState::Landing) as u8, 4);
        assert_eq!(mav_state(SystemStatus::Standby) as u8, 3);
        assert_eq!(mav_state(SystemStatus::Emergency) as u8, 6);
    }
}
