//! The navigator: what the vehicle flies in the automatic modes, between the commander (which decides the
//! mode) and the controller. In, once per control step: vehicle time `now_us` (µs), the step `dt_s`, the
//! commander's state, the estimate (NED m, m/s, rad, with its geodetic origin), home, whether the vehicle
//! is landed; and, when they arrive, the mission (as [`NavItem`]s), offboard setpoints and goto targets.
//! Out: a [`Setpoint`] for the vehicle's reference shaping and controller, the [`NavStatus`] the commander's
//! transitions read at the next step (mission valid and done, landing, offboard fresh), and
//! [`NavEvent`]s for the ground station (MISSION_CURRENT, MISSION_ITEM_REACHED, STATUSTEXT).
//!
//! - **Paths.** Every move between points is a [`Leg`]: a straight 3D line, or a C2 cubic spline through a
//!   run of waypoints (periodic when the run closes on itself, as the paper's figure-8 does), flown by a
//!   reference whose along-track progress is prefiltered ([`spline::ProgressFilter`], critically damped,
//!   natural frequency `e·accel/speed`, so the peak acceleration of a start is `accel`). Its velocity and
//!   acceleration are exact feed-forward. The down coordinate is interpolated linearly in arc length
//!   between the waypoints' altitudes.
//! - **Missions.** Items are flown in order from `current`. Consecutive NAV_WAYPOINTs without hold time are one run,
//!   flown through without stopping (each reported reached as the reference passes it); a run ends, decelerating to
//!   rest, at a waypoint with a hold time, before any other item, and at a DO_JUMP, unless the jump repeats a run that
//!   closes on itself (in N, E and D) from its first waypoint: then the laps are flown as one leg through the seam
//!   without stopping (the figure-8 for N laps). A closed run (its last waypoint is its first) entered from elsewhere
//!   is preceded by a straight leg to its first waypoint, so the loop itself is periodic. NAV_TAKEOFF climbs at the
//!   takeoff speed; NAV_LAND flies to its point (or lands here) and descends until landed; NAV_RETURN_TO_LAUNCH runs
//!   the return below; NAV_LOITER_TIME and NAV_DELAY hold for their time, NAV_LOITER_UNLIM forever; DO_CHANGE_SPEED
//!   sets the speed of the following legs; DO_JUMP repeats from its target (param2 times, -1 forever). A mission
//!   started on the ground first climbs to its first item's altitude (at least `takeoff_alt_m`). After the last item
//!   the mission is done (the commander holds), unless it landed.
//! - **Return to launch.** Climb to `rtl_return_alt_m` above home if lower, fly to above home, land.
//! - **Hold and goto.** A new hold point (DO_REPOSITION, a pause) is flown to along a straight leg.
//! - **Offboard.** Position (with optional velocity and acceleration feed-forward), velocity (a carrot
//!   integrated from the current position, at most 1 m ahead) or attitude setpoints, with yaw or yaw
//!   rate; fresh while younger than `offboard_timeout_s` of vehicle time.
//!
//! Yaw is held at the mission's start unless a waypoint gives one (param4, degrees).

use std::collections::BTreeMap;

use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};

use ::mavlink::dialects::common::{MavCmd, MavFrame};

use crate::core::estimator::GeoOrigin;
use crate::core::mission::{Mission, MissionItem, XY_UNSET, is_global_frame, xy_to_float};

pub mod spline;

use spline::{ProgressFilter, SplinePath};

/// The navigator's parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NavigatorConfig {
    /// Horizontal cruise speed of missions, goto and return (m/s; MPC_XY_CRUISE).
    pub cruise_speed_mps: f64,
    /// Vertical speed of altitude changes between items (m/s; MPC_Z_VEL_MAX_UP).
    pub climb_speed_mps: f64,
    /// Acceleration of the path's speed profile (m/s²; MPC_ACC_HOR).
    pub accel_mps2: f64,
    /// Waypoint acceptance radius when the item names none (m; NAV_ACC_RAD).
    pub acceptance_radius_m: f64,
    /// Altitude above home to climb to before returning (m; RTL_RETURN_ALT).
    pub rtl_return_alt_m: f64,
    /// Offboard setpoints older than this end offboard control (s; COM_OF_LOSS_T).
    pub offboard_timeout_s: f64,
}

impl Default for NavigatorConfig {
    fn default() -> Self {
        Self {
            cruise_speed_mps: 1.0,
            climb_speed_mps: 1.0,
            accel_mps2: 1.0,
            acceptance_radius_m: 0.2,
            rtl_return_alt_m: 3.0,
            offboard_timeout_s: 0.5,
        }
    }
}

/// Prefilter step, as the scenario runner's (the reference is the same function of time at any rate).
const FILTER_STEP_S: f64 = 1e-4;
/// Legs shorter than this are skipped (m).
const MIN_LEG_M: f64 = 1e-3;
/// A leg has ended when the reference is this close to its end and this slow.
const LEG_END_M: f64 = 2e-3;
const LEG_END_MPS: f64 = 5e-3;
/// How far a velocity setpoint's carrot may run ahead of the vehicle (m).
const CARROT_MAX_M: f64 = 1.0;
/// Runs hold at most this many waypoints (the spline is solved once per run).
const MAX_RUN: usize = 64;

/// A position in a mission item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NavTarget {
    /// Latitude, longitude (deg), altitude (m) above home (`relative`) or AMSL.
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
    Waypoint {
        target: NavTarget,
        hold_s: f64,
        accept_m: Option<f64>,
        yaw_rad: Option<f64>,
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

/// An offboard setpoint (SET_POSITION_TARGET_* or SET_ATTITUDE_TARGET), already in local NED.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OffboardSetpoint {
    pub pos_ned_m: Option<Vector3<f64>>,
    pub vel_ned_mps: Option<Vector3<f64>>,
    pub acc_ned_mps2: Option<Vector3<f64>>,
    pub yaw_rad: Option<f64>,
    pub yaw_rate_radps: Option<f64>,
    /// Attitude (ZYX Euler rad); without `thrust_frac` the altitude is held where offboard attitude
    /// control began.
    pub attitude_rad: Option<Vector3<f64>>,
    /// Normalized collective thrust 0-1 with an attitude (SET_ATTITUDE_TARGET.thrust).
    pub thrust_frac: Option<f64>,
}

/// What the vehicle's reference shaping and controller should fly (NED m, m/s, m/s², rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NavSetpoint {
    /// Follow a moving reference with feed-forward.
    Track { pos_ned_m: Vector3<f64>, vel_ned_mps: Vector3<f64>, acc_ned_mps2: Vector3<f64>, yaw_rad: f64 },
    /// Climb (or descend) vertically to this point at the takeoff speed.
    Climb { pos_ned_m: Vector3<f64>, yaw_rad: f64 },
    /// Descend here at the land speed until landed.
    Descend { pos_ne_m: Vector2<f64>, yaw_rad: f64 },
    /// Attitude-only control: altitude held at `pos_d_m`, or with `thrust_frac` the collective given
    /// directly (`pos_d_m` then follows the vehicle, so the altitude loop has nothing to wind up).
    Attitude { euler_rad: Vector3<f64>, pos_d_m: f64, thrust_frac: Option<f64> },
}

/// What the commander's transitions read (from the previous step).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NavStatus {
    /// A mission is loaded and can be flown (the estimator has a geodetic origin).
    pub mission_valid: bool,
    /// The mission flew its last item (and did not land).
    pub mission_done: bool,
    /// Descending to land in an automatic mode (auto-disarm applies once landed).
    pub landing: bool,
    /// An offboard setpoint younger than the timeout.
    pub offboard_fresh: bool,
}

/// Something the ground station hears about.
#[derive(Debug, Clone, PartialEq)]
pub enum NavEvent {
    /// The item the mission is now flying towards (MISSION_CURRENT).
    Current(u16),
    /// An item was reached (MISSION_ITEM_REACHED).
    Reached(u16),
    /// A STATUSTEXT (info).
    Text(String),
}

/// Which automatic behaviour the commander is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AutoMode {
    Mission,
    ReturnToLaunch,
    Offboard,
}

/// One step's inputs.
#[derive(Debug, Clone, Copy)]
pub struct NavInput {
    pub now_us: u64,
    pub dt_s: f64,
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    pub yaw_rad: f64,
    pub origin: Option<GeoOrigin>,
    /// Home (NED m); its down coordinate is the ground.
    pub home_ned_m: Option<Vector3<f64>>,
    /// Home altitude (m AMSL), for AMSL targets.
    pub home_alt_amsl_m: Option<f64>,
    pub landed: bool,
    /// Default takeoff altitude above home (m; MIS_TAKEOFF_ALT).
    pub takeoff_alt_m: f64,
    /// Takeoff acceptance (m).
    pub takeoff_acceptance_m: f64,
}

/// The mission's items as the navigator flies them (in order; the mission was validated on upload).
/// Waypoint and loiter yaw (param4) and land yaw are degrees on the wire; NaN means "keep".
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
    let yaw = |deg: f32| deg.is_finite().then(|| crate::core::control::frames::wrap_pi(f64::from(deg).to_radians()));
    let command = match item.command {
        MavCmd::MAV_CMD_NAV_TAKEOFF => NavCommand::Takeoff { alt_m: f64::from(item.z), relative },
        MavCmd::MAV_CMD_NAV_WAYPOINT => NavCommand::Waypoint {
            target,
            hold_s: f64::from(item.param1).max(0.0),
            accept_m: (item.param2 > 0.0).then_some(f64::from(item.param2)),
            yaw_rad: yaw(item.param4),
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

/// The shape of a leg.
#[derive(Debug, Clone)]
enum LegPath {
    Line {
        from: Vector3<f64>,
        to: Vector3<f64>,
    },
    /// A horizontal spline; `alt` holds (arc length, down) at each knot.
    Spline {
        path: SplinePath,
        alt: Vec<(f64, f64)>,
    },
}

impl LegPath {
    fn length_m(&self) -> f64 {
        match self {
            Self::Line { from, to } => (to - from).norm(),
            Self::Spline { path, .. } => path.length_m(),
        }
    }

    /// Position, first and second derivatives with respect to the progress `s_m`.
    fn eval(&self, s_m: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        match self {
            Self::Line { from, to } => {
                let len = (to - from).norm();
                let t = if len > 0.0 { (to - from) / len } else { Vector3::zeros() };
                (from + t * s_m.clamp(0.0, len), t, Vector3::zeros())
            }
            Self::Spline { path, alt } => {
                let (p, t, k) = path.eval(s_m);
                // A closed run flown for laps (through a DO_JUMP) is closed in altitude too.
                let len = path.length_m();
                let s = if path.closed() && s_m > len { s_m.rem_euclid(len) } else { s_m.clamp(0.0, len) };
                let j = alt.partition_point(|&(a, _)| a <= s).clamp(1, alt.len() - 1);
                let ((s0, d0), (s1, d1)) = (alt[j - 1], alt[j]);
                let slope = if s1 > s0 { (d1 - d0) / (s1 - s0) } else { 0.0 };
                let d = d0 + slope * (s - s0);
                (Vector3::new(p.x, p.y, d), Vector3::new(t.x, t.y, slope), Vector3::new(k.x, k.y, 0.0))
            }
        }
    }
}

/// A move along a path at a speed, and the items whose points lie on it.
#[derive(Debug, Clone)]
struct Leg {
    path: LegPath,
    filter: ProgressFilter,
    /// The unfiltered progress (m), moved at `speed_mps` up to the length.
    target_m: f64,
    speed_mps: f64,
    yaw_rad: f64,
    /// (arc length, item seq) of each point on the leg after its start, in order; the last is its end.
    knots: Vec<(f64, u16)>,
    /// Knots reported reached so far.
    passed: usize,
    /// The progress (m) at which the leg ends: the path's length, or whole laps of a closed path.
    length_m: f64,
    /// More laps of a closed run, when a DO_JUMP repeats it.
    laps: Option<Laps>,
}

/// The laps still to fly of a closed run that a DO_JUMP repeats from its first waypoint.
#[derive(Debug, Clone)]
struct Laps {
    /// One lap's length (m) and knots, from its start: the jump, then the run's waypoints.
    lap_m: f64,
    knots: Vec<(f64, u16)>,
    /// Laps left to add (None: forever, a DO_JUMP repeat of -1).
    left: Option<u32>,
}

impl Leg {
    fn new(path: LegPath, speed_mps: f64, accel_mps2: f64, yaw_rad: f64, knots: Vec<(f64, u16)>) -> Self {
        let speed = speed_mps.max(0.01);
        let wn = (std::f64::consts::E * accel_mps2.max(0.01) / speed).clamp(0.2, 20.0);
        Self {
            filter: ProgressFilter::at_rest(wn, 0.0),
            target_m: 0.0,
            speed_mps: speed,
            yaw_rad,
            knots,
            passed: 0,
            length_m: path.length_m(),
            laps: None,
            path,
        }
    }

    /// Fly this leg `repeat` more times (-1: forever) through the DO_JUMP `jump_seq` at its end, without
    /// stopping, if it is a spline closed in all three axes (otherwise it stays as it is).
    fn repeat_laps(&mut self, jump_seq: u16, repeat: i32) {
        let LegPath::Spline { path, alt } = &self.path else {
            return;
        };
        let closed_d = matches!((alt.first(), alt.last()), (Some(a), Some(b)) if (a.1 - b.1).abs() < MIN_LEG_M);
        if repeat == 0 || !path.closed() || !closed_d {
            return;
        }
        let mut knots = vec![(0.0, jump_seq)];
        knots.extend_from_slice(&self.knots);
        let left = u32::try_from(repeat).ok();
        self.laps = Some(Laps { lap_m: path.length_m(), knots, left });
    }

    /// Adds a lap at the end, if any are left: the reference then runs on through the seam.
    fn extend_lap(&mut self) {
        let Some(laps) = &mut self.laps else { return };
        if laps.left == Some(0) {
            return;
        }
        if let Some(n) = &mut laps.left {
            *n -= 1;
        }
        self.knots.drain(..self.passed);
        self.passed = 0;
        let base = self.length_m;
        self.knots.extend(laps.knots.iter().map(|&(s, seq)| (base + s, seq)));
        self.length_m += laps.lap_m;
    }

    fn line(
        from: Vector3<f64>,
        to: Vector3<f64>,
        cfg: &NavigatorConfig,
        speed: f64,
        yaw: f64,
        seq: Option<u16>,
    ) -> Self {
        let len = (to - from).norm();
        let knots = seq.map(|s| vec![(len, s)]).unwrap_or_default();
        Self::new(LegPath::Line { from, to }, speed, cfg.accel_mps2, yaw, knots)
    }

    fn advance(&mut self, dt_s: f64) {
        let steps = (dt_s / FILTER_STEP_S).round().max(1.0) as u32;
        let h = dt_s / f64::from(steps);
        for _ in 0..steps {
            let next_m = self.target_m + self.speed_mps * h;
            if next_m > self.length_m {
                self.extend_lap();
            }
            self.target_m = next_m.min(self.length_m);
            self.filter.step(self.target_m, h);
        }
        let len = self.length_m;
        if self.filter.s_m > len {
            self.filter.s_m = len;
            self.filter.s_dot_mps = self.filter.s_dot_mps.min(0.0);
        }
    }

    fn setpoint(&self) -> NavSetpoint {
        let s = self.filter.s_m;
        let (s_dot, s_ddot) = (self.filter.s_dot_mps, self.filter.accel_mps2(self.target_m));
        let (p, dp, d2p) = self.path.eval(s);
        NavSetpoint::Track {
            pos_ned_m: p,
            vel_ned_mps: dp * s_dot,
            acc_ned_mps2: d2p * s_dot * s_dot + dp * s_ddot,
            yaw_rad: self.yaw_rad,
        }
    }

    fn end(&self) -> Vector3<f64> {
        self.path.eval(self.length_m).0
    }

    fn at_end(&self) -> bool {
        self.length_m - self.filter.s_m <= LEG_END_M && self.filter.s_dot_mps.abs() <= LEG_END_MPS
    }

    /// Knots the reference has passed since the last call (all but the end, which needs arrival).
    fn newly_passed(&mut self) -> Vec<u16> {
        let mut out = Vec::new();
        while self.passed + 1 < self.knots.len() && self.filter.s_m >= self.knots[self.passed].0 {
            out.push(self.knots[self.passed].1);
            self.passed += 1;
        }
        out
    }
}

/// Where a mission is within its current item.
#[derive(Debug, Clone)]
enum Phase {
    /// Nothing started yet: start the item at `current`.
    Start,
    /// Climbing to this point (NAV_TAKEOFF, or the implicit climb of a mission started on the ground);
    /// then `then` (None: the takeoff item itself is reached).
    Climb { to: Vector3<f64>, item: Option<u16> },
    /// Flying a leg; on arrival at its end the item `end_item` starts holding `hold_s` (then the next item).
    Fly { leg: Box<Leg>, end_item: u16, hold_s: f64, accept_m: f64, then: After },
    /// Holding a point until `until_us` (None: forever).
    Wait { at: Vector3<f64>, until_us: Option<u64>, item: u16 },
    /// Descending to land (NAV_LAND).
    Descend { ne: Vector2<f64>, item: Option<u16> },
    /// Returning to launch (NAV_RETURN_TO_LAUNCH): reached once landed at home.
    Return { item: u16 },
    /// The mission flew its last item.
    Done,
    /// The mission ended on the ground here: it stays landing (the commander disarms after touchdown).
    Landed { ne: Vector2<f64> },
}

/// What happens when a [`Phase::Fly`] leg arrives.
#[derive(Debug, Clone, Copy, PartialEq)]
enum After {
    /// Hold `hold_s`, report the item reached, go on with the next item.
    Next,
    /// Hold for the time (loiter), then the next item; `None`: forever.
    Loiter(Option<f64>),
    /// Descend and land.
    Land,
    /// At the first waypoint of a closed loop: plan the item again from here (nothing is reported).
    Restart,
}

/// Return-to-launch progress.
#[derive(Debug, Clone)]
enum RtlPhase {
    /// A vertical leg up to the return altitude (prefiltered, so it stops without overshoot).
    Climb(Leg),
    Return(Leg),
    Descend(Vector2<f64>),
}

/// The navigator. See the module docs.
#[derive(Debug, Clone)]
pub struct Navigator {
    config: NavigatorConfig,
    items: Vec<NavItem>,
    current: usize,
    phase: Phase,
    /// Remaining repeats of each DO_JUMP (by seq), set on first use.
    jumps: BTreeMap<u16, i32>,
    speed_mps: Option<f64>,
    yaw_rad: f64,
    rtl: Option<RtlPhase>,
    /// The last reference position flown (legs start here).
    last_ref_ned_m: Option<Vector3<f64>>,
    hold: Option<(Vector3<f64>, Leg)>,
    offboard: Option<(u64, OffboardSetpoint)>,
    carrot_ned_m: Option<Vector3<f64>>,
    offboard_yaw_rad: Option<f64>,
    attitude_hold_d_m: Option<f64>,
    last_mode: Option<AutoMode>,
    status: NavStatus,
    events: Vec<NavEvent>,
    last_current: Option<u16>,
}

impl Navigator {
    #[must_use]
    pub fn new(config: NavigatorConfig) -> Self {
        Self {
            config,
            items: Vec::new(),
            current: 0,
            phase: Phase::Start,
            jumps: BTreeMap::new(),
            speed_mps: None,
            yaw_rad: 0.0,
            rtl: None,
            last_ref_ned_m: None,
            hold: None,
            offboard: None,
            carrot_ned_m: None,
            offboard_yaw_rad: None,
            attitude_hold_d_m: None,
            last_mode: None,
            status: NavStatus::default(),
            events: Vec::new(),
            last_current: None,
        }
    }

    /// New parameters, from the next step (legs under way keep their speed).
    pub fn set_config(&mut self, config: NavigatorConfig) {
        self.config = config;
    }

    #[must_use]
    pub fn config(&self) -> &NavigatorConfig {
        &self.config
    }

    /// A new mission (replacing the old one), to start at its first item.
    pub fn set_mission(&mut self, items: Vec<NavItem>) {
        self.items = items;
        self.set_current(0);
    }

    /// Continue the mission at the item of sequence number `seq` (MISSION_SET_CURRENT, MISSION_START).
    pub fn set_current(&mut self, seq: u16) {
        self.current = self.items.iter().position(|i| i.seq == seq).unwrap_or(0);
        self.phase = Phase::Start;
        self.jumps.clear();
        self.last_current = None;
        self.status.mission_done = false;
    }

    /// The sequence number of the item the mission flies towards (or its last, once done).
    #[must_use]
    pub fn current_seq(&self) -> u16 {
        self.items.get(self.current.min(self.items.len().saturating_sub(1))).map_or(0, |i| i.seq)
    }

    #[must_use]
    pub fn mission_len(&self) -> usize {
        self.items.len()
    }

    /// The latest offboard setpoint, received at `now_us`.
    pub fn set_offboard(&mut self, now_us: u64, setpoint: OffboardSetpoint) {
        self.offboard = Some((now_us, setpoint));
    }

    /// DO_CHANGE_SPEED outside a mission: the speed of the following legs.
    pub fn set_speed(&mut self, speed_mps: Option<f64>) {
        self.speed_mps = speed_mps.filter(|s| s.is_finite() && *s > 0.0);
    }

    /// What the commander reads.
    #[must_use]
    pub fn status(&self) -> NavStatus {
        self.status
    }

    /// The events since the last call.
    pub fn take_events(&mut self) -> Vec<NavEvent> {
        std::mem::take(&mut self.events)
    }

    fn speed(&self) -> f64 {
        self.speed_mps.unwrap_or(self.config.cruise_speed_mps)
    }

    /// Refreshes the status for the commander's next step: mission valid, offboard fresh.
    pub fn refresh(&mut self, now_us: u64, origin: Option<GeoOrigin>) {
        self.status.mission_valid = !self.items.is_empty() && origin.is_some();
        let timeout_us = (self.config.offboard_timeout_s.max(0.0) * 1e6) as u64;
        self.status.offboard_fresh = self.offboard.is_some_and(|(t, _)| now_us.saturating_sub(t) <= timeout_us);
    }

    /// Hold `target` (NED m) at `yaw_rad`: flown to along a straight leg from the last reference when it
    /// moved. Returns the setpoint.
    pub fn hold(&mut self, input: &NavInput, target: Vector3<f64>, yaw_rad: f64) -> NavSetpoint {
        self.leave_auto();
        let from = self.last_ref_ned_m.unwrap_or(input.pos_ned_m);
        let keep = self.hold.take().filter(|(t, leg)| (t - target).norm() <= MIN_LEG_M && leg.yaw_rad == yaw_rad);
        let (target, mut leg) =
            keep.unwrap_or_else(|| (target, Leg::line(from, target, &self.config, self.speed(), yaw_rad, None)));
        leg.advance(input.dt_s);
        let sp = leg.setpoint();
        self.hold = Some((target, leg));
        self.remember(&sp);
        sp
    }

    /// The reference position of a setpoint flown by the vehicle (a leg starts where the last ended).
    pub fn remember(&mut self, sp: &NavSetpoint) {
        self.last_ref_ned_m = match *sp {
            NavSetpoint::Track { pos_ned_m, .. } | NavSetpoint::Climb { pos_ned_m, .. } => Some(pos_ned_m),
            NavSetpoint::Descend { .. } | NavSetpoint::Attitude { .. } => None,
        };
    }

    /// The vehicle flew something the navigator did not plan (takeoff, land, idle): legs restart from
    /// the vehicle, and a later hold is planned afresh.
    pub fn forget(&mut self) {
        self.last_ref_ned_m = None;
        self.hold = None;
        self.leave_auto();
    }

    fn leave_auto(&mut self) {
        self.last_mode = None;
        self.rtl = None;
        self.carrot_ned_m = None;
        self.attitude_hold_d_m = None;
        self.status.landing = false;
    }

    /// One step in `mode`.
    pub fn update(&mut self, mode: AutoMode, input: &NavInput) -> NavSetpoint {
        self.hold = None;
        if self.last_mode != Some(mode) {
            self.rtl = None;
            if mode == AutoMode::Mission && !matches!(self.phase, Phase::Done | Phase::Landed { .. }) {
                // Resume the current item from where the vehicle is.
                self.phase = Phase::Start;
            }
            self.carrot_ned_m = None;
            self.attitude_hold_d_m = None;
            self.offboard_yaw_rad = None;
            self.yaw_rad = input.yaw_rad;
            self.last_mode = Some(mode);
        }
        self.status.landing = false;
        let sp = match mode {
            AutoMode::Mission => self.mission_step(input),
            AutoMode::ReturnToLaunch => self.rtl_step(input),
            AutoMode::Offboard => self.offboard_step(input),
        };
        self.remember(&sp);
        sp
    }

    /// Where a leg starts: the last reference, or the vehicle.
    fn start_point(&self, input: &NavInput) -> Vector3<f64> {
        self.last_ref_ned_m.unwrap_or(input.pos_ned_m)
    }

    fn ground_d_m(input: &NavInput) -> f64 {
        input.home_ned_m.map_or(0.0, |h| h.z)
    }

    /// The local NED point of `target`, with `here` for "here".
    fn resolve(input: &NavInput, target: &NavTarget, here: Vector3<f64>) -> Option<Vector3<f64>> {
        match *target {
            NavTarget::Here { alt_rel_m } => {
                Some(Vector3::new(here.x, here.y, alt_rel_m.map_or(here.z, |a| Self::ground_d_m(input) - a)))
            }
            NavTarget::Global { lat_deg, lon_deg, alt_m, relative } => {
                let origin = input.origin?;
                let alt_amsl_m = if relative { input.home_alt_amsl_m? + alt_m } else { alt_m };
                let p = origin.ned_from_geodetic(lat_deg, lon_deg, alt_amsl_m);
                p.iter().all(|x| x.is_finite()).then_some(p)
            }
        }
    }

    fn emit_current(&mut self) {
        let seq = self.current_seq();
        if self.last_current != Some(seq) {
            self.last_current = Some(seq);
            self.events.push(NavEvent::Current(seq));
        }
    }

    /// The repeats left of the DO_JUMP `seq` (its param2 `repeat` until first taken; -1 is forever).
    fn jumps_left(&self, seq: u16, repeat: i32) -> i32 {
        self.jumps.get(&seq).copied().unwrap_or(repeat)
    }

    /// Takes the DO_JUMP `seq` if it has repeats left, counting one off; `false` once it is used up.
    fn take_jump(&mut self, seq: u16, repeat: i32) -> bool {
        let left = self.jumps.entry(seq).or_insert(repeat);
        if *left == 0 {
            return false;
        }
        if *left > 0 {
            *left -= 1;
        }
        true
    }

    /// On to the next item (past the last: the mission finishes at the next step).
    fn advance_item(&mut self) {
        self.current += 1;
        self.phase = Phase::Start;
    }

    fn finish(&mut self, input: &NavInput) -> NavSetpoint {
        self.phase = Phase::Done;
        self.status.mission_done = true;
        self.current = self.items.len().saturating_sub(1);
        self.events.push(NavEvent::Text("Mission finished".into()));
        NavSetpoint::Track {
            pos_ned_m: self.start_point(input),
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            yaw_rad: self.yaw_rad,
        }
    }

    fn still(&self, at: Vector3<f64>) -> NavSetpoint {
        NavSetpoint::Track {
            pos_ned_m: at,
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            yaw_rad: self.yaw_rad,
        }
    }

    fn mission_step(&mut self, input: &NavInput) -> NavSetpoint {
        // Items that start at once (DO items, a finished jump) are handled in one step, boundedly.
        for _ in 0..=self.items.len() + 1 {
            if matches!(self.phase, Phase::Start) {
                if self.current >= self.items.len() {
                    return self.finish(input);
                }
                self.emit_current();
                if !self.start_item(input) {
                    continue;
                }
            }
            return self.run_phase(input);
        }
        self.finish(input)
    }

    /// Starts the item at `current`; `false` when it completed at once (the loop goes on).
    fn start_item(&mut self, input: &NavInput) -> bool {
        let item = self.items[self.current];
        let here = self.start_point(input);
        let ground = Self::ground_d_m(input);
        // On the ground, any moving item first climbs (at least to the takeoff altitude).
        let climb_first = |to: Vector3<f64>| -> Option<Vector3<f64>> {
            let min_d = ground - input.takeoff_alt_m;
            input.landed.then(|| Vector3::new(input.pos_ned_m.x, input.pos_ned_m.y, to.z.min(min_d)))
        };
        match item.command {
            NavCommand::Takeoff { alt_m, relative } => {
                let alt_rel_m = match (relative, input.home_alt_amsl_m) {
                    (true, _) => alt_m,
                    (false, Some(home)) => alt_m - home,
                    (false, None) => f64::NAN,
                };
                let alt = if alt_rel_m.is_finite() && alt_rel_m > 0.0 { alt_rel_m } else { input.takeoff_alt_m };
                let to = Vector3::new(input.pos_ned_m.x, input.pos_ned_m.y, ground - alt);
                self.phase = Phase::Climb { to, item: Some(item.seq) };
            }
            NavCommand::ChangeSpeed { speed_mps } => {
                self.set_speed(speed_mps);
                self.events.push(NavEvent::Reached(item.seq));
                self.advance_item();
                return false;
            }
            NavCommand::Jump { target, repeat } => {
                let target_index = self.items.iter().position(|i| i.seq == target);
                match target_index {
                    Some(t) if self.take_jump(item.seq, repeat) => {
                        self.events.push(NavEvent::Reached(item.seq));
                        self.current = t;
                        self.phase = Phase::Start;
                    }
                    _ => {
                        self.events.push(NavEvent::Reached(item.seq));
                        self.advance_item();
                    }
                }
                return false;
            }
            NavCommand::Delay { time_s } => {
                let until = input.now_us + (time_s.max(0.0) * 1e6) as u64;
                self.phase = Phase::Wait { at: here, until_us: Some(until), item: item.seq };
            }
            NavCommand::ReturnToLaunch => {
                self.rtl = None;
                self.phase = Phase::Return { item: item.seq };
            }
            NavCommand::Waypoint { .. }
            | NavCommand::LoiterTime { .. }
            | NavCommand::LoiterUnlimited { .. }
            | NavCommand::Land { .. } => {
                let Some(leg_phase) = self.plan_flight(input, here) else {
                    self.events.push(NavEvent::Text(format!("Mission item {} has no position: skipped", item.seq)));
                    self.advance_item();
                    return false;
                };
                let target_d = match &leg_phase {
                    Phase::Fly { leg, .. } => leg.end().z,
                    _ => here.z,
                };
                if let Some(to) = climb_first(Vector3::new(here.x, here.y, target_d)) {
                    self.phase = Phase::Climb { to, item: None };
                    return true;
                }
                self.phase = leg_phase;
            }
        }
        true
    }

    /// The leg (or run of legs) of the flying item at `current`, starting at `from`.
    fn plan_flight(&mut self, input: &NavInput, from: Vector3<f64>) -> Option<Phase> {
        let item = self.items[self.current];
        let accept_default = self.config.acceptance_radius_m;
        match item.command {
            NavCommand::Waypoint { .. } => {
                // The run: this waypoint and the waypoints after it without hold time.
                let mut points = vec![from];
                let mut knots: Vec<u16> = Vec::new();
                let mut idx = self.current;
                let mut last_hold = 0.0;
                let mut last_accept = accept_default;
                let mut yaw = None;
                while idx < self.items.len() && knots.len() < MAX_RUN {
                    let NavCommand::Waypoint { target, hold_s, accept_m, yaw_rad } = self.items[idx].command else {
                        break;
                    };
                    let p = Self::resolve(input, &target, *points.last().unwrap_or(&from))?;
                    if knots.is_empty() && (p - from).norm() < MIN_LEG_M {
                        // The run starts at the vehicle's point: the first waypoint is its start.
                        points[0] = p;
                    } else {
                        points.push(p);
                    }
                    knots.push(self.items[idx].seq);
                    yaw = yaw.or(yaw_rad);
                    last_hold = hold_s.max(0.0);
                    last_accept = accept_m.filter(|a| *a > 0.0).unwrap_or(accept_default);
                    idx += 1;
                    if hold_s > 0.0 {
                        break;
                    }
                }
                if let Some(y) = yaw {
                    self.yaw_rad = y;
                }
                let end_item = *knots.last()?;
                // A closed loop of waypoints (the figure-8) entered from elsewhere, even from a few
                // centimetres away: fly to its first waypoint, then the loop itself, periodic.
                if let (&[first_seq, .., _], &[_, first, .., last]) = (knots.as_slice(), points.as_slice())
                    && knots.len() >= 4
                    && points.len() > knots.len()
                    && (first - last).norm() < MIN_LEG_M
                {
                    let leg = Leg::line(from, first, &self.config, self.speed(), self.yaw_rad, Some(first_seq));
                    let (leg, accept_m) = (Box::new(leg), accept_default);
                    return Some(Phase::Fly { leg, end_item: first_seq, hold_s: 0.0, accept_m, then: After::Restart });
                }
                // A run that ends where it starts (to within rounding: the start is the last leg's end) is
                // closed exactly, so its spline is periodic.
                if let [first, .., last] = points.as_mut_slice()
                    && (*first - *last).norm() < MIN_LEG_M
                {
                    *first = *last;
                }
                let mut leg = self.run_leg(&points, &knots, from)?;
                // A DO_JUMP right after a closed run, back to its first waypoint (the figure-8 flown for
                // laps): the laps are one leg, flown through the seam without stopping.
                if let Some(&NavItem { seq: jump_seq, command: NavCommand::Jump { target, repeat } }) =
                    self.items.get(idx)
                    && last_hold <= 0.0
                    && knots.first() == Some(&target)
                {
                    leg.repeat_laps(jump_seq, self.jumps_left(jump_seq, repeat));
                }
                // Items of the run before its end are passed on the way; `current` moves as they are.
                Some(Phase::Fly {
                    leg: Box::new(leg),
                    end_item,
                    hold_s: last_hold,
                    accept_m: last_accept,
                    then: After::Next,
                })
            }
            NavCommand::LoiterTime { target, time_s, yaw_rad } => {
                self.loiter_leg(input, from, item.seq, target, yaw_rad, Some(time_s.max(0.0)))
            }
            NavCommand::LoiterUnlimited { target, yaw_rad } => {
                self.loiter_leg(input, from, item.seq, target, yaw_rad, None)
            }
            NavCommand::Land { target, yaw_rad } => {
                if let Some(y) = yaw_rad {
                    self.yaw_rad = y;
                }
                let to = Self::resolve(input, &target, from)?;
                let to = Vector3::new(to.x, to.y, from.z);
                let leg = Leg::line(from, to, &self.config, self.speed(), self.yaw_rad, Some(item.seq));
                Some(Phase::Fly {
                    leg: Box::new(leg),
                    end_item: item.seq,
                    hold_s: 0.0,
                    accept_m: accept_default,
                    then: After::Land,
                })
            }
            _ => None,
        }
    }

    /// Fly to `target` and loiter there for `time_s` (None: forever).
    fn loiter_leg(
        &mut self,
        input: &NavInput,
        from: Vector3<f64>,
        seq: u16,
        target: NavTarget,
        yaw_rad: Option<f64>,
        time_s: Option<f64>,
    ) -> Option<Phase> {
        let to = Self::resolve(input, &target, from)?;
        if let Some(y) = yaw_rad {
            self.yaw_rad = y;
        }
        let leg = Leg::line(from, to, &self.config, self.speed(), self.yaw_rad, Some(seq));
        let accept_m = self.config.acceptance_radius_m;
        Some(Phase::Fly { leg: Box::new(leg), end_item: seq, hold_s: 0.0, accept_m, then: After::Loiter(time_s) })
    }

    /// A leg through `points` (the first is the start): a line for two, a spline for more.
    fn run_leg(&self, points: &[Vector3<f64>], knots: &[u16], from: Vector3<f64>) -> Option<Leg> {
        if points.len() <= 2 {
            let to = *points.last()?;
            return Some(Leg::line(from, to, &self.config, self.speed(), self.yaw_rad, knots.last().copied()));
        }
        let ne: Vec<[f64; 2]> = points.iter().map(|p| [p.x, p.y]).collect();
        // Consecutive equal points (a vertical-only move inside a run) cannot be splined: fly the run as
        // lines up to its first such point.
        let Some(path) = SplinePath::try_new(&ne) else {
            return Some(Leg::line(from, points[1], &self.config, self.speed(), self.yaw_rad, knots.first().copied()));
        };
        let offset = usize::from(points.len() > knots.len());
        let alt: Vec<(f64, f64)> = (0..points.len()).map(|i| (path.knot_arc_m(i), points[i].z)).collect();
        let knot_arcs: Vec<(f64, u16)> =
            knots.iter().enumerate().map(|(i, &seq)| (path.knot_arc_m(i + offset), seq)).collect();
        Some(Leg::new(LegPath::Spline { path, alt }, self.speed(), self.config.accel_mps2, self.yaw_rad, knot_arcs))
    }

    fn run_phase(&mut self, input: &NavInput) -> NavSetpoint {
        match &mut self.phase {
            Phase::Start | Phase::Done => self.still(self.last_ref_ned_m.unwrap_or(input.pos_ned_m)),
            Phase::Landed { ne } => {
                self.status.landing = true;
                NavSetpoint::Descend { pos_ne_m: *ne, yaw_rad: self.yaw_rad }
            }
            Phase::Climb { to, item } => {
                let (to, item) = (*to, *item);
                if (input.pos_ned_m.z - to.z).abs() <= input.takeoff_acceptance_m && !input.landed {
                    self.last_ref_ned_m = Some(to);
                    match item {
                        Some(seq) => {
                            self.events.push(NavEvent::Reached(seq));
                            self.advance_item();
                        }
                        None => self.phase = Phase::Start,
                    }
                    return self.still(to);
                }
                NavSetpoint::Climb { pos_ned_m: to, yaw_rad: self.yaw_rad }
            }
            Phase::Fly { leg, end_item, hold_s, accept_m, then } => {
                leg.advance(input.dt_s);
                let passed = leg.newly_passed();
                let (end_item, hold_s, accept_m, then) = (*end_item, *hold_s, *accept_m, *then);
                let arrived = leg.at_end() && (input.pos_ned_m - leg.end()).norm() <= accept_m;
                let sp = leg.setpoint();
                let end = leg.end();
                for seq in passed {
                    self.events.push(NavEvent::Reached(seq));
                    let Some(i) = self.items.iter().position(|i| i.seq == seq) else { continue };
                    if let NavCommand::Jump { target, repeat } = self.items[i].command {
                        // A lap of a repeated run ended: the jump is taken as start_item would take it
                        // (the leg has a lap only while the jump has repeats left).
                        self.take_jump(seq, repeat);
                        self.current = self.items.iter().position(|i| i.seq == target).unwrap_or(i);
                    } else {
                        self.current = i + 1;
                    }
                    self.emit_current();
                }
                if arrived {
                    self.current = self.items.iter().position(|i| i.seq == end_item).unwrap_or(self.current);
                    match then {
                        After::Next if hold_s <= 0.0 => {
                            self.events.push(NavEvent::Reached(end_item));
                            self.last_ref_ned_m = Some(end);
                            self.advance_item();
                        }
                        After::Next => {
                            let until = input.now_us + (hold_s * 1e6) as u64;
                            self.phase = Phase::Wait { at: end, until_us: Some(until), item: end_item };
                        }
                        After::Loiter(time) => {
                            let until = time.map(|t| input.now_us + (t * 1e6) as u64);
                            self.phase = Phase::Wait { at: end, until_us: until, item: end_item };
                        }
                        After::Land => self.phase = Phase::Descend { ne: end.xy(), item: Some(end_item) },
                        After::Restart => {
                            self.last_ref_ned_m = Some(end);
                            self.phase = Phase::Start;
                        }
                    }
                }
                sp
            }
            Phase::Wait { at, until_us, item } => {
                let (at, until, item) = (*at, *until_us, *item);
                if until.is_some_and(|u| input.now_us >= u) {
                    self.events.push(NavEvent::Reached(item));
                    self.last_ref_ned_m = Some(at);
                    self.advance_item();
                }
                self.still(at)
            }
            Phase::Descend { ne, item } => {
                let (ne, item) = (*ne, *item);
                self.status.landing = true;
                if input.landed {
                    self.landed_at_end(item, ne);
                }
                NavSetpoint::Descend { pos_ne_m: ne, yaw_rad: self.yaw_rad }
            }
            Phase::Return { item } => {
                let item = *item;
                let sp = self.rtl_step(input);
                if self.status.landing && input.landed {
                    self.landed_at_end(Some(item), input.pos_ned_m.xy());
                }
                sp
            }
        }
    }

    /// The mission ended on the ground (NAV_LAND, NAV_RETURN_TO_LAUNCH): the item is reached, and the
    /// mission done (the commander disarms after landing).
    fn landed_at_end(&mut self, item: Option<u16>, ne: Vector2<f64>) {
        if let Some(seq) = item {
            self.events.push(NavEvent::Reached(seq));
        }
        self.phase = Phase::Landed { ne };
        self.events.push(NavEvent::Text("Mission finished: landed".into()));
    }

    fn rtl_step(&mut self, input: &NavInput) -> NavSetpoint {
        let here = self.start_point(input);
        let home = input.home_ned_m.unwrap_or(Vector3::new(input.pos_ned_m.x, input.pos_ned_m.y, 0.0));
        let return_d = (home.z - self.config.rtl_return_alt_m).min(here.z);
        let phase = self.rtl.take().unwrap_or_else(|| {
            if here.z > return_d + input.takeoff_acceptance_m {
                let to = Vector3::new(here.x, here.y, return_d);
                RtlPhase::Climb(Leg::line(here, to, &self.config, self.config.climb_speed_mps, self.yaw_rad, None))
            } else {
                self.rtl_return_leg(here, home)
            }
        });
        let (next, sp) = match phase {
            RtlPhase::Climb(mut leg) => {
                leg.advance(input.dt_s);
                let sp = leg.setpoint();
                let to = leg.end();
                if leg.at_end() && (input.pos_ned_m.z - to.z).abs() <= input.takeoff_acceptance_m {
                    self.last_ref_ned_m = Some(to);
                    (self.rtl_return_leg(to, home), sp)
                } else {
                    (RtlPhase::Climb(leg), sp)
                }
            }
            RtlPhase::Return(mut leg) => {
                leg.advance(input.dt_s);
                let sp = leg.setpoint();
                if leg.at_end() && (input.pos_ned_m - leg.end()).xy().norm() <= self.config.acceptance_radius_m {
                    (RtlPhase::Descend(leg.end().xy()), sp)
                } else {
                    (RtlPhase::Return(leg), sp)
                }
            }
            RtlPhase::Descend(ne) => {
                self.status.landing = true;
                (RtlPhase::Descend(ne), NavSetpoint::Descend { pos_ne_m: ne, yaw_rad: self.yaw_rad })
            }
        };
        self.rtl = Some(next);
        sp
    }

    fn rtl_return_leg(&self, from: Vector3<f64>, home: Vector3<f64>) -> RtlPhase {
        let to = Vector3::new(home.x, home.y, from.z);
        if (to - from).norm() < self.config.acceptance_radius_m {
            return RtlPhase::Descend(to.xy());
        }
        RtlPhase::Return(Leg::line(from, to, &self.config, self.speed(), self.yaw_rad, None))
    }

    fn offboard_step(&mut self, input: &NavInput) -> NavSetpoint {
        let Some((_, sp)) = self.offboard else {
            return self.still(self.start_point(input));
        };
        if let Some(euler_rad) = sp.attitude_rad {
            if sp.thrust_frac.is_some() {
                // Direct thrust: were the thrust dropped later, hold the altitude the vehicle is at then.
                self.attitude_hold_d_m = Some(input.pos_ned_m.z);
            }
            let pos_d_m = *self.attitude_hold_d_m.get_or_insert(input.pos_ned_m.z);
            return NavSetpoint::Attitude { euler_rad, pos_d_m, thrust_frac: sp.thrust_frac };
        }
        self.attitude_hold_d_m = None;
        let yaw = match (sp.yaw_rad, sp.yaw_rate_radps) {
            (Some(y), _) => y,
            (None, Some(rate)) => {
                let y = self.offboard_yaw_rad.unwrap_or(input.yaw_rad) + rate * input.dt_s;
                crate::core::control::frames::wrap_pi(y)
            }
            (None, None) => self.offboard_yaw_rad.unwrap_or(input.yaw_rad),
        };
        self.offboard_yaw_rad = Some(yaw);
        let vel = sp.vel_ned_mps.unwrap_or_else(Vector3::zeros);
        let acc = sp.acc_ned_mps2.unwrap_or_else(Vector3::zeros);
        let pos = match sp.pos_ned_m {
            Some(p) => {
                self.carrot_ned_m = None;
                p
            }
            None => {
                let carrot = self.carrot_ned_m.unwrap_or(input.pos_ned_m) + vel * input.dt_s;
                let ahead = carrot - input.pos_ned_m;
                let carrot = if ahead.norm() > CARROT_MAX_M {
                    input.pos_ned_m + ahead * (CARROT_MAX_M / ahead.norm())
                } else {
                    carrot
                };
                self.carrot_ned_m = Some(carrot);
                carrot
            }
        };
        NavSetpoint::Track { pos_ned_m: pos, vel_ned_mps: vel, acc_ned_mps2: acc, yaw_rad: yaw }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORIGIN: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };
    const DT_S: f64 = 0.002;

    /// A vehicle that is where its setpoint says (climbing and descending at 1 m/s), landed at D >= 0.
    struct Ideal {
        nav: Navigator,
        pos: Vector3<f64>,
        now_us: u64,
        events: Vec<NavEvent>,
        max_speed_mps: f64,
    }

    impl Ideal {
        fn new(items: Vec<NavItem>) -> Self {
            let mut nav = Navigator::new(NavigatorConfig::default());
            nav.set_mission(items);
            Self { nav, pos: Vector3::zeros(), now_us: 0, events: Vec::new(), max_speed_mps: 0.0 }
        }

        fn input(&self) -> NavInput {
            NavInput {
                now_us: self.now_us,
                dt_s: DT_S,
                pos_ned_m: self.pos,
                vel_ned_mps: Vector3::zeros(),
                yaw_rad: 0.0,
                origin: Some(ORIGIN),
                home_ned_m: Some(Vector3::zeros()),
                home_alt_amsl_m: Some(ORIGIN.alt_amsl_m),
                landed: self.pos.z >= -1e-3,
                takeoff_alt_m: 2.5,
                takeoff_acceptance_m: 0.1,
            }
        }

        fn step(&mut self, mode: AutoMode) -> NavSetpoint {
            self.nav.refresh(self.now_us, Some(ORIGIN));
            let sp = self.nav.update(mode, &self.input());
            match sp {
                NavSetpoint::Track { pos_ned_m, vel_ned_mps, .. } => {
                    self.max_speed_mps = self.max_speed_mps.max(vel_ned_mps.xy().norm());
                    self.pos = pos_ned_m;
                }
                NavSetpoint::Climb { pos_ned_m, .. } => {
                    self.pos.x = pos_ned_m.x;
                    self.pos.y = pos_ned_m.y;
                    self.pos.z += (pos_ned_m.z - self.pos.z).clamp(-DT_S, DT_S);
                }
                NavSetpoint::Descend { pos_ne_m, .. } => {
                    self.pos = Vector3::new(pos_ne_m.x, pos_ne_m.y, (self.pos.z + DT_S).min(0.0));
                }
                NavSetpoint::Attitude { .. } => {}
            }
            self.now_us += 2_000;
            self.events.extend(self.nav.take_events());
            sp
        }

        fn run(&mut self, mode: AutoMode, seconds: f64) {
            for _ in 0..(seconds / DT_S) as usize {
                self.step(mode);
            }
        }

        fn reached(&self) -> Vec<u16> {
            self.events.iter().filter_map(|e| if let NavEvent::Reached(s) = e { Some(*s) } else { None }).collect()
        }
    }

    /// A waypoint `n_m`, `e_m` metres from the origin at `alt_m` above home.
    fn wp(seq: u16, n_m: f64, e_m: f64, alt_m: f64) -> NavItem {
        let (lat_deg, lon_deg, _) = ORIGIN.geodetic_from_ned(&Vector3::new(n_m, e_m, 0.0));
        NavItem {
            seq,
            command: NavCommand::Waypoint {
                target: NavTarget::Global { lat_deg, lon_deg, alt_m, relative: true },
                hold_s: 0.0,
                accept_m: None,
                yaw_rad: None,
            },
        }
    }

    fn figure8(first_seq: u16) -> Vec<NavItem> {
        let pts = spline::FIGURE8_NE_M;
        pts.iter().enumerate().map(|(i, &[n, e])| wp(first_seq + i as u16, n, e, 1.5)).collect()
    }

    #[test]
    fn given_takeoff_waypoints_and_land_when_flown_then_every_item_is_reached_in_order_and_it_lands() {
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
        items.extend([wp(1, 3.0, 0.0, 2.0), wp(2, 3.0, 4.0, 3.0)]);
        items.push(NavItem {
            seq: 3,
            command: NavCommand::Land { target: NavTarget::Here { alt_rel_m: None }, yaw_rad: None },
        });
        let mut v = Ideal::new(items);
        v.run(AutoMode::Mission, 40.0);
        assert_eq!(v.reached(), vec![0, 1, 2, 3]);
        assert!((v.pos - Vector3::new(3.0, 4.0, 0.0)).norm() < 0.01, "landed at {:?}", v.pos);
        assert!(!v.nav.status().mission_done, "a landed mission is not done in the air");
        assert!(v.max_speed_mps <= NavigatorConfig::default().cruise_speed_mps + 1e-6, "{}", v.max_speed_mps);
        let current: Vec<u16> =
            v.events.iter().filter_map(|e| if let NavEvent::Current(s) = e { Some(*s) } else { None }).collect();
        assert_eq!(current, vec![0, 1, 2, 3]);
    }

    #[test]
    fn given_the_figure8_as_waypoints_when_flown_then_one_closed_spline_through_every_point_without_stopping() {
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 1.5, relative: true } }];
        items.push(NavItem { seq: 1, command: NavCommand::ChangeSpeed { speed_mps: Some(0.3) } });
        items.extend(figure8(2));
        let mut v = Ideal::new(items);
        let mut closest = [f64::INFINITY; 9];
        let mut min_speed_mid_run = f64::INFINITY;
        for k in 0..(60.0 / DT_S) as usize {
            let sp = v.step(AutoMode::Mission);
            if let NavSetpoint::Track { pos_ned_m, vel_ned_mps, .. } = sp {
                for (i, item) in figure8(0).iter().enumerate() {
                    let NavCommand::Waypoint { target: NavTarget::Global { lat_deg, lon_deg, .. }, .. } = item.command
                    else {
                        continue;
                    };
                    let p = ORIGIN.ned_from_geodetic(lat_deg, lon_deg, ORIGIN.alt_amsl_m);
                    closest[i] = closest[i].min((pos_ned_m.xy() - p.xy()).norm());
                }
                let reached = v.reached().len();
                if (5..10).contains(&reached) && k > 0 {
                    min_speed_mid_run = min_speed_mid_run.min(vel_ned_mps.xy().norm());
                }
            }
        }
        assert_eq!(v.reached(), (0..=10).collect::<Vec<u16>>());
        assert!(closest.iter().all(|d| *d < 1e-3), "passes through every waypoint: {closest:?}");
        assert!(min_speed_mid_run > 0.2, "does not stop at the waypoints: {min_speed_mid_run}");
        assert!((v.max_speed_mps - 0.3).abs() < 0.01, "DO_CHANGE_SPEED 0.3: {}", v.max_speed_mps);
        assert!(v.nav.status().mission_done);
    }

    #[test]
    fn given_a_jump_repeated_twice_when_flown_then_its_run_is_flown_three_times() {
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
        items.extend([wp(1, 2.0, 0.0, 2.0), wp(2, 0.0, 0.0, 2.0)]);
        items.push(NavItem { seq: 3, command: NavCommand::Jump { target: 1, repeat: 2 } });
        let mut v = Ideal::new(items);
        v.run(AutoMode::Mission, 60.0);
        assert_eq!(v.reached(), vec![0, 1, 2, 3, 1, 2, 3, 1, 2, 3]);
        assert!(v.nav.status().mission_done);
    }

    /// The horizontal speed of each step and the reached events so far, over `seconds` of a mission.
    fn fly_logging(v: &mut Ideal, seconds: f64) -> Vec<(f64, usize)> {
        let mut log = Vec::new();
        for _ in 0..(seconds / DT_S) as usize {
            if let NavSetpoint::Track { vel_ned_mps, .. } = v.step(AutoMode::Mission) {
                log.push((vel_ned_mps.xy().norm(), v.reached().len()));
            }
        }
        log
    }

    #[test]
    fn given_the_figure8_repeated_by_a_jump_when_flown_then_the_laps_are_one_leg_through_the_seam() {
        // GIVEN takeoff, speed 0.3 m/s, the figure-8 (seq 2-10) and DO_JUMP to its first waypoint twice.
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 1.5, relative: true } }];
        items.push(NavItem { seq: 1, command: NavCommand::ChangeSpeed { speed_mps: Some(0.3) } });
        items.extend(figure8(2));
        items.push(NavItem { seq: 11, command: NavCommand::Jump { target: 2, repeat: 2 } });
        let mut v = Ideal::new(items);
        let log = fly_logging(&mut v, 100.0);
        // THEN every waypoint and the jump are reached once a lap, three laps, and the jump is used up.
        let lap: Vec<u16> = (2..=11).collect();
        let mut want = vec![0, 1];
        for _ in 0..3 {
            want.extend(&lap);
        }
        assert_eq!(v.reached(), want);
        assert!(v.nav.status().mission_done);
        assert_eq!(v.nav.jumps.get(&11), Some(&0));
        // AND it never slows down between leaving the first waypoint and the last lap's approach.
        let total = want.len();
        let mid: Vec<f64> = log.iter().filter(|(_, r)| (4..total - 3).contains(r)).map(|(s, _)| *s).collect();
        let min_speed = mid.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min_speed > 0.2, "no stop at the seams: min speed {min_speed} m/s");
        // AND the three laps take three laps' time at 0.3 m/s, plus one start and one stop.
        let lap_s = SplinePath::new(&spline::FIGURE8_NE_M).length_m() / 0.3;
        let moving_s = log.iter().filter(|(_, r)| (2..total - 1).contains(r)).count() as f64 * DT_S;
        assert!(moving_s > 3.0 * lap_s && moving_s < 3.0 * lap_s + 4.0, "{moving_s} s for 3 laps of {lap_s} s");
    }

    #[test]
    fn given_a_jump_repeated_forever_when_flown_then_it_laps_on_without_stopping() {
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 1.5, relative: true } }];
        items.push(NavItem { seq: 1, command: NavCommand::ChangeSpeed { speed_mps: Some(0.3) } });
        items.extend(figure8(2));
        items.push(NavItem { seq: 11, command: NavCommand::Jump { target: 2, repeat: -1 } });
        let mut v = Ideal::new(items);
        let log = fly_logging(&mut v, 200.0);
        let laps = v.reached().iter().filter(|&&s| s == 11).count();
        assert!(laps >= 7, "{laps} laps in 200 s");
        assert!(!v.nav.status().mission_done);
        let min_speed = log.iter().filter(|(_, r)| *r >= 4).map(|(s, _)| *s).fold(f64::INFINITY, f64::min);
        assert!(min_speed > 0.2, "min speed {min_speed} m/s");
        assert_eq!(v.nav.jumps.get(&11), Some(&-1));
    }

    #[test]
    fn given_a_loop_entered_from_outside_when_repeated_then_the_first_lap_stops_at_the_jump_and_later_ones_do_not() {
        // GIVEN a triangle that does not start where the vehicle is: its first lap is an open run.
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
        items.push(NavItem { seq: 1, command: NavCommand::ChangeSpeed { speed_mps: Some(0.3) } });
        items.extend([wp(2, 2.0, 0.0, 2.0), wp(3, 2.0, 2.0, 2.0), wp(4, 0.0, 2.0, 2.0)]);
        items.push(NavItem { seq: 5, command: NavCommand::Jump { target: 2, repeat: 2 } });
        let mut v = Ideal::new(items);
        let log = fly_logging(&mut v, 120.0);
        assert_eq!(v.reached(), vec![0, 1, 2, 3, 4, 5, 2, 3, 4, 5, 2, 3, 4, 5]);
        // The first arrival at seq 4 (6 events) is at rest; laps two and three run through.
        let at_first_jump = log.iter().find(|(_, r)| *r == 6).map(|(s, _)| *s).expect("first jump");
        assert!(at_first_jump < 0.01, "first lap ends at rest: {at_first_jump} m/s");
        let later = log.iter().filter(|(_, r)| (7..12).contains(r)).map(|(s, _)| *s).fold(f64::INFINITY, f64::min);
        assert!(later > 0.1, "later laps do not stop: min {later} m/s");
    }

    #[test]
    fn given_hold_and_loiter_times_when_flown_then_the_vehicle_waits_there_that_long() {
        let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
        let mut hold = wp(1, 1.0, 0.0, 2.0);
        if let NavCommand::Waypoint { hold_s, .. } = &mut hold.command {
            *hold_s = 3.0;
        }
        items.push(hold);
        items.push(NavItem { seq: 2, command: NavCommand::Delay { time_s: 2.0 } });
        let mut v = Ideal::new(items);
        let mut reached_at = Vec::new();
        for _ in 0..(30.0 / DT_S) as usize {
            let before = v.reached().len();
            v.step(AutoMode::Mission);
            if v.reached().len() > before {
                reached_at.push(v.now_us as f64 * 1e-6);
            }
        }
        assert_eq!(v.reached(), vec![0, 1, 2]);
        let delay = reached_at[2] - reached_at[1];
        assert!((delay - 2.0).abs() < 0.01, "NAV_DELAY 2 s: {delay}");
        assert!(reached_at[1] - reached_at[0] > 3.0, "the 3 s hold comes before the waypoint counts as done");
    }

    #[test]
    fn given_return_to_launch_when_flown_then_it_climbs_returns_above_home_and_descends() {
        let mut v = Ideal::new(Vec::new());
        v.pos = Vector3::new(6.0, -8.0, -1.0);
        let mut max_alt: f64 = 0.0;
        let mut landing_seen = false;
        for _ in 0..(40.0 / DT_S) as usize {
            v.step(AutoMode::ReturnToLaunch);
            max_alt = max_alt.max(-v.pos.z);
            landing_seen |= v.nav.status().landing;
            if v.pos.z >= 0.0 {
                break;
            }
        }
        assert!((max_alt - 3.0).abs() < 0.11, "climbed to RTL_RETURN_ALT: {max_alt}");
        assert!(v.pos.xy().norm() < 0.01, "landed at home: {:?}", v.pos);
        assert!(landing_seen);
    }

    #[test]
    fn given_offboard_velocity_then_a_carrot_moves_and_setpoints_go_stale_after_the_timeout() {
        let mut v = Ideal::new(Vec::new());
        v.pos = Vector3::new(0.0, 0.0, -2.0);
        v.nav.set_offboard(
            0,
            OffboardSetpoint {
                vel_ned_mps: Some(Vector3::new(1.0, 0.0, 0.0)),
                yaw_rad: Some(0.5),
                ..OffboardSetpoint::default()
            },
        );
        let sp = v.step(AutoMode::Offboard);
        let NavSetpoint::Track { vel_ned_mps, yaw_rad, .. } = sp else { panic!("{sp:?}") };
        assert_eq!((vel_ned_mps, yaw_rad), (Vector3::new(1.0, 0.0, 0.0), 0.5));
        assert!(v.nav.status().offboard_fresh);
        v.run(AutoMode::Offboard, 0.4);
        assert!(v.pos.x > 0.39 && v.pos.x < 0.41, "carrot moved 1 m/s x 0.4 s: {}", v.pos.x);
        v.run(AutoMode::Offboard, 0.2);
        v.nav.refresh(v.now_us, Some(ORIGIN));
        assert!(!v.nav.status().offboard_fresh, "stale after 0.5 s");
    }

    #[test]
    fn given_a_new_hold_point_then_a_smooth_leg_flies_there_and_stays() {
        let mut v = Ideal::new(Vec::new());
        v.pos = Vector3::new(0.0, 0.0, -2.0);
        let target = Vector3::new(4.0, 0.0, -2.0);
        let mut max_acc: f64 = 0.0;
        for _ in 0..(15.0 / DT_S) as usize {
            let input = v.input();
            let sp = v.nav.hold(&input, target, 0.0);
            if let NavSetpoint::Track { pos_ned_m, acc_ned_mps2, .. } = sp {
                v.pos = pos_ned_m;
                max_acc = max_acc.max(acc_ned_mps2.norm());
            }
        }
        assert!((v.pos - target).norm() < 1e-3, "{:?}", v.pos);
        assert!(max_acc <= NavigatorConfig::default().accel_mps2 * 1.05, "peak acceleration {max_acc}");
    }
}
