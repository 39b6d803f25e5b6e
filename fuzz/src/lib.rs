//! What the fuzz targets share: ground-station messages built from the fuzzer's bytes with `arbitrary`
//! (the messages each service answers, addressed to the vehicle, with the numbers that break code: NaN,
//! infinities, huge values), and the invariants checked on the vehicle after every step.

// The deprecated mission and mode messages are what older ground stations still send: they are inputs.
#![allow(deprecated)]

use arbitrary::{Arbitrary, Result, Unstructured};
use autopilot::core::mavlink::common::{
    COMMAND_INT_DATA, HEARTBEAT_DATA, MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA,
    MISSION_SET_CURRENT_DATA, MavCmd, MavFrame, MavMessage, MavMissionResult, MavMissionType, MavParamType,
    PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA, PositionTargetTypemask, SET_ATTITUDE_TARGET_DATA,
    SET_MODE_DATA, SET_POSITION_TARGET_GLOBAL_INT_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use autopilot::core::mavlink::{command_long, gcs_heartbeat};
use autopilot::core::params::PARAMS;
use autopilot::core::vehicle::{Vehicle, VehicleOutputs};

/// The vehicle's system id in every target (instance 0).
pub const SYSID: u8 = 1;

/// A float as a fuzzer should pick it: mostly ordinary (-30..30, a flight's scale), often an edge of f32.
#[derive(Debug, Clone, Copy)]
pub struct Num(pub f32);

impl<'a> Arbitrary<'a> for Num {
    fn arbitrary(u: &mut Unstructured<'a>) -> Result<Self> {
        Ok(Self(match u.int_in_range(0_u8..=11)? {
            0..=4 => f32::from(u.int_in_range(-3000_i16..=3000)?) * 0.01,
            5 => f32::NAN,
            6 => f32::INFINITY,
            7 => f32::NEG_INFINITY,
            8 => 1e30,
            9 => -1e30,
            10 => 21196.0, // the ARM command's "force" magic
            _ => f32::arbitrary(u)?,
        }))
    }
}

/// A count or sequence number: mostly small (a plan of a few items), sometimes any u16.
#[derive(Debug, Clone, Copy)]
pub struct Small(pub u16);

impl<'a> Arbitrary<'a> for Small {
    fn arbitrary(u: &mut Unstructured<'a>) -> Result<Self> {
        Ok(Self(if u.ratio(7_u8, 8)? { u.int_in_range(0..=8)? } else { u16::arbitrary(u)? }))
    }
}

/// The commands a ground station sends a flying vehicle, then any command at all.
const COMMANDS: [MavCmd; 16] = [
    MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
    MavCmd::MAV_CMD_DO_SET_MODE,
    MavCmd::MAV_CMD_NAV_TAKEOFF,
    MavCmd::MAV_CMD_NAV_LAND,
    MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MavCmd::MAV_CMD_DO_REPOSITION,
    MavCmd::MAV_CMD_MISSION_START,
    MavCmd::MAV_CMD_DO_CHANGE_SPEED,
    MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
    MavCmd::MAV_CMD_REQUEST_MESSAGE,
    MavCmd::MAV_CMD_NAV_LOITER_UNLIM,
    MavCmd::MAV_CMD_DO_SET_HOME,
    MavCmd::MAV_CMD_DO_SET_MISSION_CURRENT,
    MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
    MavCmd::MAV_CMD_DO_FLIGHTTERMINATION,
    MavCmd::MAV_CMD_CONDITION_YAW,
];

/// A command id: one of [`COMMANDS`] mostly, any otherwise.
#[derive(Debug, Clone, Copy)]
pub struct Command(pub MavCmd);

impl<'a> Arbitrary<'a> for Command {
    fn arbitrary(u: &mut Unstructured<'a>) -> Result<Self> {
        Ok(Self(if u.ratio(7_u8, 8)? { *u.choose(&COMMANDS)? } else { MavCmd::arbitrary(u)? }))
    }
}

/// A parameter name: one of the vehicle's mostly, else any 16 bytes.
#[derive(Debug, Clone, Copy)]
pub struct ParamName(pub [u8; 16]);

impl<'a> Arbitrary<'a> for ParamName {
    fn arbitrary(u: &mut Unstructured<'a>) -> Result<Self> {
        if u.ratio(7_u8, 8)? {
            let name = u.choose(*PARAMS)?.name.as_bytes();
            let mut id = [0u8; 16];
            let n = name.len().min(16);
            id[..n].copy_from_slice(&name[..n]);
            Ok(Self(id))
        } else {
            Ok(Self(<[u8; 16]>::arbitrary(u)?))
        }
    }
}

/// The parameter protocol.
#[derive(Debug, Clone, Arbitrary)]
pub enum ParamMessage {
    RequestList,
    Read { name: ParamName, index: i16 },
    Set { name: ParamName, value: Num, param_type: MavParamType },
}

impl ParamMessage {
    #[must_use]
    pub fn to_message(&self) -> MavMessage {
        match self {
            Self::RequestList => {
                MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: SYSID, target_component: 1 })
            }
            Self::Read { name, index } => MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: *index,
                target_system: SYSID,
                target_component: 1,
                param_id: name.0.into(),
            }),
            Self::Set { name, value, param_type } => MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: value.0,
                target_system: SYSID,
                target_component: 1,
                param_id: name.0.into(),
                param_type: *param_type,
            }),
        }
    }
}

/// The mission protocol, for the three plans.
#[derive(Debug, Clone, Arbitrary)]
pub enum MissionMessage {
    Count { count: Small, mission_type: MavMissionType },
    ItemInt { seq: Small, item: Box<MISSION_ITEM_INT_DATA> },
    Item { seq: Small, item: Box<MISSION_ITEM_DATA> },
    RequestList { mission_type: MavMissionType },
    Request { seq: Small, mission_type: MavMissionType },
    RequestInt { seq: Small, mission_type: MavMissionType },
    Ack { result: MavMissionResult, mission_type: MavMissionType },
    ClearAll { mission_type: MavMissionType },
    SetCurrent { seq: Small },
}

impl MissionMessage {
    #[must_use]
    pub fn to_message(&self) -> MavMessage {
        let (target_system, target_component) = (SYSID, 1);
        match self {
            Self::Count { count, mission_type } => MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: count.0,
                target_system,
                target_component,
                mission_type: *mission_type,
                ..MISSION_COUNT_DATA::default()
            }),
            Self::ItemInt { seq, item } => MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                seq: seq.0,
                target_system,
                target_component,
                ..(**item).clone()
            }),
            Self::Item { seq, item } => MavMessage::MISSION_ITEM(MISSION_ITEM_DATA {
                seq: seq.0,
                target_system,
                target_component,
                ..(**item).clone()
            }),
            Self::RequestList { mission_type } => MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
                target_system,
                target_component,
                mission_type: *mission_type,
            }),
            Self::Request { seq, mission_type } => MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                seq: seq.0,
                target_system,
                target_component,
                mission_type: *mission_type,
            }),
            Self::RequestInt { seq, mission_type } => MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq: seq.0,
                target_system,
                target_component,
                mission_type: *mission_type,
            }),
            Self::Ack { result, mission_type } => MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                target_system,
                target_component,
                mavtype: *result,
                mission_type: *mission_type,
                ..MISSION_ACK_DATA::default()
            }),
            Self::ClearAll { mission_type } => MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
                target_system,
                target_component,
                mission_type: *mission_type,
            }),
            Self::SetCurrent { seq } => MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA {
                seq: seq.0,
                target_system,
                target_component,
            }),
        }
    }
}

/// One ground-station message to a flying vehicle.
#[derive(Debug, Clone, Arbitrary)]
pub enum GcsMessage {
    CommandLong {
        command: Command,
        params: [Num; 7],
    },
    CommandInt {
        command: Command,
        frame: MavFrame,
        params: [Num; 4],
        x: i32,
        y: i32,
        z: Num,
    },
    /// A PX4 mode as ground stations ask for it (main 1..6, sub 0..6 mostly).
    DoSetMode {
        main: u8,
        sub: u8,
    },
    SetMode(SET_MODE_DATA),
    OffboardLocal {
        type_mask: u16,
        frame: MavFrame,
        pos: [Num; 3],
        vel: [Num; 3],
        acc: [Num; 3],
        yaw: Num,
        yaw_rate: Num,
    },
    OffboardGlobal(Box<SET_POSITION_TARGET_GLOBAL_INT_DATA>),
    Attitude(Box<SET_ATTITUDE_TARGET_DATA>),
    Param(ParamMessage),
    Mission(MissionMessage),
    GcsHeartbeat,
    Heartbeat(HEARTBEAT_DATA),
    /// Any message of the dialect, as decoded from the wire.
    Any(Box<MavMessage>),
}

impl GcsMessage {
    /// The message, addressed to the vehicle where it has a target (except [`GcsMessage::Any`]).
    #[must_use]
    pub fn to_message(&self) -> MavMessage {
        match self {
            Self::CommandLong { command, params } => command_long(SYSID, 1, command.0, params.map(|p| p.0)),
            Self::CommandInt { command, frame, params, x, y, z } => MavMessage::COMMAND_INT(COMMAND_INT_DATA {
                param1: params[0].0,
                param2: params[1].0,
                param3: params[2].0,
                param4: params[3].0,
                x: *x,
                y: *y,
                z: z.0,
                command: command.0,
                target_system: SYSID,
                target_component: 1,
                frame: *frame,
                ..COMMAND_INT_DATA::default()
            }),
            Self::DoSetMode { main, sub } => command_long(
                SYSID,
                1,
                MavCmd::MAV_CMD_DO_SET_MODE,
                [1.0, f32::from(main % 8), f32::from(sub % 8), 0.0, 0.0, 0.0, 0.0],
            ),
            Self::SetMode(m) => MavMessage::SET_MODE(SET_MODE_DATA { target_system: SYSID, ..m.clone() }),
            Self::OffboardLocal { type_mask, frame, pos, vel, acc, yaw, yaw_rate } => {
                MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
                    x: pos[0].0,
                    y: pos[1].0,
                    z: pos[2].0,
                    vx: vel[0].0,
                    vy: vel[1].0,
                    vz: vel[2].0,
                    afx: acc[0].0,
                    afy: acc[1].0,
                    afz: acc[2].0,
                    yaw: yaw.0,
                    yaw_rate: yaw_rate.0,
                    type_mask: PositionTargetTypemask::from_bits_truncate(*type_mask),
                    target_system: SYSID,
                    target_component: 1,
                    coordinate_frame: *frame,
                    ..SET_POSITION_TARGET_LOCAL_NED_DATA::default()
                })
            }
            Self::OffboardGlobal(m) => {
                MavMessage::SET_POSITION_TARGET_GLOBAL_INT(SET_POSITION_TARGET_GLOBAL_INT_DATA {
                    target_system: SYSID,
                    target_component: 1,
                    ..(**m).clone()
                })
            }
            Self::Attitude(m) => MavMessage::SET_ATTITUDE_TARGET(SET_ATTITUDE_TARGET_DATA {
                target_system: SYSID,
                target_component: 1,
                ..(**m).clone()
            }),
            Self::Param(p) => p.to_message(),
            Self::Mission(m) => m.to_message(),
            Self::GcsHeartbeat => gcs_heartbeat(),
            Self::Heartbeat(h) => MavMessage::HEARTBEAT(h.clone()),
            Self::Any(m) => (**m).clone(),
        }
    }

    /// Whether this asks to arm (COMMAND_LONG or COMMAND_INT of ARM_DISARM with param1 1).
    #[must_use]
    pub fn is_arm(&self) -> bool {
        match self.to_message() {
            MavMessage::COMMAND_LONG(c) => c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM && c.param1 == 1.0,
            MavMessage::COMMAND_INT(c) => c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM && c.param1 == 1.0,
            _ => false,
        }
    }
}

/// The invariants of every vehicle step, whatever came in: motor commands finite and in 1000-2000 µs, all
/// at 1000 µs while disarmed except one motor during a motor test, never a motor test while armed; the
/// estimate and the reference finite.
///
/// # Panics
/// When one does not hold (the fuzzer records the input).
pub fn check_step(vehicle: &Vehicle, out: &VehicleOutputs) {
    assert!(out.pwm_us.iter().all(|p| p.is_finite() && (1000.0..=2000.0).contains(p)), "pwm {:?}", out.pwm_us);
    assert!(!(out.armed && out.motor_test), "a motor test while armed");
    if !out.armed {
        let moving = out.pwm_us.iter().filter(|p| **p != 1000.0).count();
        let allowed = usize::from(out.motor_test);
        assert!(moving <= allowed, "disarmed but pwm {:?} (motor test: {})", out.pwm_us, out.motor_test);
    }
    check_vehicle(vehicle);
}

/// The estimate and the reference are finite.
///
/// # Panics
/// When one is not.
pub fn check_vehicle(vehicle: &Vehicle) {
    let e = vehicle.estimate();
    assert!(
        e.pos_ned_m.iter().chain(e.vel_ned_mps.iter()).all(|v| v.is_finite()),
        "estimate not finite: {:?} {:?}",
        e.pos_ned_m,
        e.vel_ned_mps
    );
    if let Some(r) = vehicle.reference() {
        assert!(
            r.pos_ned_m.iter().chain(r.vel_ned_mps.iter()).chain(r.acc_ned_mps2.iter()).all(|v| v.is_finite())
                && r.yaw_rad.is_finite(),
            "reference not finite: {r:?}"
        );
    }
}
