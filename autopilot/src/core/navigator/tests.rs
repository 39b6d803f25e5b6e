//! The navigator flown by an ideal vehicle that is exactly where its reference says: missions, jumps,
//! holds, the return and offboard, checked on the reference's own numbers (limits, continuity, events).

use nalgebra::{Vector2, Vector3};

use super::spline::SplinePath;
use super::*;
use crate::core::control::Reference;
use crate::core::plan::geofence::Rally;

const ORIGIN: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };
const DT_S: f64 = 0.002;

/// A vehicle that is where its reference says, landed at D >= 0.
struct Ideal {
    nav: Navigator,
    pos: Vector3<f64>,
    now_us: u64,
    events: Vec<NavEvent>,
    max_speed_mps: f64,
    /// The levels the navigator's progress events last reported (what the commander reads).
    done: bool,
    landing: bool,
}

impl Ideal {
    fn new(items: Vec<NavItem>) -> Self {
        let mut nav = Navigator::new(NavigatorConfig::default());
        nav.set_mission(items.into());
        Self {
            nav,
            pos: Vector3::zeros(),
            now_us: 0,
            events: Vec::new(),
            max_speed_mps: 0.0,
            done: false,
            landing: false,
        }
    }

    fn input(&self) -> NavInput {
        NavInput {
            now_us: self.now_us,
            pos_ned_m: self.pos,
            vel_ned_mps: Vector3::zeros(),
            yaw_rad: 0.0,
            origin: Some(ORIGIN),
            home_ned_m: Some(Vector3::zeros()),
            home_alt_amsl_m: Some(ORIGIN.alt_amsl_m),
            landed: self.pos.z >= -1e-3,
            position_valid: true,
            takeoff_alt_m: 2.5,
            takeoff_acceptance_m: 0.1,
        }
    }

    fn step(&mut self, mode: AutoMode) -> Reference {
        let sp = self.nav.update(Intent::Auto(mode), &self.input(), &Rally::default()).expect("flying");
        self.take_progress();
        self.follow(&sp);
        self.now_us += 2_000;
        self.events.extend(self.nav.take_events());
        sp
    }

    /// The vehicle goes where the reference is (not below the ground).
    fn follow(&mut self, sp: &Reference) {
        if sp.attitude_rad.is_none() {
            self.max_speed_mps = self.max_speed_mps.max(sp.vel_ned_mps.xy().norm());
            self.pos = sp.pos_ned_m;
            self.pos.z = self.pos.z.min(0.0);
        }
    }

    /// The navigator's progress events, as the commander takes them.
    fn take_progress(&mut self) {
        for p in self.nav.take_progress() {
            match p {
                Progress::MissionDone(done) => self.done = done,
                Progress::Landing(landing) => self.landing = landing,
            }
        }
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
            spline: false,
        },
    }
}

/// A spline waypoint `n_m`, `e_m` metres from the origin at `alt_m` above home.
fn spline_wp(seq: u16, n_m: f64, e_m: f64, alt_m: f64) -> NavItem {
    let mut item = wp(seq, n_m, e_m, alt_m);
    if let NavCommand::Waypoint { spline, .. } = &mut item.command {
        *spline = true;
    }
    item
}

fn figure8(first_seq: u16) -> Vec<NavItem> {
    let pts = spline::FIGURE8_NE_M;
    pts.iter().enumerate().map(|(i, &[n, e])| spline_wp(first_seq + i as u16, n, e, 1.5)).collect()
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
    assert!(!v.done, "a landed mission is not done in the air");
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
        {
            let (pos_ned_m, vel_ned_mps) = (sp.pos_ned_m, sp.vel_ned_mps);
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
    assert!(v.done);
}

#[test]
fn given_a_jump_repeated_twice_when_flown_then_its_run_is_flown_three_times() {
    let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
    items.extend([wp(1, 2.0, 0.0, 2.0), wp(2, 0.0, 0.0, 2.0)]);
    items.push(NavItem { seq: 3, command: NavCommand::Jump { target: 1, repeat: 2 } });
    let mut v = Ideal::new(items);
    v.run(AutoMode::Mission, 60.0);
    assert_eq!(v.reached(), vec![0, 1, 2, 3, 1, 2, 3, 1, 2, 3]);
    assert!(v.done);
}

/// The horizontal speed of each step and the reached events so far, over `seconds` of a mission.
fn fly_logging(v: &mut Ideal, seconds: f64) -> Vec<(f64, usize)> {
    let mut log = Vec::new();
    for _ in 0..(seconds / DT_S) as usize {
        let sp = v.step(AutoMode::Mission);
        log.push((sp.vel_ned_mps.xy().norm(), v.reached().len()));
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
    assert!(v.done);
    assert_eq!(v.nav.mission.jumps_left_of(11), Some(0));
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
    assert!(!v.done);
    let min_speed = log.iter().filter(|(_, r)| *r >= 4).map(|(s, _)| *s).fold(f64::INFINITY, f64::min);
    assert!(min_speed > 0.2, "min speed {min_speed} m/s");
    assert_eq!(v.nav.mission.jumps_left_of(11), Some(-1));
}

#[test]
fn given_a_loop_entered_from_outside_when_repeated_then_the_first_lap_stops_at_the_jump_and_later_ones_do_not() {
    // GIVEN a triangle that does not start where the vehicle is: its first lap is an open run.
    let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
    items.push(NavItem { seq: 1, command: NavCommand::ChangeSpeed { speed_mps: Some(0.3) } });
    items.extend([spline_wp(2, 2.0, 0.0, 2.0), spline_wp(3, 2.0, 2.0, 2.0), spline_wp(4, 0.0, 2.0, 2.0)]);
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
    for _ in 0..(60.0 / DT_S) as usize {
        v.step(AutoMode::ReturnToLaunch);
        max_alt = max_alt.max(-v.pos.z);
        landing_seen |= v.landing;
        if v.pos.z >= 0.0 {
            break;
        }
    }
    let rtl_alt = NavigatorConfig::default().rtl_return_alt_m;
    assert!((max_alt - rtl_alt).abs() < 1e-6, "climbed to RTL_RETURN_ALT, no overshoot: {max_alt}");
    assert!(v.pos.xy().norm() < 0.01, "landed at home: {:?}", v.pos);
    assert!(landing_seen);
}

#[test]
fn given_offboard_velocity_then_a_carrot_moves_at_that_velocity() {
    let mut v = Ideal::new(Vec::new());
    v.pos = Vector3::new(0.0, 0.0, -2.0);
    v.nav.set_offboard(OffboardSetpoint {
        vel_ned_mps: Some(Vector3::new(1.0, 0.0, 0.0)),
        yaw_rad: Some(0.5),
        ..OffboardSetpoint::default()
    });
    let sp = v.step(AutoMode::Offboard);
    assert_eq!((sp.vel_ned_mps, sp.yaw_rad), (Vector3::new(1.0, 0.0, 0.0), 0.5));
    v.run(AutoMode::Offboard, 0.4);
    assert!(v.pos.x > 0.39 && v.pos.x < 0.41, "carrot moved 1 m/s x 0.4 s: {}", v.pos.x);
}

/// Flies `intent` with the ideal vehicle for `seconds`; the references.
fn fly_task(v: &mut Ideal, intent: Intent, seconds: f64) -> Vec<Reference> {
    let mut out = Vec::new();
    for _ in 0..(seconds / DT_S) as usize {
        let input = v.input();
        let sp = v.nav.update(intent, &input, &Rally::default()).expect("flying");
        v.take_progress();
        v.follow(&sp);
        v.now_us += 2_000;
        out.push(sp);
    }
    out
}

#[test]
fn given_a_new_hold_point_then_a_jerk_limited_leg_flies_there_within_the_limits_and_stays() {
    let mut v = Ideal::new(Vec::new());
    v.pos = Vector3::new(0.0, 0.0, -2.0);
    let target = Vector3::new(4.0, 3.0, -2.0);
    let refs = fly_task(&mut v, Intent::Hold { at: HoldAt::Point(target), yaw_rad: None }, 15.0);
    let cfg = NavigatorConfig::default();
    let max_speed = refs.iter().map(|r| r.vel_ned_mps.norm()).fold(0.0, f64::max);
    let max_acc = refs.iter().map(|r| r.acc_ned_mps2.norm()).fold(0.0, f64::max);
    let max_jerk = refs.windows(2).map(|w| (w[1].acc_ned_mps2 - w[0].acc_ned_mps2).norm() / DT_S).fold(0.0, f64::max);
    assert!((v.pos - target).norm() < 1e-9, "{:?}", v.pos);
    assert!(max_speed <= cfg.cruise_speed_mps + 1e-9 && max_speed > 0.99 * cfg.cruise_speed_mps, "{max_speed}");
    assert!(max_acc <= cfg.acc_hor_mps2 + 1e-9, "peak acceleration {max_acc}");
    assert!(max_jerk <= cfg.jerk_mps3 * 1.001, "peak jerk {max_jerk}");
    // The position never passes the target along the way (no overshoot).
    let dir = target.xy().normalize();
    let beyond = refs.iter().map(|r| r.pos_ned_m.xy().dot(&dir) - 5.0).fold(f64::NEG_INFINITY, f64::max);
    assert!(beyond <= 1e-9, "overshoot {beyond}");
}

#[test]
fn given_a_takeoff_then_hold_at_the_same_point_then_the_climb_goes_on_smoothly_at_the_takeoff_speed() {
    let mut v = Ideal::new(Vec::new());
    let target = Vector3::new(0.0, 0.0, -5.0);
    let mut refs = fly_task(&mut v, Intent::Takeoff { alt_m: 5.0 }, 2.0);
    refs.extend(fly_task(&mut v, Intent::Hold { at: HoldAt::TakeoffPoint, yaw_rad: None }, 8.0));
    let cfg = NavigatorConfig::default();
    let max_climb = refs.iter().map(|r| -r.vel_ned_mps.z).fold(0.0, f64::max);
    assert!((max_climb - cfg.takeoff_speed_mps).abs() < 1e-9, "{max_climb}");
    let max_jerk = refs.windows(2).map(|w| (w[1].acc_ned_mps2 - w[0].acc_ned_mps2).norm() / DT_S).fold(0.0, f64::max);
    assert!(max_jerk <= cfg.jerk_mps3 * 1.001, "continuous acceleration at the handover: peak jerk {max_jerk}");
    assert!(refs.iter().all(|r| r.pos_ned_m.z >= target.z - 1e-9), "never above the target");
    assert_eq!(v.pos, target);
}

#[test]
fn given_a_moving_reference_when_hold_here_then_it_stops_jerk_limited_and_stays() {
    let mut v = Ideal::new(Vec::new());
    v.pos = Vector3::new(0.0, 0.0, -2.0);
    fly_task(&mut v, Intent::Hold { at: HoldAt::Point(Vector3::new(20.0, 0.0, -2.0)), yaw_rad: None }, 5.0);
    let moving_at = v.pos;
    let refs = fly_task(&mut v, Intent::Hold { at: HoldAt::Stop, yaw_rad: None }, 5.0);
    let cfg = NavigatorConfig::default();
    let max_jerk = refs.windows(2).map(|w| (w[1].acc_ned_mps2 - w[0].acc_ned_mps2).norm() / DT_S).fold(0.0, f64::max);
    assert!(max_jerk <= cfg.jerk_mps3 * 1.001, "{max_jerk}");
    let end = refs.last().expect("refs").pos_ned_m;
    assert!(end.x > moving_at.x && end.x < moving_at.x + 1.5, "stops ahead within its braking distance: {end:?}");
    assert!(refs.last().expect("refs").vel_ned_mps.norm() < 1e-12);
}

#[test]
fn given_a_land_task_then_it_descends_at_the_land_speed_below_the_ground() {
    let mut v = Ideal::new(Vec::new());
    v.pos = Vector3::new(1.0, 2.0, -5.0);
    let refs = fly_task(&mut v, Intent::Land, 12.0);
    let cfg = NavigatorConfig::default();
    let max_sink = refs.iter().map(|r| r.vel_ned_mps.z).fold(0.0, f64::max);
    assert!((max_sink - cfg.land_speed_mps).abs() < 1e-9, "{max_sink}");
    let last = refs.last().expect("refs").pos_ned_m;
    assert!((last.z - cfg.land_below_ground_m).abs() < 1e-9, "{last:?}");
    assert!(v.landing);
}

#[test]
fn given_a_waypoint_with_a_hold_time_of_1e30_s_then_the_vehicle_waits_without_overflow() {
    let mut items = vec![NavItem { seq: 0, command: NavCommand::Takeoff { alt_m: 2.0, relative: true } }];
    let mut hold = wp(1, 1.0, 0.0, 2.0);
    if let NavCommand::Waypoint { hold_s, .. } = &mut hold.command {
        *hold_s = 1e30;
    }
    items.push(hold);
    items.push(NavItem { seq: 2, command: NavCommand::Delay { time_s: f64::MAX } });
    let mut v = Ideal::new(items);
    v.run(AutoMode::Mission, 30.0);
    assert_eq!(v.reached(), vec![0], "still holding at the waypoint");
}

#[test]
fn given_an_offboard_position_stream_along_a_circle_then_the_reference_follows_without_stalling() {
    // GIVEN position setpoints at 20 Hz moving along a circle of 5 m at 0.5 m/s (a target that moves a
    // little at every update).
    let mut v = Ideal::new(Vec::new());
    v.pos = Vector3::new(5.0, 0.0, -2.0);
    let mut speeds = Vec::new();
    let mut worst_gap: f64 = 0.0;
    for k in 0..(30.0 / DT_S) as usize {
        let t_s = k as f64 * DT_S;
        let angle = 0.1 * t_s;
        let target = Vector3::new(5.0 * angle.cos(), 5.0 * angle.sin(), -2.0);
        if k % 25 == 0 {
            let sp = OffboardSetpoint { pos_ned_m: Some(target), yaw_rad: Some(0.0), ..OffboardSetpoint::default() };
            v.nav.set_offboard(sp);
        }
        let sp = v.step(AutoMode::Offboard);
        if t_s > 5.0 {
            speeds.push(sp.vel_ned_mps.norm());
            worst_gap = worst_gap.max((sp.pos_ned_m - target).norm());
        }
    }
    // THEN it keeps moving with the target (no brake at every update) and stays behind it by about what a
    // position controller lags a 0.5 m/s target (0.52 m measured; each leg aims to stop at its target).
    let slowest = speeds.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(slowest > 0.3, "the reference stalls: {slowest} m/s");
    assert!(worst_gap < 0.8, "falls behind the stream: {worst_gap} m");
}

/// The navigator steps once with `intent` from where the ideal vehicle is, at `yaw_rad`.
fn step_intent(v: &mut Ideal, intent: Intent, yaw_rad: f64) -> Reference {
    let input = NavInput { yaw_rad, ..v.input() };
    let sp = v.nav.update(intent, &input, &Rally::default()).expect("flying");
    v.follow(&sp);
    v.now_us += 2_000;
    sp
}

#[test]
fn given_intents_then_the_navigator_latches_the_takeoff_point_here_keeps_it_for_a_new_altitude_and_lands_here() {
    let mut v = Ideal::new(Vec::new());
    v.pos = Vector3::new(1.0, -2.0, 0.0);
    // The yaw is the vehicle's as it leaves the ground idle, and stays while it turns.
    assert_eq!(v.nav.update(Intent::Idle, &NavInput { yaw_rad: 0.7, ..v.input() }, &Rally::default()), None);
    let sp = step_intent(&mut v, Intent::Takeoff { alt_m: 2.5 }, 0.7);
    assert_eq!(sp.yaw_rad, 0.7);
    for _ in 0..500 {
        assert_eq!(step_intent(&mut v, Intent::Takeoff { alt_m: 2.5 }, 0.1).yaw_rad, 0.7);
    }
    // A new altitude while climbing keeps the point the takeoff latched (not where the climb is now).
    v.pos.x += 0.3;
    let refs: Vec<Reference> = (0..4000).map(|_| step_intent(&mut v, Intent::Takeoff { alt_m: 4.0 }, 0.1)).collect();
    let end = refs.last().expect("refs").pos_ned_m;
    assert_eq!(end, Vector3::new(1.0, -2.0, -4.0), "the takeoff's point, 4 m above the ground");
    // The hold that ends a takeoff holds that point; a reposition's yaw is latched and kept.
    assert_eq!(step_intent(&mut v, Intent::Hold { at: HoldAt::TakeoffPoint, yaw_rad: None }, 0.1).pos_ned_m, end);
    let p = Vector3::new(3.0, 0.0, -4.0);
    assert_eq!(step_intent(&mut v, Intent::Hold { at: HoldAt::Point(p), yaw_rad: Some(-1.0) }, 0.1).yaw_rad, -1.0);
    assert_eq!(step_intent(&mut v, Intent::Hold { at: HoldAt::Stop, yaw_rad: None }, 0.1).yaw_rad, -1.0);
    // A landing descends where the vehicle is as it starts.
    v.pos = Vector3::new(2.0, 1.0, -4.0);
    let sp = step_intent(&mut v, Intent::Land, 0.1);
    assert_eq!(sp.pos_ned_m.xy(), Vector2::new(2.0, 1.0));
    v.pos.y += 0.5;
    for _ in 0..100 {
        assert_eq!(step_intent(&mut v, Intent::Land, 0.1).pos_ned_m.xy(), Vector2::new(2.0, 1.0));
    }
}

/// An intent the random sequences below may give (no Idle and no Land: those restart from or run into
/// the ground, where the ideal vehicle stops following its reference).
fn any_intent() -> impl proptest::strategy::Strategy<Value = Intent> {
    use proptest::prelude::*;
    prop_oneof![
        (0.5f64..20.0).prop_map(|alt_m| Intent::Takeoff { alt_m }),
        Just(Intent::Hold { at: HoldAt::Stop, yaw_rad: None }),
        Just(Intent::Hold { at: HoldAt::TakeoffPoint, yaw_rad: None }),
        (-30.0f64..30.0, -30.0f64..30.0, -20.0f64..-1.0, proptest::option::of(-3.0f64..3.0))
            .prop_map(|(n, e, d, yaw_rad)| Intent::Hold { at: HoldAt::Point(Vector3::new(n, e, d)), yaw_rad }),
    ]
}

proptest::proptest! {
    // 96 cases of the default 256: PROPTEST_CASES scales them with every other property test.
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(proptest::prelude::ProptestConfig::default().cases * 96 / 256))]

    /// Whatever the commander asks, in whatever order and for however long, the navigator's reference is
    /// finite; jerk-limited while an intent holds; and across every change of intent continuous in
    /// position, in velocity to within the 0.02 m/s a new leg may drop across its path, and in
    /// acceleration to within the acceleration limits (a new leg keeps only the acceleration along its
    /// path: this test found that the across part, up to MPC_ACC_UP_MAX, is dropped in one step).
    #[test]
    fn given_any_sequence_of_intents_then_the_reference_is_finite_jerk_limited_within_each_and_continuous_across(
        steps in proptest::collection::vec((any_intent(), 1usize..1500), 1..8),
    ) {
        let mut nav = Navigator::new(NavigatorConfig::default());
        let cfg = NavigatorConfig::default();
        let acc_max = cfg.acc_up_mps2.max(cfg.acc_down_mps2).max(cfg.acc_hor_mps2);
        // A slanted leg may move at both its horizontal and its vertical limit.
        let speed_max = cfg.cruise_speed_mps.hypot(cfg.climb_speed_mps.max(cfg.descent_speed_mps));
        let mut pos = Vector3::new(0.0, 0.0, -2.0);
        let mut vel = Vector3::zeros();
        let mut now_us = 0;
        let mut last: Option<(Intent, Reference)> = None;
        nav.start_airborne(pos, 0.0);
        for (intent, n) in steps {
            for _ in 0..n {
                let input = NavInput {
                    now_us,
                    pos_ned_m: pos,
                    vel_ned_mps: vel,
                    yaw_rad: 0.0,
                    origin: Some(ORIGIN),
                    home_ned_m: Some(Vector3::zeros()),
                    home_alt_amsl_m: Some(ORIGIN.alt_amsl_m),
                    landed: false,
                    position_valid: true,
                    takeoff_alt_m: 2.5,
                    takeoff_acceptance_m: 0.1,
                };
                let sp = nav.update(intent, &input, &Rally::default()).expect("flying");
                proptest::prop_assert!(
                    sp.pos_ned_m.iter().chain(sp.vel_ned_mps.iter()).chain(sp.acc_ned_mps2.iter()).all(|x| x.is_finite())
                        && sp.yaw_rad.is_finite(),
                    "{:?}", sp
                );
                if let Some((prev_intent, prev)) = last {
                    let step_m = (sp.pos_ned_m - prev.pos_ned_m).norm();
                    proptest::prop_assert!(step_m <= speed_max * DT_S * 1.01 + 1e-9, "position step {} m", step_m);
                    let dv = (sp.vel_ned_mps - prev.vel_ned_mps).norm();
                    let da = (sp.acc_ned_mps2 - prev.acc_ned_mps2).norm();
                    if prev_intent == intent {
                        proptest::prop_assert!(da / DT_S <= cfg.jerk_mps3 * 1.001 + 1e-9, "jerk {} in {:?}", da / DT_S, intent);
                    } else {
                        proptest::prop_assert!(dv <= 0.021 + acc_max * DT_S, "velocity step {} into {:?}", dv, intent);
                        proptest::prop_assert!(da <= acc_max * 1.001 + cfg.jerk_mps3 * DT_S, "acceleration step {} into {:?}", da, intent);
                    }
                }
                last = Some((intent, sp));
                pos = sp.pos_ned_m;
                vel = sp.vel_ned_mps;
                now_us += 2_000;
            }
        }
    }
}
