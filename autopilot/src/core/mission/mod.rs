//! The mission store: the items a ground station uploaded, validated, and their persistence text. In: one
//! MISSION_ITEM_INT (x, y as integers: degE7 for global frames, m * 1e4 for local frames) or legacy float
//! MISSION_ITEM (x, y in deg for global frames, m for local frames) per item, or a QGC WPL 110 text
//! ([`Mission::from_wpl`]). Out: a [`Mission`] whose every item is one this vehicle can fly, or a
//! [`MissionError`] naming the first item that is not, with the MAV_MISSION_RESULT to answer
//! ([`MissionError::result`]) and a reason short enough for a STATUSTEXT (its `Display`).
//!
//! - Commands: NAV_WAYPOINT (16), NAV_SPLINE_WAYPOINT (82), NAV_LOITER_UNLIM (17), NAV_LOITER_TIME (19), NAV_RETURN_TO_LAUNCH (20),
//!   NAV_LAND (21), NAV_TAKEOFF (22), NAV_DELAY (93), DO_JUMP (177), DO_CHANGE_SPEED (178); anything else is
//!   MAV_MISSION_UNSUPPORTED.
//! - Frames: GLOBAL (0), GLOBAL_RELATIVE_ALT (3), GLOBAL_INT (5), GLOBAL_RELATIVE_ALT_INT (6) for every
//!   command, MISSION (2) only for the commands without a position (RTL, delay, jump, speed); anything else
//!   is MAV_MISSION_UNSUPPORTED_FRAME.
//! - Positions: waypoints and loiters need latitude and longitude (degE7 within +-90 deg / +-180 deg) and a
//!   finite altitude z (m, AMSL or above home as the frame says); take-off needs a finite altitude; take-off
//!   and land may leave latitude and longitude unset ([`XY_UNSET`]: "here").
//! - Parameters: loiter time (param1, s) and delay (param1, s) finite and >= 0 (the time-of-day form of
//!   NAV_DELAY, param1 = -1, is refused: the vehicle has no calendar clock); DO_JUMP param1 a whole item
//!   number in the mission other than the jump itself, param2 a whole repeat count >= 0 or -1 for "repeat
//!   forever" (as ArduPilot takes it, and as the navigator flies it); DO_CHANGE_SPEED param2 (m/s) finite
//!   and >= 0, or -1 for "no change".
//!
//! MAVLink's "not given" for an integer x/y is INT32_MAX ([`XY_UNSET`]); the float forms (legacy
//! MISSION_ITEM, WPL text) carry it as NaN. In the MISSION frame x and y are param5 and param6 as whole
//! numbers (PX4 casts them the same way).

// The legacy MISSION_ITEM and the *_INT frames are deprecated in the dialect, but QGroundControl, MAVSDK
// (GLOBAL_RELATIVE_ALT_INT), MAVProxy and pymavlink still send them: this module exists to read them.
#![allow(deprecated)]

use ::mavlink::dialects::common::{MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA, MavCmd, MavFrame, MavMissionResult};
use thiserror::Error;

mod nav;
mod wpl;

pub use nav::{NavCommand, NavItem, NavTarget, nav_items};

pub use wpl::{WPL_HEADER, WplError, items_from_wpl, items_to_wpl};

/// x/y meaning "not given" (MAVLink's INT32_MAX for integer parameters; NaN in the float forms).
pub const XY_UNSET: i32 = i32::MAX;

/// Latitude limit (degE7).
pub const LAT_LIMIT_DEGE7: i32 = 900_000_000;
/// Longitude limit (degE7).
pub const LON_LIMIT_DEGE7: i32 = 1_800_000_000;

/// The commands a mission may hold.
pub const SUPPORTED_COMMANDS: [MavCmd; 10] = [
    MavCmd::MAV_CMD_NAV_WAYPOINT,
    MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT,
    MavCmd::MAV_CMD_NAV_LOITER_UNLIM,
    MavCmd::MAV_CMD_NAV_LOITER_TIME,
    MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MavCmd::MAV_CMD_NAV_LAND,
    MavCmd::MAV_CMD_NAV_TAKEOFF,
    MavCmd::MAV_CMD_NAV_DELAY,
    MavCmd::MAV_CMD_DO_JUMP,
    MavCmd::MAV_CMD_DO_CHANGE_SPEED,
];

/// The frames a mission item may use.
pub const SUPPORTED_FRAMES: [MavFrame; 5] = [
    MavFrame::MAV_FRAME_GLOBAL,
    MavFrame::MAV_FRAME_MISSION,
    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
    MavFrame::MAV_FRAME_GLOBAL_INT,
    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
];

/// The MAV_CMD number of a command.
#[must_use]
pub fn command_id(command: MavCmd) -> u32 {
    command as u32
}

/// The MAV_FRAME number of a frame.
#[must_use]
pub fn frame_id(frame: MavFrame) -> u32 {
    frame as u32
}

/// A supported command from its MAV_CMD number (`None` for any other number).
#[must_use]
pub fn supported_command(id: u32) -> Option<MavCmd> {
    SUPPORTED_COMMANDS.into_iter().find(|&c| command_id(c) == id)
}

/// A supported frame from its MAV_FRAME number (`None` for any other number).
#[must_use]
pub fn supported_frame(id: u32) -> Option<MavFrame> {
    SUPPORTED_FRAMES.into_iter().find(|&f| frame_id(f) == id)
}

/// Whether x/y of `frame` are latitude/longitude.
#[must_use]
pub fn is_global_frame(frame: MavFrame) -> bool {
    matches!(
        frame,
        MavFrame::MAV_FRAME_GLOBAL
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MavFrame::MAV_FRAME_GLOBAL_INT
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT
            | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
    )
}

/// Whether x/y of `frame` are metres (carried as m * 1e4 in MISSION_ITEM_INT).
#[must_use]
pub fn is_local_frame(frame: MavFrame) -> bool {
    matches!(
        frame,
        MavFrame::MAV_FRAME_LOCAL_NED
            | MavFrame::MAV_FRAME_LOCAL_ENU
            | MavFrame::MAV_FRAME_LOCAL_OFFSET_NED
            | MavFrame::MAV_FRAME_BODY_NED
            | MavFrame::MAV_FRAME_BODY_OFFSET_NED
            | MavFrame::MAV_FRAME_BODY_FRD
            | MavFrame::MAV_FRAME_LOCAL_FRD
            | MavFrame::MAV_FRAME_LOCAL_FLU
    )
}

/// The number of decimals of x/y in the integer form: 7 (degE7) for global frames, 4 (m * 1e4) for local
/// frames, 0 (whole parameters) otherwise.
#[must_use]
pub fn xy_decimals(frame: MavFrame) -> u32 {
    if is_global_frame(frame) {
        7
    } else if is_local_frame(frame) {
        4
    } else {
        0
    }
}

/// The integer x/y of a float one (deg, m or a parameter as `frame` says): NaN -> [`XY_UNSET`], rounded to
/// the nearest integer unit; `None` when infinite or out of the i32 range.
#[must_use]
pub fn xy_from_float(value: f64, frame: MavFrame) -> Option<i32> {
    if value.is_nan() {
        return Some(XY_UNSET);
    }
    let scaled = (value * 10_f64.powi(xy_decimals(frame) as i32)).round();
    (scaled.is_finite() && scaled >= f64::from(i32::MIN) && scaled <= f64::from(i32::MAX)).then_some(scaled as i32)
}

/// The float x/y (deg, m or a parameter as `frame` says) of an integer one; [`XY_UNSET`] -> NaN.
#[must_use]
pub fn xy_to_float(value: i32, frame: MavFrame) -> f64 {
    if value == XY_UNSET { f64::NAN } else { f64::from(value) / 10_f64.powi(xy_decimals(frame) as i32) }
}

/// One mission item, as MISSION_ITEM_INT carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionItem {
    /// Index in the mission (0-based).
    pub seq: u16,
    pub frame: MavFrame,
    pub command: MavCmd,
    pub param1: f32,
    pub param2: f32,
    pub param3: f32,
    pub param4: f32,
    /// Latitude (degE7) in global frames, x (m * 1e4) in local frames, param5 in the MISSION frame;
    /// [`XY_UNSET`] when not given.
    pub x: i32,
    /// Longitude (degE7) in global frames, y (m * 1e4) in local frames, param6 in the MISSION frame;
    /// [`XY_UNSET`] when not given.
    pub y: i32,
    /// Altitude (m; AMSL or above home as the frame says), or param7.
    pub z: f32,
    pub autocontinue: bool,
}

impl MissionItem {
    /// The item of a MISSION_ITEM_INT (taken as it is; validate with [`validate_item`]).
    #[must_use]
    pub fn from_item_int(m: &MISSION_ITEM_INT_DATA) -> Self {
        Self {
            seq: m.seq,
            frame: m.frame,
            command: m.command,
            param1: m.param1,
            param2: m.param2,
            param3: m.param3,
            param4: m.param4,
            x: m.x,
            y: m.y,
            z: m.z,
            autocontinue: m.autocontinue != 0,
        }
    }

    /// The item of a legacy MISSION_ITEM: x/y deg (global frames) -> degE7, m (local) -> m * 1e4, rounded;
    /// NaN -> [`XY_UNSET`].
    ///
    /// # Errors
    /// [`MissionError::InvalidParam`] (param 5 or 6) when x or y is infinite or too large for the integer
    /// form.
    pub fn from_item(m: &MISSION_ITEM_DATA) -> Result<Self, MissionError> {
        let x = xy_from_float(f64::from(m.x), m.frame).ok_or(MissionError::InvalidParam {
            seq: m.seq,
            param: 5,
            reason: "x/latitude not representable",
        })?;
        let y = xy_from_float(f64::from(m.y), m.frame).ok_or(MissionError::InvalidParam {
            seq: m.seq,
            param: 6,
            reason: "y/longitude not representable",
        })?;
        Ok(Self {
            seq: m.seq,
            frame: m.frame,
            command: m.command,
            param1: m.param1,
            param2: m.param2,
            param3: m.param3,
            param4: m.param4,
            x,
            y,
            z: m.z,
            autocontinue: m.autocontinue != 0,
        })
    }

    /// The MISSION_ITEM_INT of this item, to `target_system`/`target_component`.
    #[must_use]
    pub fn to_item_int(&self, target_system: u8, target_component: u8, current: bool) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA {
            param1: self.param1,
            param2: self.param2,
            param3: self.param3,
            param4: self.param4,
            x: self.x,
            y: self.y,
            z: self.z,
            seq: self.seq,
            command: self.command,
            target_system,
            target_component,
            frame: self.frame,
            current: u8::from(current),
            autocontinue: u8::from(self.autocontinue),
            ..Default::default()
        }
    }

    /// The legacy MISSION_ITEM of this item (x/y back to deg or m, at f32 precision: about 1e-7 relative).
    #[must_use]
    pub fn to_item(&self, target_system: u8, target_component: u8, current: bool) -> MISSION_ITEM_DATA {
        MISSION_ITEM_DATA {
            param1: self.param1,
            param2: self.param2,
            param3: self.param3,
            param4: self.param4,
            x: xy_to_float(self.x, self.frame) as f32,
            y: xy_to_float(self.y, self.frame) as f32,
            z: self.z,
            seq: self.seq,
            command: self.command,
            target_system,
            target_component,
            frame: self.frame,
            current: u8::from(current),
            autocontinue: u8::from(self.autocontinue),
            ..Default::default()
        }
    }

    /// Whether the command flies to (or from) a position, so needs a global frame.
    #[must_use]
    pub fn has_position(&self) -> bool {
        matches!(
            self.command,
            MavCmd::MAV_CMD_NAV_WAYPOINT
                | MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT
                | MavCmd::MAV_CMD_NAV_LOITER_UNLIM
                | MavCmd::MAV_CMD_NAV_LOITER_TIME
                | MavCmd::MAV_CMD_NAV_LAND
                | MavCmd::MAV_CMD_NAV_TAKEOFF
        )
    }
}

/// Why a mission (or one of its items) was refused. `Display` is the STATUSTEXT reason (short).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MissionError {
    #[error("item {seq}: command {command} unsupported")]
    UnsupportedCommand { seq: u16, command: u32 },
    #[error("item {seq}: frame {frame} unsupported for cmd {command}")]
    UnsupportedFrame { seq: u16, frame: u32, command: u32 },
    /// `param` 1..=7 (5 = x, 6 = y, 7 = z).
    #[error("item {seq}: {reason}")]
    InvalidParam { seq: u16, param: u8, reason: &'static str },
    #[error("item {seq}: jump target {target} not in 0..{count}")]
    JumpTarget { seq: u16, target: f32, count: usize },
    #[error("item {index} has seq {seq}")]
    Sequence { index: usize, seq: u16 },
    #[error("{count} items, at most {max}")]
    TooManyItems { count: usize, max: usize },
}

impl MissionError {
    /// The MISSION_ACK result that reports this error.
    #[must_use]
    pub fn result(&self) -> MavMissionResult {
        match self {
            Self::UnsupportedCommand { .. } => MavMissionResult::MAV_MISSION_UNSUPPORTED,
            Self::UnsupportedFrame { .. } => MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
            Self::InvalidParam { param, .. } => match param {
                1 => MavMissionResult::MAV_MISSION_INVALID_PARAM1,
                2 => MavMissionResult::MAV_MISSION_INVALID_PARAM2,
                3 => MavMissionResult::MAV_MISSION_INVALID_PARAM3,
                4 => MavMissionResult::MAV_MISSION_INVALID_PARAM4,
                5 => MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
                6 => MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y,
                7 => MavMissionResult::MAV_MISSION_INVALID_PARAM7,
                _ => MavMissionResult::MAV_MISSION_INVALID,
            },
            Self::JumpTarget { .. } => MavMissionResult::MAV_MISSION_INVALID_PARAM1,
            Self::Sequence { .. } => MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
            Self::TooManyItems { .. } => MavMissionResult::MAV_MISSION_NO_SPACE,
        }
    }
}

fn whole(x: f32) -> bool {
    x.is_finite() && x.fract() == 0.0
}

/// Checks one item of a mission of `count` items (its index is `item.seq`).
///
/// # Errors
/// The first rule of the module doc the item breaks.
pub fn validate_item(item: &MissionItem, count: usize) -> Result<(), MissionError> {
    let seq = item.seq;
    let command = command_id(item.command);
    if !SUPPORTED_COMMANDS.contains(&item.command) {
        return Err(MissionError::UnsupportedCommand { seq, command });
    }
    let global = is_global_frame(item.frame);
    if !SUPPORTED_FRAMES.contains(&item.frame) || (item.has_position() && !global) {
        return Err(MissionError::UnsupportedFrame { seq, frame: frame_id(item.frame), command });
    }
    let invalid = |param: u8, reason: &'static str| Err(MissionError::InvalidParam { seq, param, reason });
    if item.has_position() {
        let needs_xy = !matches!(item.command, MavCmd::MAV_CMD_NAV_LAND | MavCmd::MAV_CMD_NAV_TAKEOFF);
        if item.x == XY_UNSET {
            if needs_xy {
                return invalid(5, "latitude not set");
            }
        } else if !(-LAT_LIMIT_DEGE7..=LAT_LIMIT_DEGE7).contains(&item.x) {
            return invalid(5, "latitude out of range");
        }
        if item.y == XY_UNSET {
            if needs_xy {
                return invalid(6, "longitude not set");
            }
        } else if !(-LON_LIMIT_DEGE7..=LON_LIMIT_DEGE7).contains(&item.y) {
            return invalid(6, "longitude out of range");
        }
        if item.command != MavCmd::MAV_CMD_NAV_LAND && !item.z.is_finite() {
            return invalid(7, "altitude not finite");
        }
    }
    match item.command {
        MavCmd::MAV_CMD_NAV_LOITER_TIME if !(item.param1.is_finite() && item.param1 >= 0.0) => {
            invalid(1, "loiter time invalid")
        }
        MavCmd::MAV_CMD_NAV_DELAY if !(item.param1.is_finite() && item.param1 >= 0.0) => {
            invalid(1, "delay invalid (s >= 0 only)")
        }
        MavCmd::MAV_CMD_DO_JUMP => {
            let target = item.param1;
            if !whole(target) || target < 0.0 || target >= count as f32 {
                Err(MissionError::JumpTarget { seq, target, count })
            } else if target == f32::from(seq) {
                invalid(1, "jump to itself")
            } else if !whole(item.param2) || item.param2 < -1.0 {
                invalid(2, "jump repeat count invalid")
            } else {
                Ok(())
            }
        }
        MavCmd::MAV_CMD_DO_CHANGE_SPEED
            if !(item.param2.is_finite() && (item.param2 >= 0.0 || item.param2 == -1.0)) =>
        {
            invalid(2, "speed invalid")
        }
        _ => Ok(()),
    }
}

/// A mission: items 0..n-1 in flight order. Build it with [`Mission::new`] (or an upload, or
/// [`Mission::from_wpl`]) to have it validated.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mission {
    pub items: Vec<MissionItem>,
}

impl Mission {
    /// The largest mission the wire can count (MISSION_COUNT is a u16).
    pub const MAX_ITEMS: usize = u16::MAX as usize;

    /// A validated mission.
    ///
    /// # Errors
    /// See [`Mission::validate`].
    pub fn new(items: Vec<MissionItem>) -> Result<Self, MissionError> {
        let mission = Self { items };
        mission.validate()?;
        Ok(mission)
    }

    /// Checks every item ([`validate_item`]), that item `i` has seq `i`, and the count.
    ///
    /// # Errors
    /// The first error, in item order.
    pub fn validate(&self) -> Result<(), MissionError> {
        let count = self.items.len();
        if count > Self::MAX_ITEMS {
            return Err(MissionError::TooManyItems { count, max: Self::MAX_ITEMS });
        }
        self.items.iter().enumerate().try_for_each(|(index, item)| {
            if usize::from(item.seq) != index {
                return Err(MissionError::Sequence { index, seq: item.seq });
            }
            validate_item(item, count)
        })
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.items.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAT_DEGE7: i32 = 473_977_419;
    const LON_DEGE7: i32 = 85_455_939;

    pub(super) fn waypoint(seq: u16, x: i32, y: i32, z: f32) -> MissionItem {
        MissionItem {
            seq,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            param1: 0.0,
            param2: 0.0,
            param3: 0.0,
            param4: f32::NAN,
            x,
            y,
            z,
            autocontinue: true,
        }
    }

    pub(super) fn do_item(seq: u16, command: MavCmd, param1: f32, param2: f32) -> MissionItem {
        MissionItem {
            frame: MavFrame::MAV_FRAME_MISSION,
            command,
            param1,
            param2,
            param4: 0.0,
            x: 0,
            y: 0,
            z: 0.0,
            ..waypoint(seq, 0, 0, 0.0)
        }
    }

    fn legacy(frame: MavFrame, x: f32, y: f32) -> MISSION_ITEM_DATA {
        MISSION_ITEM_DATA {
            param1: 0.0,
            param2: 0.0,
            param3: 0.0,
            param4: 0.0,
            x,
            y,
            z: 10.0,
            seq: 0,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            target_system: 1,
            target_component: 1,
            frame,
            current: 0,
            autocontinue: 1,
            ..Default::default()
        }
    }

    #[test]
    fn given_a_legacy_item_in_a_global_frame_when_converted_then_deg_become_dege7_and_back() {
        let m = legacy(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT, 47.397_742, 8.545_594);
        let item = MissionItem::from_item(&m).expect("finite");
        assert_eq!(item.x, (f64::from(m.x) * 1e7).round() as i32);
        assert_eq!(item.y, (f64::from(m.y) * 1e7).round() as i32);
        let back = item.to_item(1, 1, false);
        assert_eq!((back.x, back.y), (m.x, m.y), "f32 deg survive the degE7 round trip");
    }

    #[test]
    fn given_legacy_items_with_nan_inf_and_local_frames_when_converted_then_unset_refused_or_scaled() {
        let nan = MissionItem::from_item(&legacy(MavFrame::MAV_FRAME_GLOBAL, f32::NAN, 8.5)).expect("NaN is unset");
        assert_eq!(nan.x, XY_UNSET);
        assert!(nan.to_item(1, 1, false).x.is_nan());
        let inf = MissionItem::from_item(&legacy(MavFrame::MAV_FRAME_GLOBAL, 47.0, f32::INFINITY));
        assert_eq!(inf.map_err(|e| e.result()), Err(MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y));
        let local = MissionItem::from_item(&legacy(MavFrame::MAV_FRAME_LOCAL_NED, 12.5, -3.25)).expect("finite");
        assert_eq!((local.x, local.y), (125_000, -32_500), "m * 1e4");
        let mission = MissionItem::from_item(&legacy(MavFrame::MAV_FRAME_MISSION, 3.0, 0.0)).expect("finite");
        assert_eq!(mission.x, 3, "MISSION frame: the parameter as a whole number");
    }

    #[test]
    fn given_every_supported_command_when_validated_then_accepted() {
        let items = vec![
            MissionItem { command: MavCmd::MAV_CMD_NAV_TAKEOFF, x: XY_UNSET, y: XY_UNSET, ..waypoint(0, 0, 0, 5.0) },
            waypoint(1, LAT_DEGE7, LON_DEGE7, 10.0),
            MissionItem { command: MavCmd::MAV_CMD_NAV_LOITER_TIME, param1: 5.0, ..waypoint(2, LAT_DEGE7, 0, 10.0) },
            MissionItem { command: MavCmd::MAV_CMD_NAV_LOITER_UNLIM, ..waypoint(3, -LAT_LIMIT_DEGE7, 0, 10.0) },
            do_item(4, MavCmd::MAV_CMD_NAV_DELAY, 2.0, 0.0),
            do_item(5, MavCmd::MAV_CMD_DO_CHANGE_SPEED, 1.0, 3.0),
            do_item(6, MavCmd::MAV_CMD_DO_JUMP, 1.0, 2.0),
            do_item(7, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0),
            MissionItem { command: MavCmd::MAV_CMD_NAV_LAND, z: f32::NAN, ..waypoint(8, XY_UNSET, XY_UNSET, 0.0) },
        ];
        assert_eq!(Mission::new(items).map(|m| m.len()), Ok(9));
    }

    #[test]
    fn given_a_jump_repeated_forever_when_validated_then_accepted_as_the_navigator_flies_it() {
        // -1 is "forever" at upload as in the navigator (DO_JUMP repeat -1); 0 (no repeat) stays valid.
        for repeat in [-1.0, 0.0, 3.0] {
            let items = vec![waypoint(0, LAT_DEGE7, LON_DEGE7, 10.0), do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.0, repeat)];
            assert_eq!(Mission::new(items).map(|m| m.len()), Ok(2), "repeat {repeat}");
        }
        // The uploaded -1 reaches the navigator as its "forever".
        let items = vec![waypoint(0, LAT_DEGE7, LON_DEGE7, 10.0), do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.0, -1.0)];
        let nav = crate::core::navigator::nav_items(&Mission::new(items).expect("accepted"));
        assert!(
            matches!(
                nav.last().map(|n| &n.command),
                Some(crate::core::navigator::NavCommand::Jump { target: 0, repeat: -1 })
            ),
            "{nav:?}"
        );
    }

    #[test]
    fn given_bad_items_when_validated_then_each_refused_with_its_result_and_a_short_reason() {
        use MavMissionResult as R;
        let cases = [
            (do_item(0, MavCmd::MAV_CMD_DO_SET_SERVO, 1.0, 1000.0), R::MAV_MISSION_UNSUPPORTED),
            (
                MissionItem { frame: MavFrame::MAV_FRAME_LOCAL_NED, ..waypoint(0, 1, 1, 1.0) },
                R::MAV_MISSION_UNSUPPORTED_FRAME,
            ),
            (
                MissionItem { frame: MavFrame::MAV_FRAME_MISSION, ..waypoint(0, 1, 1, 1.0) },
                R::MAV_MISSION_UNSUPPORTED_FRAME,
            ),
            (waypoint(0, XY_UNSET, 1, 1.0), R::MAV_MISSION_INVALID_PARAM5_X),
            (waypoint(0, LAT_LIMIT_DEGE7 + 1, 1, 1.0), R::MAV_MISSION_INVALID_PARAM5_X),
            (waypoint(0, 1, XY_UNSET, 1.0), R::MAV_MISSION_INVALID_PARAM6_Y),
            (waypoint(0, 1, -LON_LIMIT_DEGE7 - 1, 1.0), R::MAV_MISSION_INVALID_PARAM6_Y),
            (waypoint(0, 1, 1, f32::NAN), R::MAV_MISSION_INVALID_PARAM7),
            (do_item(0, MavCmd::MAV_CMD_DO_JUMP, 3.0, 1.0), R::MAV_MISSION_INVALID_PARAM1),
            (do_item(0, MavCmd::MAV_CMD_DO_JUMP, 0.0, 1.0), R::MAV_MISSION_INVALID_PARAM1),
            (do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.5, 1.0), R::MAV_MISSION_INVALID_PARAM1),
            (do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.0, -2.0), R::MAV_MISSION_INVALID_PARAM2),
            (do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.0, 1.5), R::MAV_MISSION_INVALID_PARAM2),
            (do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.0, -0.5), R::MAV_MISSION_INVALID_PARAM2),
            (do_item(1, MavCmd::MAV_CMD_DO_JUMP, 0.0, f32::NAN), R::MAV_MISSION_INVALID_PARAM2),
            (do_item(0, MavCmd::MAV_CMD_NAV_DELAY, -1.0, 0.0), R::MAV_MISSION_INVALID_PARAM1),
            (do_item(0, MavCmd::MAV_CMD_DO_CHANGE_SPEED, 1.0, f32::NAN), R::MAV_MISSION_INVALID_PARAM2),
        ];
        for (item, result) in cases {
            let err = validate_item(&item, 3).expect_err("refused");
            assert_eq!(err.result(), result, "{item:?}");
            assert!(format!("Mission: {err}").len() <= 50, "STATUSTEXT-sized: {err}");
        }
        let err = Mission::new(vec![waypoint(1, 1, 1, 1.0)]).expect_err("seq 1 at index 0");
        assert_eq!(err.result(), R::MAV_MISSION_INVALID_SEQUENCE);
    }
}
