//! The command microservice. In: COMMAND_LONG, COMMAND_INT and the SET_MODE message (#11) with the
//! sender's header; the home altitude (m AMSL) for NAV_TAKEOFF. Out: an [`InboundCommand`] whose
//! [`CommandEffect`] is a commander [`Request`] (or a refusal or UNSUPPORTED decided here), and, once the
//! vehicle has applied it, [`command_replies`]: a COMMAND_ACK to the sender and, on DENIED, a STATUSTEXT
//! with the reason.
//!
//! - ARM_DISARM (400): param1 1 arm (param2 21196 = force), param1 0 disarm, param1 0 with 21196 = kill.
//! - NAV_TAKEOFF (22): param7 (COMMAND_INT: z) altitude; NaN -> the commander's default; finite -> AMSL
//!   made relative to home; a value below the home altitude is taken as relative (as are COMMAND_INT's
//!   relative-altitude frames, and any value when no home altitude is known yet).
//! - NAV_LAND (21): land here.
//! - DO_SET_MODE (176) and SET_MODE: PX4 main = param2 (custom_mode bits 16-23), sub = param3 (bits 24-31);
//!   only the CUSTOM_MODE_ENABLED bit of base_mode is read, so arming never comes from a mode change.
//! - NAV_RETURN_TO_LAUNCH (20), MISSION_START (300), DO_FLIGHTTERMINATION (185, param1 1: a kill).
//! - Answered by the vehicle ([`VehicleCommand`]): REQUEST_MESSAGE (512) and
//!   REQUEST_AUTOPILOT_CAPABILITIES (520), SET_/GET_MESSAGE_INTERVAL (511/510), DO_CHANGE_SPEED (178),
//!   DO_SET_HOME (179), DO_REPOSITION (192: all-NaN position = pause here), PREFLIGHT_REBOOT_SHUTDOWN (246),
//!   and the motor test ([`MotorTestRequest`], as PX4's commander reads it): ACTUATOR_TEST (310: param1
//!   value, param2 timeout s, param5 output function, MOTOR1..4 = 1..4) and DO_MOTOR_TEST (209: param1
//!   motor 1-based, param2 throttle type, param3 value, param4 timeout s, param5 motor count).
//! - INJECT_FAILURE (420): param1 unit, param2 type, param3 instance, whole numbers 0-255 (else DENIED);
//!   answered by the failure-injection service ([`super::failure`]), possibly a few steps later.
//! - Anything else: UNSUPPORTED.
//!
//! The ACK carries the sender in its target fields, and the caller sends it only to the peer the command
//! came from.

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavFrame, MavMessage, MavModeFlag, MavResult, MavSeverity,
};

use super::addressed_to_us;
use super::failure::FailureRequest;
use super::identity::Px4Mode;
use super::telemetry::statustext;
use crate::core::commander::Request;

/// ARM_DISARM param2 meaning "force" (and, with param1 0, kill).
pub const ARM_FORCE_MAGIC: f32 = 21196.0;

/// What the command decoder needs to know of the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CommandContext {
    /// Home altitude (m AMSL): home once set, else the ground under the vehicle; None without an origin.
    pub home_alt_amsl_m: Option<f64>,
}

/// What a command asks of the vehicle.
#[derive(Debug, Clone, PartialEq)]
pub enum CommandEffect {
    /// Ask the commander; ACCEPTED if it agrees, DENIED with its refusal text otherwise.
    Request(Request),
    /// Handled by the vehicle itself (messages, stream rates, home, speed, mission start, reboot).
    Vehicle(VehicleCommand),
    /// Refused here (bad parameters), with the STATUSTEXT.
    Deny(String),
    /// Not a command this vehicle knows.
    Unsupported,
    /// INJECT_FAILURE (420): param1 unit, param2 type, param3 instance, for the failure-injection service
    /// (see [`super::failure`]), which answers it itself: now, or when the plant has.
    InjectFailure(FailureRequest),
}

/// A geodetic point of a command: latitude, longitude (deg), altitude (m) AMSL or above home.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandPoint {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
    pub relative_alt: bool,
}

/// The commands the vehicle answers itself.
#[derive(Debug, Clone, PartialEq)]
pub enum VehicleCommand {
    /// REQUEST_MESSAGE (512) or REQUEST_AUTOPILOT_CAPABILITIES (520, as message 148).
    RequestMessage { message_id: u32 },
    /// SET_MESSAGE_INTERVAL (511): `interval_us` -1 off, 0 default.
    SetMessageInterval { message_id: u32, interval_us: f64 },
    /// GET_MESSAGE_INTERVAL (510).
    GetMessageInterval { message_id: u32 },
    /// DO_CHANGE_SPEED (178): ground speed (m/s); None: back to cruise.
    ChangeSpeed { speed_mps: Option<f64> },
    /// DO_SET_HOME (179): here (`None`) or a point.
    SetHome { point: Option<CommandPoint> },
    /// DO_REPOSITION (192): hold at the point (`None`: here, QGroundControl's pause), yaw (rad).
    Reposition { point: Option<CommandPoint>, yaw_rad: Option<f64> },
    /// MISSION_START (300): fly the mission from item `first`.
    MissionStart { first: u16 },
    /// PREFLIGHT_REBOOT_SHUTDOWN (246) param1 1: restart the autopilot (disarmed only).
    Reboot,
    /// Accepted, nothing to do (PREFLIGHT_REBOOT_SHUTDOWN param1 0).
    NoOp,
    /// ACTUATOR_TEST (310) or DO_MOTOR_TEST (209): spin one motor, or stop it (disarmed only).
    MotorTest(MotorTestRequest),
}

/// How many motors the vehicle has: motor N = output N = the paper's rotor N (1 right, 2 rear, 3 front,
/// 4 left).
pub const MOTOR_COUNT: u8 = 4;

/// The longest a motor test runs (µs), PX4's cap (and its timeout when none is given).
pub const MOTOR_TEST_MAX_US: u64 = 3_000_000;

/// A motor test as PX4's commander decodes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotorTestRequest {
    /// Run `motor` (1..=[`MOTOR_COUNT`]) at `thrust` of its output range (0 = 1000 µs, 1 = 2000 µs) for
    /// `timeout_us` (1 ms ..= [`MOTOR_TEST_MAX_US`]); it replaces any test running.
    Run { motor: u8, thrust: f64, timeout_us: u64 },
    /// Stop `motor`'s test (ACTUATOR_TEST with timeout 0 or value NaN or below 0; DO_MOTOR_TEST with
    /// value 0).
    Stop { motor: u8 },
}

/// PX4's `(int)(x + 0.5)` for the values a command can sensibly carry; None for NaN or beyond ±1e6.
fn round_half_up(x: f64) -> Option<i64> {
    (x.is_finite() && x.abs() <= 1e6).then(|| (x + 0.5).floor() as i64)
}

/// The motor of an output function or motor number, or the refusal.
fn motor_of(n: i64, what: &str) -> Result<u8, CommandEffect> {
    match u8::try_from(n) {
        Ok(m @ 1..=MOTOR_COUNT) => Ok(m),
        _ => Err(CommandEffect::Deny(format!("Motor test: no {what} {n} (motors 1-{MOTOR_COUNT})"))),
    }
}

/// ACTUATOR_TEST (310), as PX4's commander: the function (param5, rounded) names the motor (MOTOR1..4 =
/// 1..4; another motor or servo function this vehicle lacks is DENIED, anything else UNSUPPORTED); a
/// timeout (param2, s, rounded to ms) of 0 or less stops the motor, else it is capped at 3 s; the value
/// (param1) NaN or below 0 stops the motor (a non-reversible motor's "off"), else it is the thrust,
/// clamped to [0, 1].
fn actuator_test(value: f32, timeout_s: f32, function: f64) -> CommandEffect {
    let Some(function) = round_half_up(function) else { return CommandEffect::Unsupported };
    if !(1..=16).contains(&function) && !(33..=48).contains(&function) {
        return CommandEffect::Unsupported;
    }
    let motor = match motor_of(function, "output function") {
        Ok(m) => m,
        Err(refusal) => return refusal,
    };
    let timeout_ms = round_half_up(f64::from(timeout_s) * 1e3).unwrap_or(if timeout_s > 0.0 { i64::MAX } else { 0 });
    let value = f64::from(value);
    if timeout_ms <= 0 || value.is_nan() || value < -f64::from(f32::EPSILON) {
        return CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Stop { motor }));
    }
    let timeout_us =
        u64::try_from(timeout_ms).map_or(MOTOR_TEST_MAX_US, |ms| ms.saturating_mul(1000).min(MOTOR_TEST_MAX_US));
    CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Run {
        motor,
        thrust: value.clamp(0.0, 1.0),
        timeout_us,
    }))
}

/// DO_MOTOR_TEST (209), as PX4's commander: the motor (param1, rounded, 1-based); only throttle type 0
/// (percent) and one motor at a time (param5 count 0 or 1) are supported (UNSUPPORTED otherwise, as
/// PX4); the value (param3, %) clamped to [0, 100], 0 (or NaN) stopping the motor; the timeout (param4,
/// s, rounded to ms) capped at 3 s, 0 (or less, or NaN) meaning 3 s. param6 (the order) is not read.
fn motor_test(p: [f32; 4], count: f64) -> CommandEffect {
    let motor = match round_half_up(f64::from(p[0])).map(|n| motor_of(n, "motor")) {
        Some(Ok(m)) => m,
        Some(Err(refusal)) => return refusal,
        None => return CommandEffect::Deny(format!("Motor test: no motor {}", p[0])),
    };
    if round_half_up(f64::from(p[1])) != Some(0) || round_half_up(count).unwrap_or(0) > 1 {
        return CommandEffect::Unsupported;
    }
    let thrust = (f64::from(p[2]) / 100.0).clamp(0.0, 1.0);
    if thrust.is_nan() || thrust < f64::from(f32::EPSILON) {
        return CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Stop { motor }));
    }
    let timeout_ms = round_half_up(f64::from(p[3]) * 1e3).unwrap_or(0);
    let timeout_us = u64::try_from(timeout_ms)
        .ok()
        .filter(|&ms| ms > 0)
        .map_or(MOTOR_TEST_MAX_US, |ms| ms.saturating_mul(1000).min(MOTOR_TEST_MAX_US));
    CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Run { motor, thrust, timeout_us }))
}

/// A command for this vehicle, decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct InboundCommand {
    /// The command to acknowledge (DO_SET_MODE for the SET_MODE message).
    pub command: MavCmd,
    /// The sender (the ACK goes back to it).
    pub sender_system: u8,
    pub sender_component: u8,
    pub effect: CommandEffect,
}

/// The NAV_TAKEOFF altitude above home (m). NaN: `None` (the commander's default). `relative_frame` (a
/// COMMAND_INT in a relative-altitude frame) or an unknown home: as given. Otherwise AMSL, made relative,
/// unless below the home altitude, when it is taken as relative already.
#[must_use]
pub fn takeoff_alt_rel_m(alt_m: f32, relative_frame: bool, home_alt_amsl_m: Option<f64>) -> Option<f64> {
    let alt_m = f64::from(alt_m);
    if alt_m.is_nan() {
        return None;
    }
    match home_alt_amsl_m {
        Some(home) if !relative_frame && home.is_finite() && alt_m >= home => Some(alt_m - home),
        _ => Some(alt_m),
    }
}

/// PX4 (main, sub) from a HEARTBEAT-style `custom_mode`.
#[must_use]
pub fn px4_main_sub(custom_mode: u32) -> (u8, u8) {
    (((custom_mode >> 16) & 0xff) as u8, (custom_mode >> 24) as u8)
}

fn f32_to_u8(x: f32) -> Option<u8> {
    ((0.0..=255.0).contains(&x) && x.fract() == 0.0).then_some(x as u8)
}

/// A command's parameters, as COMMAND_LONG and COMMAND_INT both give them: `p[0..4]` = param1..4,
/// `x`/`y` = param5/6 (COMMAND_INT: degE7 as degrees), `z` = param7, and whether the altitude is
/// relative (COMMAND_INT's relative-altitude frames).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Params {
    p: [f32; 4],
    x: f64,
    y: f64,
    z: f32,
    relative: bool,
}

impl Params {
    /// The point of params 5-7, or None when latitude and longitude are NaN (or both 0: "here").
    fn point(&self) -> Option<CommandPoint> {
        let (lat, lon) = (self.x, self.y);
        if !(lat.is_finite() && lon.is_finite()) || (lat == 0.0 && lon == 0.0) {
            return None;
        }
        Some(CommandPoint { lat_deg: lat, lon_deg: lon, alt_m: f64::from(self.z), relative_alt: self.relative })
    }
}

fn finite(x: f32) -> Option<f64> {
    x.is_finite().then_some(f64::from(x))
}

/// The effect of a command with its parameters.
// REQUEST_AUTOPILOT_CAPABILITIES and GET_MESSAGE_INTERVAL are deprecated, but MAVSDK falls back to them.
#[allow(deprecated)]
fn effect(command: MavCmd, a: &Params, ctx: &CommandContext) -> CommandEffect {
    let p = a.p;
    let vehicle = CommandEffect::Vehicle;
    match command {
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
            let force = p[1] == ARM_FORCE_MAGIC;
            if p[0] == 1.0 {
                CommandEffect::Request(Request::Arm { force })
            } else if p[0] == 0.0 {
                CommandEffect::Request(if force { Request::Kill } else { Request::Disarm { force: false } })
            } else {
                CommandEffect::Deny(format!("Arming: invalid param1 {}", p[0]))
            }
        }
        MavCmd::MAV_CMD_NAV_TAKEOFF => CommandEffect::Request(Request::Takeoff {
            alt_rel_m: takeoff_alt_rel_m(a.z, a.relative, ctx.home_alt_amsl_m),
        }),
        MavCmd::MAV_CMD_NAV_LAND => CommandEffect::Request(Request::Land),
        MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => CommandEffect::Request(Request::ReturnToLaunch),
        MavCmd::MAV_CMD_DO_SET_MODE => {
            let base = f32_to_u8(p[0]).map_or(MavModeFlag::empty(), MavModeFlag::from_bits_truncate);
            match (f32_to_u8(p[1]), f32_to_u8(p[2])) {
                _ if !base.contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) => {
                    CommandEffect::Deny("Mode: only PX4 custom modes".into())
                }
                (Some(main), sub) => {
                    let sub = sub.unwrap_or(0);
                    match Px4Mode::decode(main, sub) {
                        Px4Mode::Supported(mode) => CommandEffect::Request(Request::SetMode(mode)),
                        Px4Mode::Unsupported { name, reason } => {
                            CommandEffect::Deny(format!("Mode not supported: {name} {reason}"))
                        }
                        Px4Mode::Unknown => CommandEffect::Deny(format!("Mode not supported: main {main} sub {sub}")),
                    }
                }
                (None, _) => CommandEffect::Deny(format!("Mode: invalid main mode {}", p[1])),
            }
        }
        MavCmd::MAV_CMD_DO_FLIGHTTERMINATION => {
            if p[0] > 0.5 {
                CommandEffect::Request(Request::Kill)
            } else {
                CommandEffect::Deny("Flight termination: param1 must be 1".into())
            }
        }
        MavCmd::MAV_CMD_MISSION_START => match f32_to_u16(p[0].max(0.0)) {
            Some(first) => vehicle(VehicleCommand::MissionStart { first }),
            None => CommandEffect::Deny(format!("Mission start: invalid item {}", p[0])),
        },
        MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
            // param2 -1 (no change) or -2 (default) and 0 all mean the cruise speed.
            let speed_mps = finite(p[1]).filter(|s| *s > 0.0);
            if speed_mps.is_some_and(|s| s > MAX_SPEED_MPS) {
                return CommandEffect::Deny(format!("Speed {} m/s above {MAX_SPEED_MPS}", p[1]));
            }
            vehicle(VehicleCommand::ChangeSpeed { speed_mps })
        }
        MavCmd::MAV_CMD_DO_SET_HOME => {
            if p[0] == 1.0 {
                vehicle(VehicleCommand::SetHome { point: None })
            } else {
                match a.point() {
                    Some(point) if point.alt_m.is_finite() => vehicle(VehicleCommand::SetHome { point: Some(point) }),
                    _ => CommandEffect::Deny("Set home: no position given".into()),
                }
            }
        }
        MavCmd::MAV_CMD_DO_REPOSITION => {
            let point = a
                .point()
                .map(|pt| CommandPoint { alt_m: if pt.alt_m.is_finite() { pt.alt_m } else { f64::NAN }, ..pt });
            vehicle(VehicleCommand::Reposition { point, yaw_rad: finite(p[3]) })
        }
        MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN => {
            if p[0] == 1.0 {
                vehicle(VehicleCommand::Reboot)
            } else if p[0] == 0.0 {
                vehicle(VehicleCommand::NoOp)
            } else {
                CommandEffect::Unsupported
            }
        }
        MavCmd::MAV_CMD_REQUEST_MESSAGE => match f32_to_u32(p[0]) {
            Some(message_id) => vehicle(VehicleCommand::RequestMessage { message_id }),
            None => CommandEffect::Deny(format!("Request message: invalid id {}", p[0])),
        },
        MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
            vehicle(VehicleCommand::RequestMessage { message_id: AUTOPILOT_VERSION_ID })
        }
        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => match f32_to_u32(p[0]) {
            Some(message_id) if p[1].is_finite() => {
                vehicle(VehicleCommand::SetMessageInterval { message_id, interval_us: f64::from(p[1]) })
            }
            _ => CommandEffect::Deny(format!("Message interval: invalid id {} or interval {}", p[0], p[1])),
        },
        MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL => match f32_to_u32(p[0]) {
            Some(message_id) => vehicle(VehicleCommand::GetMessageInterval { message_id }),
            None => CommandEffect::Deny(format!("Message interval: invalid id {}", p[0])),
        },
        MavCmd::MAV_CMD_ACTUATOR_TEST => actuator_test(p[0], p[1], a.x),
        MavCmd::MAV_CMD_DO_MOTOR_TEST => motor_test(p, a.x),
        MavCmd::MAV_CMD_INJECT_FAILURE => match FailureRequest::from_params(p[0], p[1], p[2]) {
            Some(request) => CommandEffect::InjectFailure(request),
            None => {
                CommandEffect::Deny("Failure injection: unit, type and instance must be whole numbers 0-255".into())
            }
        },
        _ => CommandEffect::Unsupported,
    }
}

/// Largest speed DO_CHANGE_SPEED accepts (m/s): the controllers' horizontal velocity limit.
pub const MAX_SPEED_MPS: f64 = 3.0;

/// AUTOPILOT_VERSION's message id.
pub const AUTOPILOT_VERSION_ID: u32 = 148;

fn f32_to_u16(x: f32) -> Option<u16> {
    ((0.0..=65_535.0).contains(&x) && x.fract() == 0.0).then_some(x as u16)
}

fn f32_to_u32(x: f32) -> Option<u32> {
    ((0.0..=16_777_216.0).contains(&x) && x.fract() == 0.0).then_some(x as u32)
}

/// Decodes a received message into a command for system `sysid`; `None` when it is not a command or is
/// addressed to another system or component.
// SET_MODE and the *_INT frames are deprecated in the dialect, but QGroundControl's PX4 plugin and older
// clients still send them.
#[allow(deprecated)]
#[must_use]
pub fn decode_command(sysid: u8, header: &MavHeader, msg: &MavMessage, ctx: &CommandContext) -> Option<InboundCommand> {
    let (command, effect) = match msg {
        MavMessage::COMMAND_LONG(c) => {
            if !addressed_to_us(sysid, c.target_system, c.target_component) {
                return None;
            }
            let a = Params {
                p: [c.param1, c.param2, c.param3, c.param4],
                x: f64::from(c.param5),
                y: f64::from(c.param6),
                z: c.param7,
                relative: false,
            };
            (c.command, effect(c.command, &a, ctx))
        }
        MavMessage::COMMAND_INT(c) => {
            if !addressed_to_us(sysid, c.target_system, c.target_component) {
                return None;
            }
            let relative = matches!(
                c.frame,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            );
            let a = Params {
                p: [c.param1, c.param2, c.param3, c.param4],
                x: super::units::dege7_to_deg(c.x),
                y: super::units::dege7_to_deg(c.y),
                z: c.z,
                relative,
            };
            (c.command, effect(c.command, &a, ctx))
        }
        MavMessage::SET_MODE(m) => {
            if !addressed_to_us(sysid, m.target_system, 0) {
                return None;
            }
            let (main, sub) = px4_main_sub(m.custom_mode);
            let p = [f32::from(m.base_mode.bits()), f32::from(main), f32::from(sub), 0.0];
            let a = Params { p, x: f64::NAN, y: f64::NAN, z: f32::NAN, relative: false };
            (MavCmd::MAV_CMD_DO_SET_MODE, effect(MavCmd::MAV_CMD_DO_SET_MODE, &a, ctx))
        }
        _ => return None,
    };
    Some(InboundCommand {
        command,
        sender_system: u8::try_from(header.system_id).unwrap_or(u8::MAX),
        sender_component: header.component_id,
        effect,
    })
}

/// A COMMAND_LONG to `target_system`/`target_component` with the seven parameters in order, as a ground
/// station sends it (confirmation 0; component 0 addresses every component, as pymavlink does).
#[must_use]
pub fn command_long(target_system: u8, target_component: u8, command: MavCmd, params: [f32; 7]) -> MavMessage {
    let [param1, param2, param3, param4, param5, param6, param7] = params;
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1,
        param2,
        param3,
        param4,
        param5,
        param6,
        param7,
        command,
        target_system,
        target_component,
        confirmation: 0,
    })
}

/// A COMMAND_ACK for the command's sender.
#[must_use]
pub fn command_ack(command: &InboundCommand, result: MavResult) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: command.command,
        result,
        target_system: command.sender_system,
        target_component: command.sender_component,
        ..Default::default()
    })
}

/// The replies to `command` whose effect came out as `outcome`: `Ok` -> ACK ACCEPTED; `Err(Some(text))`
/// -> ACK DENIED and a STATUSTEXT (warning) with `text` (none for an empty text: a refusal clients repeat
/// several times a second, such as a message not available yet, would flood the text stream);
/// `Err(None)` -> ACK UNSUPPORTED. The ACK is addressed to the command's sender.
#[must_use]
pub fn command_replies(command: &InboundCommand, outcome: Result<(), Option<String>>) -> Vec<MavMessage> {
    match outcome {
        Ok(()) => vec![command_ack(command, MavResult::MAV_RESULT_ACCEPTED)],
        Err(Some(text)) if text.is_empty() => vec![command_ack(command, MavResult::MAV_RESULT_DENIED)],
        Err(Some(text)) => vec![
            command_ack(command, MavResult::MAV_RESULT_DENIED),
            statustext(MavSeverity::MAV_SEVERITY_WARNING, &text),
        ],
        Err(None) => vec![command_ack(command, MavResult::MAV_RESULT_UNSUPPORTED)],
    }
}
