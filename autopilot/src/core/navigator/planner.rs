//! What every part of the navigator shares ([`Planner`]): the parameters, the speed override, the held
//! yaw, the reference's last motion, the step's time and return point, progress and events; and how it
//! plans legs under PX4's limits (lines, takeoffs that creep until liftoff, landings through the ground,
//! jerk-limited stops, retargeted legs), each starting from the reference's motion.

use nalgebra::{Vector2, Vector3};

use super::leg::{Leg, LegPath, Motion3};
use super::trajectory::Limits;
use super::{NavEvent, NavInput, NavigatorConfig};

/// Which limits a leg flies with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Climb {
    /// Automatic moves: cruise horizontally, MPC_Z_VEL_MAX_UP / _DN vertically.
    Move,
    /// A takeoff: MPC_TKO_SPEED up.
    Takeoff,
    /// A takeoff still on the ground: a quarter of MPC_TKO_SPEED up, until the vehicle lifts off.
    Liftoff,
    /// A landing: MPC_LAND_SPEED down.
    Land,
}

/// A takeoff from the ground creeps up at this fraction of `MPC_TKO_SPEED` until the vehicle lifts off
/// (PX4 ramps its takeoff the same way): an airframe heavier or weaker than the controller's model then
/// lifts off a few centimetres behind its reference instead of lagging it by a metre and catching up.
const LIFTOFF_SPEED_FRAC: f64 = 0.25;
/// A reference farther than this from the vehicle (m), or faster or slower by more than
/// [`RUNAWAY_MPS`] (m/s), has run away from it: new legs start from the vehicle (see [`Planner::start`]).
const RUNAWAY_M: f64 = 0.5;
const RUNAWAY_MPS: f64 = 1.0;
/// A retargeted leg continues a reference moving across its new direction at up to this speed (m/s).
const RETARGET_CROSS_MPS: f64 = 0.5;
/// The vehicle has lifted off once this high above the ground (m).
const LIFTOFF_M: f64 = 0.05;

/// What every part of the navigator shares: the parameters, the speed override, the held yaw, the
/// reference's last motion, the step's time and return point, and the progress and events for the
/// commander and the ground station.
#[derive(Debug, Clone)]
pub(crate) struct Planner {
    pub config: NavigatorConfig,
    /// DO_CHANGE_SPEED (in a mission or not): the horizontal speed of the following legs.
    pub speed_mps: Option<f64>,
    /// The yaw the automatic modes hold (rad).
    pub yaw_rad: f64,
    /// The reference's motion at the last step (None: idle, or attitude control).
    pub last: Option<Motion3>,
    /// Time since the last step (s), for integrating velocity and yaw-rate setpoints (at most 0.05).
    pub dt_s: f64,
    /// Where a return goes when not home (the rally point chosen as it started; its down coordinate is
    /// the ground).
    pub return_ned_m: Option<Vector3<f64>>,
    /// Descending to land in an automatic mode, this step.
    pub landing: bool,
    /// The mission flew its last item (and did not land).
    pub mission_done: bool,
    pub events: Vec<NavEvent>,
}

impl Planner {
    /// The horizontal speed of moves (m/s).
    pub fn speed(&self) -> f64 {
        self.speed_mps.unwrap_or(self.config.cruise_speed_mps)
    }

    /// Where a new leg starts: the reference's motion, so the flight goes on smoothly; the vehicle at rest
    /// when there is none; and the vehicle's own motion when the reference has run away from it (farther
    /// than [`RUNAWAY_M`] or faster by [`RUNAWAY_MPS`]: an offboard velocity the airframe cannot reach),
    /// so that a stop stops the vehicle where it can, not a reference metres ahead of it.
    pub fn start(&self, input: &NavInput) -> Motion3 {
        let Some(last) = self.last else { return Motion3::rest(input.pos_ned_m) };
        let gap_m = (last.pos_ned_m - input.pos_ned_m).norm();
        let gap_mps = (last.vel_ned_mps - input.vel_ned_mps).norm();
        if gap_m > RUNAWAY_M || gap_mps > RUNAWAY_MPS {
            return Motion3 { vel_ned_mps: input.vel_ned_mps, ..Motion3::rest(input.pos_ned_m) };
        }
        last
    }

    /// The progress limits of `path` for `climb`.
    pub fn limits(&self, path: &LegPath, climb: Climb) -> Limits {
        let c = &self.config;
        let (v_up, v_down, a_up, a_down) = match climb {
            Climb::Move => (c.climb_speed_mps, c.descent_speed_mps, c.acc_up_mps2, c.acc_down_mps2),
            Climb::Takeoff => (c.takeoff_speed_mps, c.descent_speed_mps, c.acc_up_mps2, c.acc_down_mps2),
            Climb::Liftoff => {
                (c.takeoff_speed_mps * LIFTOFF_SPEED_FRAC, c.descent_speed_mps, c.acc_up_mps2, c.acc_down_mps2)
            }
            Climb::Land => (c.climb_speed_mps, c.land_speed_mps, c.acc_up_mps2, c.acc_down_mps2),
        };
        let (horizontal, down) = match path {
            LegPath::Line { from, to } => {
                let d = to - from;
                let len = d.norm();
                if len > 0.0 { (d.xy().norm() / len, d.z / len) } else { (1.0, 0.0) }
            }
            // Splines fly level runs (their altitude changes are gentle): the horizontal limits.
            LegPath::Spline { .. } => (1.0, 0.0),
        };
        let cap = |h_limit: f64, up: f64, dn: f64| -> f64 {
            let mut limit = f64::INFINITY;
            if horizontal > 1e-9 {
                limit = limit.min(h_limit / horizontal);
            }
            if down < -1e-9 {
                limit = limit.min(up / -down);
            } else if down > 1e-9 {
                limit = limit.min(dn / down);
            }
            if limit.is_finite() { limit } else { h_limit }
        };
        Limits {
            vel_mps: cap(self.speed(), v_up, v_down),
            acc_mps2: cap(c.acc_hor_mps2, a_up, a_down),
            jerk_mps3: c.jerk_mps3,
        }
    }

    /// A straight leg from the reference's motion to `to`, reporting `seq` at its end.
    pub fn line(&self, input: &NavInput, to: Vector3<f64>, climb: Climb, seq: Option<u16>) -> Leg {
        let start = self.start(input);
        let knots = seq.map(|s| vec![((to - start.pos_ned_m).norm(), s)]).unwrap_or_default();
        Leg::plan(&start, input.now_us, knots, |p| self.limits(p, climb), |from| LegPath::Line { from, to })
    }

    /// A takeoff to `to`: from the ground it creeps up at the liftoff speed (`Climb::Liftoff`) until
    /// [`Self::liftoff`] sees the vehicle leave the ground; in the air it climbs at once.
    pub fn takeoff(&self, input: &NavInput, to: Vector3<f64>) -> (Leg, Climb) {
        let climb = if Self::lifted(input) { Climb::Takeoff } else { Climb::Liftoff };
        (self.line(input, to, climb, None), climb)
    }

    /// Whether the vehicle is off the ground.
    fn lifted(input: &NavInput) -> bool {
        input.ground_d_m() - input.pos_ned_m.z >= LIFTOFF_M
    }

    /// Speeds a creeping takeoff leg up to the takeoff speed once the vehicle has lifted off (from the
    /// reference's motion: continuous).
    pub fn liftoff(&self, input: &NavInput, leg: &mut Leg, climb: &mut Climb) {
        if *climb == Climb::Liftoff && Self::lifted(input) {
            *leg = self.line(input, leg.end(), Climb::Takeoff, None);
            *climb = Climb::Takeoff;
        }
    }

    /// A straight leg to a target that moves with every update (an offboard position stream): continues
    /// the reference's motion towards it when it moves across the new direction at up to 0.5 m/s.
    pub fn retarget(&self, input: &NavInput, to: Vector3<f64>) -> Leg {
        let start = self.start(input);
        Leg::plan_continuing(
            &start,
            input.now_us,
            Vec::new(),
            |p| self.limits(p, Climb::Move),
            |from| LegPath::Line { from, to },
            RETARGET_CROSS_MPS,
        )
    }

    /// A landing: straight down at `ne` (NED m) at the land speed, through the ground without braking,
    /// to `land_below_ground_m` below it.
    pub fn land(&self, input: &NavInput, ne: Vector2<f64>) -> Leg {
        let floor = input.ground_d_m() + self.config.land_below_ground_m;
        let start = self.start(input);
        // Planned to run on past the floor, so it still descends at the land speed there.
        let beyond = floor.max(start.pos_ned_m.z) + 10.0;
        Leg::plan(
            &start,
            input.now_us,
            Vec::new(),
            |p| self.limits(p, Climb::Land),
            |from| LegPath::Line { from, to: Vector3::new(ne.x, ne.y, beyond.max(from.z)) },
        )
        .with_floor(floor)
    }

    /// A jerk-limited stop from the reference's motion, held where it ends.
    pub fn stop(&self, input: &NavInput) -> Leg {
        let start = self.start(input);
        Leg::plan(
            &start,
            input.now_us,
            Vec::new(),
            |p| self.limits(p, Climb::Move),
            |from| LegPath::Line { from, to: from },
        )
    }

    /// The reference of `leg` now, remembered as the last motion (the vehicle's position paces it).
    pub fn fly(&mut self, leg: &mut Leg, input: &NavInput) -> Motion3 {
        let m = leg.motion(input.now_us, input.pos_ned_m);
        self.last = Some(m);
        m
    }
}

/// A leg under way with the limits it flies by: the one implementation of takeoffs and landings, shared
/// by Takeoff and Land, a mission's NAV_TAKEOFF, its climb from the ground and its NAV_LAND, and the end of
/// a return. A takeoff creeps up at the liftoff speed until the vehicle leaves the ground, then climbs at
/// the takeoff speed ([`Planner::takeoff`], [`Planner::liftoff`]); a landing descends at the land speed
/// through the ground ([`Planner::land`]) and reports itself landing while it flies.
#[derive(Debug, Clone)]
pub(crate) struct Flight {
    pub leg: Leg,
    pub climb: Climb,
}

impl Flight {
    /// A takeoff to `to` (NED m).
    pub fn takeoff(p: &Planner, input: &NavInput, to: Vector3<f64>) -> Self {
        let (leg, climb) = p.takeoff(input, to);
        Self { leg, climb }
    }

    /// A landing at `ne` (NED m).
    pub fn land(p: &Planner, input: &NavInput, ne: Vector2<f64>) -> Self {
        Self { leg: p.land(input, ne), climb: Climb::Land }
    }

    /// Any other leg, flown with `climb`'s limits.
    pub fn of(leg: Leg, climb: Climb) -> Self {
        Self { leg, climb }
    }

    /// This step's motion: a takeoff speeds up once lifted off; a landing says it is landing.
    pub fn fly(&mut self, p: &mut Planner, input: &NavInput) -> Motion3 {
        p.liftoff(input, &mut self.leg, &mut self.climb);
        if self.climb == Climb::Land {
            p.landing = true;
        }
        p.fly(&mut self.leg, input)
    }

    /// A takeoff (or climb) is complete: the leg has arrived, the vehicle is within the takeoff acceptance
    /// of its altitude, and it is off the ground.
    pub fn reached_altitude(&self, input: &NavInput) -> bool {
        self.leg.at_end() && (input.pos_ned_m.z - self.leg.end().z).abs() <= input.takeoff_acceptance_m && !input.landed
    }
}
