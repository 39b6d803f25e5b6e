//! Mission items decoded for flight: what each validated [`MissionItem`] asks the navigator to do, in SI
//! units (m, s, rad) with positions still geodetic (resolved against the estimator's origin and home when
//! flown). In: a validated [`Mission`]. Out: [`NavItem`]s, in order; items that ask nothing of the flight
//! are left out. Waypoint, loiter and land yaw (param4) are degrees on the wire, NaN meaning "keep".

use ::mavlink::dialects::common::{MavCmd, MavFrame};

use super::{Mission, MissionItem, XY_UNSET, is_global_frame, xy_to_float};
use crate::core::control::frames::wrap_pi;

/// A position in a mission item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NavTarget {
    /// Latitude, longitude (deg), altitude (m) above home (`relative`) or AMSL; a NaN altitude keeps the current one.
    Global { lat_deg: f64, lon_deg: f64, alt_m: f64, relative: bool },
    /// Here: the current position (a zero or missing latitude/longitude), at this relative altitude if given.
    Here { alt_rel_m: Option<f64> },
}

/// What one mission item asks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NavCommand {
    /// Climb to the altitude (m; above home when `relative`, else AMSL; not finite: MIS_TAKEOFF_ALT).
    Takeoff {
        alt_m: f64,
        relative: bool,
    },
    /// Fly to the point; hold `hold_s`; reached within `accept_m` (None: NAV_ACC_RAD); yaw (rad).
    /// NAV_WAYPOINT flies a straight line to it (stopping there); NAV_SPLINE_WAYPOINT (`spline`) a curve
    /// through it and the spline waypoints after it, without stopping.
    Waypoint {
        target: NavTarget,
        hold_s: f64,
        accept_m: Option<f64>,
        yaw_rad: Option<f64>,
        spline: bool,
    },
    LoiterTime {
        target: NavTarget,
        time_s: f64,
        yaw_rad: Option<f64>,
    },
    LoiterUnlimited {
        target: NavTarget,
        yaw_rad: Option<f64>,
    },
    /// Fly to the point (Here: land where it is) and descend until landed.
    Land {
        target: NavTarget,
        yaw_rad: Option<f64>,
    },
    ReturnToLaunch,
    Delay {
        time_s: f64,
    },
    /// Continue at item `target` `repeat` more times (-1: forever).
    Jump {
        target: u16,
        repeat: i32,
    },
    /// Ground speed of the following legs (m/s); None: back to cruise.
    ChangeSpeed {
        speed_mps: Option<f64>,
    },
}

/// One mission item as the navigator flies it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavItem {
    pub seq: u16,
    pub command: NavCommand,
}

/// The mission's items as the navigator flies them (in order; the mission was validated on upload).
#[must_use]
pub fn nav_items(mission: &Mission) -> Vec<NavItem> {
    mission.items.iter().filter_map(nav_item).collect()
}

// The *_INT frames are deprecated in the dialect, but MAVSDK and QGroundControl send them.
#[allow(deprecated)]
fn nav_item(item: &MissionItem) -> Option<NavItem> {
    let relative =
        matches!(item.frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT);
    let target =
        if is_global_frame(item.frame) && item.x != XY_UNSET && item.y != XY_UNSET && (item.x, item.y) != (0, 0) {
            NavTarget::Global {
                lat_deg: xy_to_float(item.x, item.frame),
                lon_deg: xy_to_float(item.y, item.frame),
                alt_m: f64::from(item.z),
                relative,
            }
        } else {
            NavTarget::Here { alt_rel_m: (relative && item.z.is_finite()).then_some(f64::from(item.z)) }
        };
    let yaw = |deg: f32| deg.is_finite().then(|| wrap_pi(f64::from(deg).to_radians()));
    let command = match item.command {
        MavCmd::MAV_CMD_NAV_TAKEOFF => NavCommand::Takeoff { alt_m: f64::from(item.z), relative },
        MavCmd::MAV_CMD_NAV_WAYPOINT | MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT => NavCommand::Waypoint {
            target,
            hold_s: f64::from(item.param1).max(0.0),
            accept_m: (item.param2 > 0.0 && item.command == MavCmd::MAV_CMD_NAV_WAYPOINT)
                .then_some(f64::from(item.param2)),
            yaw_rad: yaw(item.param4).filter(|_| item.command == MavCmd::MAV_CMD_NAV_WAYPOINT),
            spline: item.command == MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT,
        },
        MavCmd::MAV_CMD_NAV_LOITER_TIME => {
            NavCommand::LoiterTime { target, time_s: f64::from(item.param1).max(0.0), yaw_rad: yaw(item.param4) }
        }
        MavCmd::MAV_CMD_NAV_LOITER_UNLIM => NavCommand::LoiterUnlimited { target, yaw_rad: yaw(item.param4) },
        MavCmd::MAV_CMD_NAV_LAND => NavCommand::Land {
            target: match target {
                NavTarget::Global { .. } => target,
                NavTarget::Here { .. } => NavTarget::Here { alt_rel_m: None },
            },
            yaw_rad: yaw(item.param4),
        },
        MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => NavCommand::ReturnToLaunch,
        MavCmd::MAV_CMD_NAV_DELAY => NavCommand::Delay { time_s: f64::from(item.param1).max(0.0) },
        MavCmd::MAV_CMD_DO_JUMP => NavCommand::Jump { target: item.param1 as u16, repeat: item.param2 as i32 },
        MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
            NavCommand::ChangeSpeed { speed_mps: (item.param2 > 0.0).then_some(f64::from(item.param2)) }
        }
        _ => return None,
    };
    Some(NavItem { seq: item.seq, command })
}
