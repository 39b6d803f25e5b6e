//! The small link services, sans-I/O. In: a received message (PING, FILE_TRANSFER_PROTOCOL) with the
//! sender's header, or the vehicle's identity. Out: the reply to the sender, or the message to send:
//!
//! - PING (#4): answered with the same `time_usec` and `seq`, addressed to the sender.
//! - FILE_TRANSFER_PROTOCOL (#110): there is no file system to serve; every request is answered with a NAK
//!   "file not found" (error 10), so MAVProxy falls back to the parameter protocol in about a second
//!   instead of waiting ~11 s for FTP to time out.
//! - AUTOPILOT_VERSION (#148): PX4's identity: capabilities MISSION_INT, COMMAND_INT, MAVLINK2,
//!   PARAM_ENCODE_BYTEWISE (integer parameters are INT32 in PX4's bytewise encoding, see
//!   [`super::params`]; not PARAM_ENCODE_C_CAST), SET_POSITION_TARGET_LOCAL_NED/GLOBAL_INT, SET_ATTITUDE_TARGET,
//!   FLIGHT_TERMINATION, MISSION_FENCE and MISSION_RALLY (no FTP: there is no file system); flight software
//!   1.15.0 in PX4's encoding `(major << 24) | (minor << 16) | (patch << 8) | 0xFF` (a release).
//! - MESSAGE_INTERVAL (#244): the answer to GET_MESSAGE_INTERVAL.

// PING is deprecated in the dialect in favour of TIMESYNC, but MAVProxy still sends it.
#![allow(deprecated)]

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{
    AUTOPILOT_VERSION_DATA, FILE_TRANSFER_PROTOCOL_DATA, MESSAGE_INTERVAL_DATA, MavMessage, MavProtocolCapability,
    PING_DATA,
};

use super::addressed_to_us;

/// PX4 1.15.0, a release build.
pub const FLIGHT_SW_VERSION: u32 = (1 << 24) | (15 << 16) | 0xFF;

/// FTP opcode of a NAK.
const FTP_NAK: u8 = 129;
/// FTP error "file not found".
const FTP_ERR_FILE_NOT_FOUND: u8 = 10;

/// AUTOPILOT_VERSION for system `sysid` (its `uid` is derived from the system id, stable across runs).
#[must_use]
pub fn autopilot_version(sysid: u8) -> MavMessage {
    use MavProtocolCapability as C;
    let capabilities = C::MAV_PROTOCOL_CAPABILITY_MISSION_INT
        | C::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
        | C::MAV_PROTOCOL_CAPABILITY_MAVLINK2
        | C::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
        | C::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
        | C::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
        | C::MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
        | C::MAV_PROTOCOL_CAPABILITY_FLIGHT_TERMINATION
        | C::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
        | C::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY;
    MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
        capabilities,
        uid: 0x4143_4F00_0000_0000 | u64::from(sysid),
        flight_sw_version: FLIGHT_SW_VERSION,
        middleware_sw_version: FLIGHT_SW_VERSION,
        os_sw_version: 0,
        board_version: 0,
        vendor_id: 0,
        product_id: 0,
        flight_custom_version: *b"aco-sitl",
        middleware_custom_version: [0; 8],
        os_custom_version: [0; 8],
        ..Default::default()
    })
}

/// MESSAGE_INTERVAL for `message_id`: `interval_us` µs, 0 for "not streamed" is reported as -1.
#[must_use]
pub fn message_interval(message_id: u32, interval_us: Option<u64>) -> MavMessage {
    let interval_us = match interval_us {
        Some(0) | None => -1,
        Some(us) => i32::try_from(us).unwrap_or(i32::MAX),
    };
    MavMessage::MESSAGE_INTERVAL(MESSAGE_INTERVAL_DATA {
        interval_us,
        message_id: u16::try_from(message_id).unwrap_or(u16::MAX),
    })
}

/// The reply of system `sysid` to a PING or FTP request, if `msg` is one addressed to it.
#[must_use]
pub fn reply(sysid: u8, header: &MavHeader, msg: &MavMessage) -> Option<MavMessage> {
    let sender_system = u8::try_from(header.system_id).unwrap_or(u8::MAX);
    match msg {
        // A PING to everyone (0/0) is a request; one addressed elsewhere is not ours.
        MavMessage::PING(p) if p.target_system == 0 || addressed_to_us(sysid, p.target_system, p.target_component) => {
            Some(MavMessage::PING(PING_DATA {
                time_usec: p.time_usec,
                seq: p.seq,
                target_system: sender_system,
                target_component: header.component_id,
            }))
        }
        MavMessage::FILE_TRANSFER_PROTOCOL(f) if addressed_to_us(sysid, f.target_system, f.target_component) => {
            let request = &f.payload;
            let seq = u16::from_le_bytes([request[0], request[1]]).wrapping_add(1);
            let mut payload = [0u8; 251];
            payload[0..2].copy_from_slice(&seq.to_le_bytes());
            payload[2] = request[2]; // session
            payload[3] = FTP_NAK;
            payload[4] = 1; // size of the data: the error code
            payload[5] = request[3]; // the opcode being answered
            payload[12] = FTP_ERR_FILE_NOT_FOUND;
            Some(MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
                target_network: 0,
                target_system: sender_system,
                target_component: header.component_id,
                payload,
            }))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

    #[test]
    fn given_a_ping_when_answered_then_its_time_and_seq_come_back_to_the_sender() {
        let ping = MavMessage::PING(PING_DATA { time_usec: 1234, seq: 7, target_system: 0, target_component: 0 });
        let Some(MavMessage::PING(p)) = reply(1, &GCS, &ping) else { panic!("no PING reply") };
        assert_eq!((p.time_usec, p.seq, p.target_system, p.target_component), (1234, 7, 255, 190));
        let elsewhere = MavMessage::PING(PING_DATA { time_usec: 1, seq: 1, target_system: 9, target_component: 1 });
        assert_eq!(reply(1, &GCS, &elsewhere), None);
    }

    #[test]
    fn given_an_ftp_request_when_answered_then_a_nak_file_not_found_for_its_opcode_and_seq() {
        let mut payload = [0u8; 251];
        payload[0..2].copy_from_slice(&41u16.to_le_bytes());
        payload[2] = 3;
        payload[3] = 4; // OpenFileRO
        let ftp = MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: 1,
            target_component: 1,
            payload,
        });
        let Some(MavMessage::FILE_TRANSFER_PROTOCOL(f)) = reply(1, &GCS, &ftp) else { panic!("no NAK") };
        assert_eq!(u16::from_le_bytes([f.payload[0], f.payload[1]]), 42);
        assert_eq!((f.payload[2], f.payload[3], f.payload[4], f.payload[5], f.payload[12]), (3, 129, 1, 4, 10));
        assert_eq!((f.target_system, f.target_component), (255, 190));
    }

    #[test]
    fn given_the_identity_then_px4_1_15_with_mission_int_command_int_mavlink2_bytewise_fence_rally_and_no_ftp() {
        let MavMessage::AUTOPILOT_VERSION(v) = autopilot_version(3) else { panic!("not AUTOPILOT_VERSION") };
        assert_eq!(v.flight_sw_version >> 8, 0x01_0F_00);
        let c = v.capabilities;
        assert!(c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT));
        assert!(c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT));
        assert!(c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2));
        // Integer parameters travel as INT32 with their bytes as they are (crate::core::mavlink::params), as
        // PX4's do; C_CAST would tell clients to convert the value to a float instead.
        assert!(c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE));
        assert!(!c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST));
        assert!(!c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FTP));
        assert!(c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE));
        assert!(c.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY));
        assert_eq!(v.uid & 0xff, 3);
    }
}
