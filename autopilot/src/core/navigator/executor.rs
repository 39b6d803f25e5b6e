//! The mission executor: flies the mission's [`NavItem`]s in order from `current`, each as legs planned
//! by the [`Planner`]. In, per step: the planner (limits, the reference's motion, yaw, events) and the
//! [`NavInput`]. Out: the reference's motion, MISSION_CURRENT / MISSION_ITEM_REACHED / STATUSTEXT events,
//! and the status bits (landing, mission done).
//!
//! - NAV_WAYPOINT: a straight leg to the point, at rest there, reached once the reference has arrived
//!   and the vehicle is within the acceptance radius; then its hold time.
//! - NAV_SPLINE_WAYPOINT: consecutive spline waypoints without hold time are one run, a C2 spline through
//!   them flown without stopping (each reported reached as the reference passes it); a run ends at rest
//!   at a waypoint with a hold time, before any other item, and at a DO_JUMP, unless the jump repeats a
//!   run that closes on itself (in N, E and D) from its first waypoint: then the laps are flown as one leg
//!   through the seam (the figure-8 for N laps). A closed run entered from elsewhere is preceded by a
//!   straight leg to its first waypoint, so the loop itself is periodic.
//! - NAV_TAKEOFF climbs at the takeoff speed; NAV_LAND flies to its point (or lands here) and descends
//!   until landed; NAV_RETURN_TO_LAUNCH runs the return ([`super::rtl`]); NAV_LOITER_TIME and NAV_DELAY
//!   hold for their time, NAV_LOITER_UNLIM forever; DO_CHANGE_SPEED sets the speed of the following legs;
//!   DO_JUMP repeats from its target (param2 times, -1 forever). A mission started on the ground first
//!   climbs to its first item's altitude (at least `takeoff_alt_m`). After the last item the mission is
//!   done (the commander holds), unless it landed.
//!
//! Yaw is held at the mission's start unless a waypoint gives one (param4, degrees). Hold and loiter times
//! saturate: a time of 1e30 s waits for as long as the vehicle flies.

use std::collections::BTreeMap;
use std::sync::Arc;

use nalgebra::Vector3;

use super::leg::{Leg, LegPath, MIN_LEG_M, Motion3};
use super::planner::Flight;
use super::spline::SplinePath;
use super::{Climb, NavCommand, NavEvent, NavInput, NavItem, NavTarget, Planner, rtl, still};
use crate::core::plan;
use crate::core::seconds_to_us;

/// Runs hold at most this many waypoints (the spline is solved once per run).
const MAX_RUN: usize = 64;

/// `now_us` plus `t_s` seconds, saturating (a hold of 1e30 s lasts as long as the clock).
pub(crate) fn after_us(now_us: u64, t_s: f64) -> u64 {
    now_us.saturating_add(seconds_to_us(t_s))
}

/// Where a mission is within its current item.
#[derive(Debug, Clone, Default)]
enum Phase {
    /// Nothing started yet: start the item at `current`.
    #[default]
    Start,
    /// Climbing (NAV_TAKEOFF, or the implicit climb of a mission started on the ground); then `item`
    /// is reached (None: the item at `current` starts).
    Climb { flight: Box<Flight>, item: Option<u16> },
    /// Flying a leg; on arrival at its end the item `end_item` starts holding `hold_s` (then the next item).
    Fly { leg: Box<Leg>, end_item: u16, hold_s: f64, accept_m: f64, then: After },
    /// Holding a point until `until_us` (None: forever).
    Wait { at: Vector3<f64>, until_us: Option<u64>, item: u16 },
    /// Descending to land (NAV_LAND).
    Descend { flight: Box<Flight>, item: Option<u16> },
    /// Returning to launch (NAV_RETURN_TO_LAUNCH): reached once landed at home.
    Return { rtl: Option<Box<rtl::Rtl>>, item: u16 },
    /// The mission flew its last item.
    Done,
    /// The mission ended on the ground: it stays landing (the commander disarms after touchdown).
    Landed { flight: Box<Flight> },
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

/// The mission executor. See the module docs.
#[derive(Debug, Clone, Default)]
pub(crate) struct Executor {
    items: Arc<[NavItem]>,
    current: usize,
    phase: Phase,
    /// Remaining repeats of each DO_JUMP (by seq), set on first use.
    jumps: BTreeMap<u16, i32>,
    last_current: Option<u16>,
    /// The stop flown while the mission has nothing to fly (done).
    stop: Option<Box<Leg>>,
}

impl Executor {
    pub fn set_items(&mut self, items: Arc<[NavItem]>) {
        self.items = items;
        self.set_current(0);
    }

    pub fn set_current(&mut self, seq: u16) {
        self.current = self.items.iter().position(|i| i.seq == seq).unwrap_or(0);
        self.phase = Phase::Start;
        self.jumps.clear();
        self.last_current = None;
        self.stop = None;
    }

    pub fn len(&self) -> usize {
        self.items.len()
    }

    pub fn current_seq(&self) -> u16 {
        self.items.get(self.current.min(self.items.len().saturating_sub(1))).map_or(0, |i| i.seq)
    }

    /// Entering mission mode: the current item starts again from where the reference is (unless the
    /// mission is over).
    pub fn resume(&mut self) {
        if !matches!(self.phase, Phase::Done | Phase::Landed { .. }) {
            self.phase = Phase::Start;
        }
        self.stop = None;
    }

    #[cfg(test)]
    pub fn jumps_left_of(&self, seq: u16) -> Option<i32> {
        self.jumps.get(&seq).copied()
    }

    fn emit_current(&mut self, p: &mut Planner) {
        let seq = self.current_seq();
        if self.last_current != Some(seq) {
            self.last_current = Some(seq);
            p.events.push(NavEvent::Current(seq));
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
        self.stop = None;
    }

    fn finish(&mut self, p: &mut Planner, input: &NavInput) -> Motion3 {
        self.phase = Phase::Done;
        p.mission_done = true;
        self.current = self.items.len().saturating_sub(1);
        p.events.push(NavEvent::Text("Mission finished".into()));
        self.hold_here(p, input)
    }

    /// Holding the reference where it is (at rest) or stopping it there.
    fn hold_here(&mut self, p: &mut Planner, input: &NavInput) -> Motion3 {
        let leg = self.stop.get_or_insert_with(|| Box::new(p.stop(input)));
        p.fly(leg, input)
    }

    /// One step of the mission (see the module docs).
    pub fn step(&mut self, p: &mut Planner, input: &NavInput) -> Motion3 {
        // Items that start at once (DO items, a finished jump) are handled in one step, boundedly.
        for _ in 0..=self.items.len() + 1 {
            if matches!(self.phase, Phase::Start) {
                if self.current >= self.items.len() {
                    return self.finish(p, input);
                }
                self.emit_current(p);
                if !self.start_item(p, input) {
                    continue;
                }
            }
            return self.run_phase(p, input);
        }
        self.finish(p, input)
    }

    /// Starts the item at `current`; `false` when it completed at once (the loop goes on).
    fn start_item(&mut self, p: &mut Planner, input: &NavInput) -> bool {
        let item = self.items[self.current];
        let here = p.start(input).pos_ned_m;
        let ground = input.ground_d_m();
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
                let to = Vector3::new(here.x, here.y, ground - alt);
                self.phase = Phase::Climb { flight: Box::new(Flight::takeoff(p, input, to)), item: Some(item.seq) };
            }
            NavCommand::ChangeSpeed { speed_mps } => {
                p.speed_mps = speed_mps.filter(|s| s.is_finite() && *s > 0.0);
                p.events.push(NavEvent::Reached(item.seq));
                self.advance_item();
                return false;
            }
            NavCommand::Jump { target, repeat } => {
                let target_index = self.items.iter().position(|i| i.seq == target);
                p.events.push(NavEvent::Reached(item.seq));
                match target_index {
                    Some(t) if self.take_jump(item.seq, repeat) => {
                        self.current = t;
                        self.phase = Phase::Start;
                    }
                    _ => self.advance_item(),
                }
                return false;
            }
            NavCommand::Delay { time_s } => {
                let until = after_us(input.now_us, time_s);
                self.phase = Phase::Wait { at: here, until_us: Some(until), item: item.seq };
            }
            NavCommand::ReturnToLaunch => {
                self.phase = Phase::Return { rtl: None, item: item.seq };
            }
            NavCommand::Waypoint { .. }
            | NavCommand::LoiterTime { .. }
            | NavCommand::LoiterUnlimited { .. }
            | NavCommand::Land { .. } => {
                let Some(to) = self.first_point(input, here) else {
                    p.events.push(NavEvent::Text(format!("Mission item {} has no position: skipped", item.seq)));
                    self.advance_item();
                    return false;
                };
                if let Some(climb_to) = climb_first(to) {
                    self.phase = Phase::Climb { flight: Box::new(Flight::takeoff(p, input, climb_to)), item: None };
                    return true;
                }
                let Some(phase) = self.plan_flight(p, input, here) else {
                    p.events.push(NavEvent::Text(format!("Mission item {} has no position: skipped", item.seq)));
                    self.advance_item();
                    return false;
                };
                self.phase = phase;
            }
        }
        true
    }

    /// Where the flying item at `current` goes first (its altitude decides a climb from the ground).
    fn first_point(&self, input: &NavInput, here: Vector3<f64>) -> Option<Vector3<f64>> {
        match self.items[self.current].command {
            NavCommand::Waypoint { target, .. }
            | NavCommand::LoiterTime { target, .. }
            | NavCommand::LoiterUnlimited { target, .. } => resolve(input, &target, here),
            NavCommand::Land { target, .. } => resolve(input, &target, here).map(|to| Vector3::new(to.x, to.y, here.z)),
            _ => None,
        }
    }

    /// The leg (or run of legs) of the flying item at `current`, starting from the reference's motion at
    /// `from`.
    fn plan_flight(&self, p: &mut Planner, input: &NavInput, from: Vector3<f64>) -> Option<Phase> {
        let item = self.items[self.current];
        let accept_default = p.config.acceptance_radius_m;
        match item.command {
            NavCommand::Waypoint { target, hold_s, accept_m, yaw_rad, spline: false } => {
                if let Some(y) = yaw_rad {
                    p.yaw_rad = y;
                }
                let to = resolve(input, &target, from)?;
                let leg = p.line(input, to, Climb::Move, Some(item.seq));
                Some(Phase::Fly {
                    leg: Box::new(leg),
                    end_item: item.seq,
                    hold_s: hold_s.max(0.0),
                    accept_m: accept_m.filter(|a| *a > 0.0).unwrap_or(accept_default),
                    then: After::Next,
                })
            }
            NavCommand::Waypoint { spline: true, .. } => self.plan_run(p, input, from),
            NavCommand::LoiterTime { target, time_s, yaw_rad } => {
                self.loiter_leg(p, input, from, item.seq, target, yaw_rad, Some(time_s.max(0.0)))
            }
            NavCommand::LoiterUnlimited { target, yaw_rad } => {
                self.loiter_leg(p, input, from, item.seq, target, yaw_rad, None)
            }
            NavCommand::Land { target, yaw_rad } => {
                if let Some(y) = yaw_rad {
                    p.yaw_rad = y;
                }
                let to = resolve(input, &target, from)?;
                let to = Vector3::new(to.x, to.y, from.z);
                let leg = p.line(input, to, Climb::Move, Some(item.seq));
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

    /// The run of spline waypoints from `current`: this one and the spline waypoints after it without
    /// hold time.
    fn plan_run(&self, p: &mut Planner, input: &NavInput, from: Vector3<f64>) -> Option<Phase> {
        let accept_default = p.config.acceptance_radius_m;
        let mut points = vec![from];
        let mut knots: Vec<u16> = Vec::new();
        let mut idx = self.current;
        let mut last_hold = 0.0;
        while idx < self.items.len() && knots.len() < MAX_RUN {
            let NavCommand::Waypoint { target, hold_s, spline: true, .. } = self.items[idx].command else {
                break;
            };
            let pt = resolve(input, &target, *points.last().unwrap_or(&from))?;
            if knots.is_empty() && (pt - from).norm() < MIN_LEG_M {
                // The run starts at the reference's point: the first waypoint is its start.
                points[0] = pt;
            } else {
                points.push(pt);
            }
            knots.push(self.items[idx].seq);
            last_hold = hold_s.max(0.0);
            idx += 1;
            if hold_s > 0.0 {
                break;
            }
        }
        let end_item = *knots.last()?;
        // A closed loop of waypoints (the figure-8) entered from elsewhere, even from a few centimetres
        // away: fly to its first waypoint, then the loop itself, periodic.
        if let (&[first_seq, .., _], &[_, first, .., last]) = (knots.as_slice(), points.as_slice())
            && knots.len() >= 4
            && points.len() > knots.len()
            && (first - last).norm() < MIN_LEG_M
        {
            let leg = p.line(input, first, Climb::Move, Some(first_seq));
            let (leg, accept_m) = (Box::new(leg), accept_default);
            return Some(Phase::Fly { leg, end_item: first_seq, hold_s: 0.0, accept_m, then: After::Restart });
        }
        // A run that ends where it starts (to within rounding) is closed exactly, so its spline is periodic.
        if let [first, .., last] = points.as_mut_slice()
            && (*first - *last).norm() < MIN_LEG_M
        {
            *first = *last;
        }
        let mut leg = run_leg(p, input, &points, &knots)?;
        // A DO_JUMP right after a closed run, back to its first waypoint (the figure-8 flown for laps): the
        // laps are one leg, flown through the seam without stopping.
        if let Some(&NavItem { seq: jump_seq, command: NavCommand::Jump { target, repeat } }) = self.items.get(idx)
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
            accept_m: accept_default,
            then: After::Next,
        })
    }

    /// Fly to `target` and loiter there for `time_s` (None: forever).
    #[allow(clippy::too_many_arguments)]
    fn loiter_leg(
        &self,
        p: &mut Planner,
        input: &NavInput,
        from: Vector3<f64>,
        seq: u16,
        target: NavTarget,
        yaw_rad: Option<f64>,
        time_s: Option<f64>,
    ) -> Option<Phase> {
        let to = resolve(input, &target, from)?;
        if let Some(y) = yaw_rad {
            p.yaw_rad = y;
        }
        let leg = p.line(input, to, Climb::Move, Some(seq));
        let accept_m = p.config.acceptance_radius_m;
        Some(Phase::Fly { leg: Box::new(leg), end_item: seq, hold_s: 0.0, accept_m, then: After::Loiter(time_s) })
    }

    fn run_phase(&mut self, p: &mut Planner, input: &NavInput) -> Motion3 {
        let now = input.now_us;
        match &mut self.phase {
            Phase::Start | Phase::Done => self.hold_here(p, input),
            Phase::Landed { flight } => flight.fly(p, input),
            Phase::Climb { flight, item } => {
                let item = *item;
                let m = flight.fly(p, input);
                if flight.reached_altitude(input) {
                    match item {
                        Some(seq) => {
                            p.events.push(NavEvent::Reached(seq));
                            self.advance_item();
                        }
                        None => self.phase = Phase::Start,
                    }
                }
                m
            }
            Phase::Fly { leg, end_item, hold_s, accept_m, then } => {
                let m = p.fly(leg, input);
                let passed = leg.newly_passed();
                let (end_item, hold_s, accept_m, then) = (*end_item, *hold_s, *accept_m, *then);
                let end = leg.end();
                let arrived = leg.at_end() && (input.pos_ned_m - end).norm() <= accept_m;
                for seq in passed {
                    p.events.push(NavEvent::Reached(seq));
                    let Some(i) = self.items.iter().position(|i| i.seq == seq) else { continue };
                    if let NavCommand::Jump { target, repeat } = self.items[i].command {
                        // A lap of a repeated run ended: the jump is taken as start_item would take it (the
                        // leg has a lap only while the jump has repeats left).
                        self.take_jump(seq, repeat);
                        self.current = self.items.iter().position(|i| i.seq == target).unwrap_or(i);
                    } else {
                        self.current = i + 1;
                    }
                    self.emit_current(p);
                }
                if arrived {
                    self.current = self.items.iter().position(|i| i.seq == end_item).unwrap_or(self.current);
                    match then {
                        After::Next if hold_s <= 0.0 => {
                            p.events.push(NavEvent::Reached(end_item));
                            self.advance_item();
                        }
                        After::Next => {
                            let until = after_us(now, hold_s);
                            self.phase = Phase::Wait { at: end, until_us: Some(until), item: end_item };
                        }
                        After::Loiter(time) => {
                            let until = time.map(|t| after_us(now, t));
                            self.phase = Phase::Wait { at: end, until_us: until, item: end_item };
                        }
                        After::Land => {
                            let flight = Box::new(Flight::land(p, input, end.xy()));
                            self.phase = Phase::Descend { flight, item: Some(end_item) };
                        }
                        After::Restart => self.phase = Phase::Start,
                    }
                }
                m
            }
            Phase::Wait { at, until_us, item } => {
                let (at, until, item) = (*at, *until_us, *item);
                if until.is_some_and(|u| now >= u) {
                    p.events.push(NavEvent::Reached(item));
                    self.advance_item();
                }
                let m = still(at);
                p.last = Some(m);
                m
            }
            Phase::Descend { flight, item } => {
                let item = *item;
                let m = flight.fly(p, input);
                if input.landed {
                    self.landed_at_end(p, item);
                }
                m
            }
            Phase::Return { rtl, item } => {
                let item = *item;
                let mut state = rtl.take().map(|b| *b);
                let m = rtl::step(&mut state, p, input);
                *rtl = state.map(Box::new);
                if p.landing && input.landed {
                    self.landed_at_end(p, Some(item));
                }
                m
            }
        }
    }

    /// The mission ended on the ground (NAV_LAND, NAV_RETURN_TO_LAUNCH): the item is reached, and the
    /// mission done (the commander disarms after touchdown). The landing leg flies on.
    fn landed_at_end(&mut self, p: &mut Planner, item: Option<u16>) {
        if let Some(seq) = item {
            p.events.push(NavEvent::Reached(seq));
        }
        let flight = match std::mem::take(&mut self.phase) {
            Phase::Descend { flight, .. } => Some(flight),
            Phase::Return { rtl: Some(r), .. } => r.into_flight().map(Box::new),
            _ => None,
        };
        let flight = flight.unwrap_or_else(|| {
            let here = p.last.map_or(Vector3::zeros(), |m| m.pos_ned_m);
            let rest = Leg::plan(
                &Motion3::rest(here),
                0,
                Vec::new(),
                |_| rest_limits(p),
                |from| LegPath::Line { from, to: from },
            );
            Box::new(Flight::of(rest, Climb::Land))
        });
        self.phase = Phase::Landed { flight };
        p.events.push(NavEvent::Text("Mission finished: landed".into()));
    }
}

fn rest_limits(p: &Planner) -> super::trajectory::Limits {
    super::trajectory::Limits {
        vel_mps: p.config.land_speed_mps,
        acc_mps2: p.config.acc_down_mps2,
        jerk_mps3: p.config.jerk_mps3,
    }
}

/// The local NED point of `target`, with `here` for "here" (the one resolver, `core::plan`).
pub(crate) fn resolve(input: &NavInput, target: &NavTarget, here: Vector3<f64>) -> Option<Vector3<f64>> {
    plan::resolve(target, &input.frame(), here).ok()
}

/// A leg through `points` (the first is the start): a line for two, a spline for more.
fn run_leg(p: &Planner, input: &NavInput, points: &[Vector3<f64>], knots: &[u16]) -> Option<Leg> {
    if points.len() <= 2 {
        return Some(p.line(input, *points.last()?, Climb::Move, knots.last().copied()));
    }
    let ne: Vec<[f64; 2]> = points.iter().map(|pt| [pt.x, pt.y]).collect();
    // Consecutive equal points (a vertical-only move inside a run) cannot be splined: fly the run as
    // lines up to its first such point.
    let Some(path) = SplinePath::try_new(&ne) else {
        return Some(p.line(input, points[1], Climb::Move, knots.first().copied()));
    };
    let offset = usize::from(points.len() > knots.len());
    let alt: Vec<(f64, f64)> = (0..points.len()).map(|i| (path.knot_arc_m(i), points[i].z)).collect();
    let knot_arcs: Vec<(f64, u16)> =
        knots.iter().enumerate().map(|(i, &seq)| (path.knot_arc_m(i + offset), seq)).collect();
    let spline = LegPath::Spline { path, alt };
    let start = p.start(input);
    let limits = p.limits(&spline, Climb::Move);
    // The spline starts at the reference's position (its first point is `from`); a moving start brakes
    // first and the spline is then re-solved from where it stopped.
    let first = points[0];
    Some(Leg::plan(
        &start,
        input.now_us,
        knot_arcs,
        |_| limits,
        |from| {
            if (from - first).norm() < MIN_LEG_M {
                spline.clone()
            } else {
                let mut moved: Vec<[f64; 2]> = ne.clone();
                moved[0] = [from.x, from.y];
                match SplinePath::try_new(&moved) {
                    Some(path) => {
                        let alt = (0..points.len())
                            .map(|i| (path.knot_arc_m(i), if i == 0 { from.z } else { points[i].z }))
                            .collect();
                        LegPath::Spline { path, alt }
                    }
                    None => LegPath::Line { from, to: points[1] },
                }
            }
        },
    ))
}
