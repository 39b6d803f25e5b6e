//! The vehicle's identity: a PX4 quadrotor. In: the commander's output (base_mode flags, PX4 custom_mode,
//! MAV_STATE). Out: the HEARTBEAT (type QUADROTOR 2, autopilot PX4 12, MAVLink version 3); the cadence (1 Hz
//! of vehicle time, at once on a change) is kept by `MavlinkService`.

use ::mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType};

use crate::core::commander::CommanderOutput;

/// MAV_STATE from its number (unknown numbers report UNINIT).
#[must_use]
pub fn mav_state(system_status: u8) -> MavState {
    match system_status {
        1 => MavState::MAV_STATE_BOOT,
        2 => MavState::MAV_STATE_CALIBRATING,
        3 => MavState::MAV_STATE_STANDBY,
        4 => MavState::MAV_STATE_ACTIVE,
        5 => MavState::MAV_STATE_CRITICAL,
        6 => MavState::MAV_STATE_EMERGENCY,
        7 => MavState::MAV_STATE_POWEROFF,
        8 => MavState::MAV_STATE_FLIGHT_TERMINATION,
        _ => MavState::MAV_STATE_UNINIT,
    }
}

/// The HEARTBEAT for the commander's current output.
#[must_use]
pub fn heartbeat(commander: &CommanderOutput) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: commander.custom_mode,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: MavModeFlag::from_bits_truncate(commander.base_mode),
        system_status: mav_state(commander.system_status),
        mavlink_version: 3,
    })
}
