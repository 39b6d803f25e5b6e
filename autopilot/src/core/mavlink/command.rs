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
//! - Anything else: UNSUPPORTED.
//!
//! The mavlink crate (without `mav2-message-extensions`) has no target fields in COMMAND_ACK; the reply
//! goes back to the sender because the caller sends `command_replies` to the peer the command came from.

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavFrame, MavMessage, MavModeFlag, MavResult, MavSeverity,
};

use super::addressed_to_us;
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
    /// Refused here (bad parameters), with the STATUSTEXT.
    Deny(String),
    /// Not a command this vehicle knows.
    Unsupported,
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

/// The effect of a command with its parameters (`alt_m` = COMMAND_LONG param7 / COMMAND_INT z).
fn effect(command: MavCmd, p: [f32; 4], alt_m: f32, relative_frame: bool, ctx: &CommandContext) -> CommandEffect {
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
            alt_rel_m: takeoff_alt_rel_m(alt_m, relative_frame, ctx.home_alt_amsl_m),
        }),
        MavCmd::MAV_CMD_NAV_LAND => CommandEffect::Request(Request::Land),
        MavCmd::MAV_CMD_DO_SET_MODE => {
            let base = f32_to_u8(p[0]).map_or(MavModeFlag::empty(), MavModeFlag::from_bits_truncate);
            match (f32_to_u8(p[1]), f32_to_u8(p[2])) {
                _ if !base.contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) => {
                    CommandEffect::Deny("Mode: only PX4 custom modes".into())
                }
                (Some(main), sub) => CommandEffect::Request(Request::SetMode { main, sub: sub.unwrap_or(0) }),
                (None, _) => CommandEffect::Deny(format!("Mode: invalid main mode {}", p[1])),
            }
        }
        _ => CommandEffect::Unsupported,
    }
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
            (c.command, effect(c.command, [c.param1, c.param2, c.param3, c.param4], c.param7, false, ctx))
        }
        MavMessage::COMMAND_INT(c) => {
            if !addressed_to_us(sysid, c.target_system, c.target_component) {
                return None;
            }
            let relative = matches!(
                c.frame,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            );
            (c.command, effect(c.command, [c.param1, c.param2, c.param3, c.param4], c.z, relative, ctx))
        }
        MavMessage::SET_MODE(m) => {
            if !addressed_to_us(sysid, m.target_system, 0) {
                return None;
            }
            let (main, sub) = px4_main_sub(m.custom_mode);
            let p = [f32::from(m.base_mode.bits()), f32::from(main), f32::from(sub), 0.0];
            (MavCmd::MAV_CMD_DO_SET_MODE, effect(MavCmd::MAV_CMD_DO_SET_MODE, p, f32::NAN, false, ctx))
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

/// A COMMAND_ACK.
#[must_use]
pub fn command_ack(command: MavCmd, result: MavResult) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA { command, result })
}

/// The replies to a command whose effect came out as `outcome`: `Ok` -> ACK ACCEPTED; `Err(Some(text))`
/// -> ACK DENIED and a STATUSTEXT (warning) with `text`; `Err(None)` -> ACK UNSUPPORTED.
#[must_use]
pub fn command_replies(command: MavCmd, outcome: Result<(), Option<String>>) -> Vec<MavMessage> {
    match outcome {
        Ok(()) => vec![command_ack(command, MavResult::MAV_RESULT_ACCEPTED)],
        Err(Some(text)) => vec![
            command_ack(command, MavResult::MAV_RESULT_DENIED),
            statustext(MavSeverity::MAV_SEVERITY_WARNING, &text),
        ],
        Err(None) => vec![command_ack(command, MavResult::MAV_RESULT_UNSUPPORTED)],
    }
}
