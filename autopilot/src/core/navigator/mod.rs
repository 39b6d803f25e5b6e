//! The navigator: the one place where the vehicle's reference comes from. In, once per control step:
//! the commander's [`Intent`] (idle, take off to an altitude, hold, reposition, land, or an automatic
//! mode), vehicle time `now_us` (µs), the estimate (NED m, m/s, rad, with its geodetic origin), home and
//! whether the vehicle is landed ([`NavInput`]), the rally points; and, when they arrive, the mission (as
//! [`NavItem`]s), offboard setpoints and speed changes. Out: one [`Reference`] (position, velocity and
//! acceleration feed-forward, yaw; or an attitude) or `None` for motors idle; [`Progress`] events for the
//! commander (mission done, an automatic landing began or ended), and [`NavEvent`]s for the ground
//! station (MISSION_CURRENT, MISSION_ITEM_REACHED, STATUSTEXT). It owns every point flown: it latches
//! the takeoff and landing points when their intent starts, holds the yaw, chooses the rally point a
//! return goes to and keeps its own clock; it never reads the commander's state.
//!
//! Every move is a [`Leg`] whose progress is a time-optimal jerk-limited profile ([`trajectory`]) under
//! PX4's limits: `MPC_XY_CRUISE` (or a DO_CHANGE_SPEED) and `MPC_ACC_HOR` horizontally,
//! `MPC_Z_VEL_MAX_UP` / `MPC_ACC_UP_MAX` up and `MPC_Z_VEL_MAX_DN` / `MPC_ACC_DOWN_MAX` down,
//! `MPC_TKO_SPEED` for takeoffs, `MPC_LAND_SPEED` for landings, `MPC_JERK_AUTO` for all (a slanted line
//! gets the tightest of its horizontal and vertical limits). A new leg starts from the reference's motion,
//! so across every mode change the reference is continuous in position, and in velocity to within the
//! 0.02 m/s a leg may drop across its path (a faster start brakes first), unless the reference has run
//! away from the vehicle (`Planner::start`). Its acceleration keeps only the part along the new path: the
//! part across it (at most the acceleration limit) is dropped in one step, a known jump a random-intent
//! property test measures (navigator tests).
//!
//! - **Takeoff** ([`Intent::Takeoff`]): a vertical leg from the ground to the altitude, here. The hold
//!   that follows at the same point ([`HoldAt::TakeoffPoint`]) continues the same leg.
//! - **Hold** ([`Intent::Hold`]): a leg to the point (DO_REPOSITION), or a jerk-limited stop where the
//!   reference is (a pause, or Hold entered from another mode).
//! - **Land** ([`Intent::Land`], NAV_LAND, the end of a return): a vertical leg at the land speed to
//!   `land_below_ground_m` below the ground; the vehicle touches down on the way and the commander's land
//!   detector ends it.
//! - **Missions** (`executor.rs`), **return to launch** (`rtl.rs`), **offboard** (`offboard.rs`).

use std::sync::Arc;

use nalgebra::{Vector2, Vector3};

use crate::core::control::Reference;
use crate::core::estimator::GeoOrigin;
pub use crate::core::intent::{AutoMode, HoldAt, Intent, ManualMode, Progress};
use crate::core::manual::Sticks;
pub use crate::core::mission::{NavCommand, NavItem, NavTarget, nav_items};
use crate::core::plan::geofence::Rally;

mod config;
mod executor;
pub mod leg;
pub mod manual;
mod offboard;
mod planner;
mod rtl;
pub mod spline;
pub mod trajectory;

#[cfg(test)]
mod tests;

pub use config::{ConfigError, NavigatorConfig};
use executor::Executor;
use leg::{MIN_LEG_M, Motion3};
pub use manual::ManualFlightConfig;
use manual::{ManualFlight, VerticalLimits};
pub use offboard::OffboardSetpoint;
pub(crate) use planner::{Climb, Flight, Planner};

pub use crate::core::plan::MAX_SETPOINT_FROM_HOME_M;

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

/// One step's inputs.
#[derive(Debug, Clone, Copy)]
pub struct NavInput {
    pub now_us: u64,
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    pub yaw_rad: f64,
    pub origin: Option<GeoOrigin>,
    /// Home (NED m); its down coordinate is the ground.
    pub home_ned_m: Option<Vector3<f64>>,
    /// Home altitude (m AMSL), for AMSL targets.
    pub home_alt_amsl_m: Option<f64>,
    pub landed: bool,
    /// The estimate's position is valid. Without it a reference that steers by position is flown level
    /// instead (its height and yaw kept), as PX4 flies Descend: see [`without_position`].
    pub position_valid: bool,
    /// Default takeoff altitude above home (m; MIS_TAKEOFF_ALT).
    pub takeoff_alt_m: f64,
    /// Takeoff acceptance (m).
    pub takeoff_acceptance_m: f64,
}

/// A reference flown without a valid position: level (roll and pitch 0, its yaw), its vertical part (the
/// height, and the climb or descent with its feed-forward) kept: the N and E loops would chase a position
/// the estimate no longer has (a GPS loss), while the height still comes from the barometer. An attitude
/// reference (the pilot's Stabilized or Altitude, offboard attitude) already needs no position and is
/// returned as it is. The commander's position failsafe lands after COM_POS_FS_DELAY; until then the
/// vehicle holds its height, level.
#[must_use]
pub fn without_position(reference: Reference) -> Reference {
    if reference.attitude_rad.is_some() {
        return reference;
    }
    let vertical = |v: Vector3<f64>| Vector3::new(0.0, 0.0, v.z);
    Reference {
        vel_ned_mps: vertical(reference.vel_ned_mps),
        acc_ned_mps2: vertical(reference.acc_ned_mps2),
        jerk_ned_mps3: vertical(reference.jerk_ned_mps3),
        attitude_rad: Some(Vector3::new(0.0, 0.0, reference.yaw_rad)),
        ..reference
    }
}

impl NavInput {
    /// The ground's down coordinate (home's; 0 without one).
    #[must_use]
    pub fn ground_d_m(&self) -> f64 {
        self.home_ned_m.map_or(0.0, |h| h.z)
    }

    /// The frame mission targets are read in.
    #[must_use]
    pub fn frame(&self) -> crate::core::plan::Frame {
        crate::core::plan::Frame {
            origin: self.origin,
            home_alt_amsl_m: self.home_alt_amsl_m,
            ground_d_m: self.ground_d_m(),
        }
    }
}

/// Holding still at `at` (m).
fn still(at: Vector3<f64>) -> Motion3 {
    Motion3::rest(at)
}

/// What a direct (commander-driven) leg aims at.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Aim {
    Point(Vector3<f64>),
    /// Wherever the stop ends.
    Here,
}

#[derive(Debug, Clone)]
struct Direct {
    aim: Aim,
    yaw_rad: f64,
    flight: Flight,
}

/// The navigator. See the module docs.
#[derive(Debug, Clone)]
pub struct Navigator {
    planner: Planner,
    mission: Executor,
    rtl: Option<rtl::Rtl>,
    offboard: offboard::Offboard,
    direct: Option<Direct>,
    last_auto: Option<AutoMode>,
    /// The commander's intent of the last step: the points below are latched when it changes.
    intent: Intent,
    /// Where a takeoff climbs (NED m), latched as it starts.
    takeoff_ned_m: Vector3<f64>,
    /// Where a landing descends (NE m), latched as it starts.
    land_ne_m: Vector2<f64>,
    /// The yaw the direct legs hold (rad): the vehicle's as it leaves the ground idle, or a reposition's.
    yaw_sp_rad: f64,
    /// When the last step was (µs of vehicle time).
    last_update_us: Option<u64>,
    /// Progress not yet taken, and the levels last reported.
    progress: Vec<Progress>,
    reported_landing: bool,
    reported_done: bool,
    /// The point an airborne start holds, until the intent changes.
    start_point: Option<Vector3<f64>>,
    /// The pilot's sticks of this step (None: no fresh manual control), and the manual flight under way.
    sticks: Option<Sticks>,
    manual: Option<ManualFlight>,
}

/// The reference of a motion with a yaw.
fn track(m: &Motion3, yaw_rad: f64) -> Reference {
    Reference {
        vel_ned_mps: m.vel_ned_mps,
        acc_ned_mps2: m.acc_ned_mps2,
        jerk_ned_mps3: m.jerk_ned_mps3,
        ..Reference::position(m.pos_ned_m, yaw_rad)
    }
}

impl Navigator {
    #[must_use]
    pub fn new(config: NavigatorConfig) -> Self {
        Self {
            planner: Planner {
                config,
                speed_mps: None,
                yaw_rad: 0.0,
                last: None,
                dt_s: 0.0,
                return_ned_m: None,
                landing: false,
                mission_done: false,
                events: Vec::new(),
            },
            mission: Executor::default(),
            rtl: None,
            offboard: offboard::Offboard::default(),
            direct: None,
            last_auto: None,
            intent: Intent::Idle,
            takeoff_ned_m: Vector3::zeros(),
            land_ne_m: Vector2::zeros(),
            yaw_sp_rad: 0.0,
            last_update_us: None,
            progress: Vec::new(),
            reported_landing: false,
            reported_done: false,
            start_point: None,
            sticks: None,
            manual: None,
        }
    }

    /// New parameters, from the next leg (legs under way keep their limits).
    pub fn set_config(&mut self, config: NavigatorConfig) {
        self.planner.config = config;
    }

    #[must_use]
    pub fn config(&self) -> &NavigatorConfig {
        &self.planner.config
    }

    /// A new mission (replacing the old one), to start at its first item.
    pub fn set_mission(&mut self, items: Arc<[NavItem]>) {
        self.mission.set_items(items);
        self.planner.mission_done = false;
        self.report();
    }

    /// Continue the mission at the item of sequence number `seq` (MISSION_SET_CURRENT, MISSION_START).
    pub fn set_current(&mut self, seq: u16) {
        self.mission.set_current(seq);
        self.planner.mission_done = false;
        self.report();
    }

    /// The sequence number of the item the mission flies towards (or its last, once done).
    #[must_use]
    pub fn current_seq(&self) -> u16 {
        self.mission.current_seq()
    }

    #[must_use]
    pub fn mission_len(&self) -> usize {
        self.mission.len()
    }

    /// The latest offboard setpoint.
    pub fn set_offboard(&mut self, setpoint: OffboardSetpoint) {
        self.offboard.set(setpoint);
    }

    /// The pilot's sticks for the next step (None: no fresh manual control; a manual mode then flies them
    /// centred).
    pub fn set_sticks(&mut self, sticks: Option<Sticks>) {
        self.sticks = sticks;
    }

    /// DO_CHANGE_SPEED outside a mission: the speed of the following legs.
    pub fn set_speed(&mut self, speed_mps: Option<f64>) {
        self.planner.speed_mps = speed_mps.filter(|s| s.is_finite() && *s > 0.0);
    }

    /// The progress since the last call (for the commander), in order.
    pub fn take_progress(&mut self) -> Vec<Progress> {
        std::mem::take(&mut self.progress)
    }

    /// The events since the last call (for the ground station).
    pub fn take_events(&mut self) -> Vec<NavEvent> {
        std::mem::take(&mut self.planner.events)
    }

    /// Queues the progress whose level changed since it was last reported.
    fn report(&mut self) {
        if self.planner.mission_done != self.reported_done {
            self.reported_done = self.planner.mission_done;
            self.progress.push(Progress::MissionDone(self.reported_done));
        }
        if self.planner.landing != self.reported_landing {
            self.reported_landing = self.planner.landing;
            self.progress.push(Progress::Landing(self.reported_landing));
        }
    }

    /// Starts holding exactly at `pos_ned_m` with `yaw_rad` (an airborne start: not from a first, noisy
    /// estimate), as the commander's airborne start intends ([`HoldAt::Stop`] of a reference at rest
    /// there).
    pub fn start_airborne(&mut self, pos_ned_m: Vector3<f64>, yaw_rad: f64) {
        self.planner.last = Some(Motion3::rest(pos_ned_m));
        self.intent = Intent::Hold { at: HoldAt::Stop, yaw_rad: None };
        self.yaw_sp_rad = yaw_rad;
        self.start_point = Some(pos_ned_m);
    }

    /// The reference for this step (None: motors idle), for the commander's `intent`, with the rally
    /// points a return may choose. See the module docs.
    pub fn update(&mut self, intent: Intent, input: &NavInput, rally: &Rally) -> Option<Reference> {
        self.planner.dt_s = self.last_update_us.map_or(0.0, |t| input.now_us.saturating_sub(t) as f64 * 1e-6).min(0.05);
        self.last_update_us = Some(input.now_us);
        if !matches!(intent, Intent::Manual(_))
            && let Some(flight) = self.manual.take()
        {
            // Leaving a manual mode: the next legs keep the yaw the pilot left.
            self.yaw_sp_rad = flight.yaw_sp_rad();
        }
        if intent != self.intent {
            self.latch(intent, input);
            self.intent = intent;
        }
        // Where a return goes, chosen as it starts and kept until it ends: the nearest rally point when one
        // is closer than home.
        if intent != Intent::Auto(AutoMode::ReturnToLaunch) {
            self.planner.return_ned_m = None;
        } else if self.planner.return_ned_m.is_none()
            && let Some(home) = input.home_ned_m
        {
            self.planner.return_ned_m = Some(rally.return_point(input.origin.as_ref(), home, &input.pos_ned_m));
        }
        self.planner.landing = false;
        let yaw_rad = self.yaw_sp_rad;
        let reference = match intent {
            Intent::Idle => {
                self.leave();
                self.planner.last = None;
                None
            }
            Intent::Takeoff { .. } => Some(self.direct(input, Aim::Point(self.takeoff_ned_m), Climb::Takeoff, yaw_rad)),
            Intent::Hold { at, .. } => {
                let point = match at {
                    // An airborne start holds exactly its point.
                    HoldAt::Stop => self.start_point,
                    HoldAt::TakeoffPoint => Some(self.takeoff_ned_m),
                    HoldAt::Point(p) => Some(p).filter(|p| p.iter().all(|x| x.is_finite())),
                };
                match point {
                    Some(p) => {
                        // Holding the point a takeoff climbs to continues the takeoff's leg.
                        let climb = self
                            .direct
                            .as_ref()
                            .filter(|d| d.aim == Aim::Point(p))
                            .map_or(Climb::Move, |d| d.flight.climb);
                        Some(self.direct(input, Aim::Point(p), climb, yaw_rad))
                    }
                    None => Some(self.direct(input, Aim::Here, Climb::Move, yaw_rad)),
                }
            }
            Intent::Land => {
                self.planner.landing = true;
                let floor = input.ground_d_m() + self.planner.config.land_below_ground_m;
                let to = Vector3::new(self.land_ne_m.x, self.land_ne_m.y, floor);
                Some(self.direct(input, Aim::Point(to), Climb::Land, yaw_rad))
            }
            Intent::Auto(mode) => Some(self.auto(mode, input)),
            Intent::Manual(mode) => self.manual(mode, input),
        };
        self.report();
        if input.position_valid { reference } else { reference.map(without_position) }
    }

    /// Latches the points a new intent flies to (see [`Intent`]).
    fn latch(&mut self, intent: Intent, input: &NavInput) {
        self.start_point = None;
        if self.intent == Intent::Idle && intent != Intent::Idle && input.yaw_rad.is_finite() {
            self.yaw_sp_rad = input.yaw_rad;
        }
        match intent {
            Intent::Takeoff { alt_m } => {
                let ne = if matches!(self.intent, Intent::Takeoff { .. }) {
                    self.takeoff_ned_m.xy()
                } else {
                    input.pos_ned_m.xy()
                };
                self.takeoff_ned_m = Vector3::new(ne.x, ne.y, input.ground_d_m() - alt_m);
            }
            Intent::Hold { yaw_rad: Some(y), .. } if y.is_finite() => self.yaw_sp_rad = y,
            Intent::Land => self.land_ne_m = input.pos_ned_m.xy(),
            _ => {}
        }
    }

    /// Leaves the automatic modes and the direct legs (the reference's motion stays for the next leg).
    fn leave(&mut self) {
        self.last_auto = None;
        self.rtl = None;
        self.direct = None;
        self.offboard.leave();
    }

    fn direct(&mut self, input: &NavInput, aim: Aim, climb: Climb, yaw_rad: f64) -> Reference {
        if self.last_auto.is_some() {
            self.leave();
        }
        let keep = self.direct.as_ref().is_some_and(|d| {
            d.yaw_rad == yaw_rad
                && match (d.aim, aim) {
                    (Aim::Point(a), Aim::Point(b)) => (a - b).norm() <= MIN_LEG_M,
                    (Aim::Here, Aim::Here) => true,
                    _ => false,
                }
        });
        if !keep {
            self.direct = None;
            self.planner.yaw_rad = yaw_rad;
        }
        let planner = &mut self.planner;
        let d = self.direct.get_or_insert_with(|| {
            let flight = match aim {
                Aim::Point(p) if climb == Climb::Land => Flight::land(planner, input, p.xy()),
                Aim::Point(p) if climb == Climb::Takeoff => Flight::takeoff(planner, input, p),
                Aim::Point(p) => Flight::of(planner.line(input, p, climb, None), climb),
                Aim::Here => Flight::of(planner.stop(input), climb),
            };
            Direct { aim, yaw_rad, flight }
        });
        let m = d.flight.fly(planner, input);
        track(&m, yaw_rad)
    }

    /// A manual mode: the pilot's sticks through the mode's setpoint generator (`manual.rs`), started from
    /// the reference's motion.
    fn manual(&mut self, mode: ManualMode, input: &NavInput) -> Option<Reference> {
        if self.last_auto.is_some() || self.direct.is_some() {
            self.leave();
        }
        let start = self.planner.start(input);
        let yaw_rad = self.yaw_sp_rad;
        let flight = self.manual.get_or_insert_with(|| ManualFlight::new(start, yaw_rad));
        let c = &self.planner.config;
        let vertical = VerticalLimits {
            climb_mps: c.climb_speed_mps,
            descent_mps: c.descent_speed_mps,
            acc_up_mps2: c.acc_up_mps2,
            acc_down_mps2: c.acc_down_mps2,
            floor_d_m: input.ground_d_m() + c.land_below_ground_m,
        };
        let reference = flight.step(mode, self.sticks, input, self.planner.dt_s, &c.manual, &vertical);
        self.yaw_sp_rad = flight.yaw_sp_rad();
        self.planner.last = reference.map(|_| flight.motion());
        reference
    }

    fn auto(&mut self, mode: AutoMode, input: &NavInput) -> Reference {
        self.direct = None;
        if self.last_auto != Some(mode) {
            self.rtl = None;
            self.offboard.leave();
            if mode == AutoMode::Mission {
                // Resume the current item from where the reference is.
                self.mission.resume();
            }
            self.planner.yaw_rad = input.yaw_rad;
            self.last_auto = Some(mode);
        }
        match mode {
            AutoMode::Mission => {
                let m = self.mission.step(&mut self.planner, input);
                track(&m, self.planner.yaw_rad)
            }
            AutoMode::ReturnToLaunch => {
                let m = rtl::step(&mut self.rtl, &mut self.planner, input);
                track(&m, self.planner.yaw_rad)
            }
            AutoMode::Offboard => self.offboard.step(&mut self.planner, input),
        }
    }
}
