//! Commander tests: requests and refusals, the PX4 identity it reports, and whole flights against a tiny
//! vertical point-mass model (100 Hz, ground at D = 0) on simulated time.

use nalgebra::Vector3;

use super::*;
use crate::core::battery::BatteryWarning;
use crate::core::intent::{AutoMode, HoldAt, Intent, ManualMode, Progress};

const STEP_US: u64 = 10_000;
const G: f64 = 9.81;

/// A vertical point mass whose "controller" tracks the intent's vertical speed with a first-order lag;
/// idle or motors off, it falls; the ground at D = 0 stops it.
#[derive(Debug, Clone)]
struct Sim {
    now_us: u64,
    pos_d_m: f64,
    vel_d_mps: f64,
    converged: bool,
    throttle_low: bool,
    /// The vehicle's facts (a mission to fly, offboard setpoints).
    facts: Facts,
    /// The navigator's part: an automatic mode descends to land.
    landing: bool,
    /// The takeoff altitude the navigator latched (m above the ground at D = 0).
    takeoff_alt_m: f64,
    gcs_heartbeat_us: Option<u64>,
    /// The pack's state of charge the monitor reads every step (None: no pack).
    battery_remaining: Option<f64>,
    /// The geofence breach the vehicle would report.
    fence_breach: Option<crate::core::plan::geofence::Violation>,
}

impl Sim {
    fn new() -> Self {
        Self {
            now_us: 0,
            pos_d_m: 0.0,
            vel_d_mps: 0.0,
            converged: true,
            throttle_low: true,
            facts: Facts::default(),
            landing: false,
            takeoff_alt_m: 0.0,
            gcs_heartbeat_us: None,
            battery_remaining: None,
            fence_breach: None,
        }
    }

    fn inputs(&self) -> CommanderInputs {
        CommanderInputs {
            now_us: self.now_us,
            estimate: Estimate {
                pos_ned_m: Vector3::new(1.0, -2.0, self.pos_d_m),
                vel_ned_mps: Vector3::new(0.0, 0.0, self.vel_d_mps),
                roll_rad: 0.0,
                pitch_rad: 0.0,
                yaw_rad: 0.3,
                position_valid: self.converged,
                converged: self.converged,
                has_origin: true,
            },
            throttle_low: self.throttle_low,
            facts: self.facts,
            gcs_heartbeat_us: self.gcs_heartbeat_us,
            battery: self.battery_remaining.map(|r| crate::core::battery::BatterySample {
                voltage_v: 6.0 * 3.8,
                remaining: Some(r),
                ..Default::default()
            }),
            fence_breach: self.fence_breach,
        }
    }

    /// Advances one step under `out`.
    fn advance(&mut self, out: &CommanderOutput) {
        let dt = STEP_US as f64 * 1e-6;
        // The navigator's part: latch the takeoff's altitude, fly to points, stop, descend.
        if let Intent::Takeoff { alt_m } = out.intent {
            self.takeoff_alt_m = alt_m;
        }
        let to_d_m = |d_m: f64| Some((1.5 * (d_m - self.pos_d_m)).clamp(-1.5, 1.5));
        let vel_cmd = match out.intent {
            Intent::Takeoff { .. } | Intent::Hold { at: HoldAt::TakeoffPoint, .. } => to_d_m(-self.takeoff_alt_m),
            Intent::Hold { at: HoldAt::Point(p), .. } => to_d_m(p.z),
            // Hold where it stops: the vertical speed decays.
            Intent::Hold { at: HoldAt::Stop, .. } => Some(0.0),
            Intent::Land => Some(0.7),
            // Descend while it lands, hold the altitude otherwise.
            Intent::Auto(_) => Some(if self.landing { 0.7 } else { 0.0 }),
            // Sticks centred: hold the altitude; throttle low (`landing`): descend.
            Intent::Manual(_) => Some(if self.landing { 0.7 } else { 0.0 }),
            Intent::Idle => None,
        };
        let acc = match vel_cmd {
            Some(v) if out.motors_enabled => (4.0 * (v - self.vel_d_mps)).clamp(-G, G),
            _ => G,
        };
        self.vel_d_mps += acc * dt;
        self.pos_d_m += self.vel_d_mps * dt;
        let on_ground = self.pos_d_m >= 0.0;
        if on_ground {
            self.pos_d_m = 0.0;
            self.vel_d_mps = self.vel_d_mps.min(0.0);
        }
        // Thrust at its minimum: idle, off, or pushing down on the ground.
        self.throttle_low = vel_cmd.is_none() || !out.motors_enabled || (on_ground && acc >= 0.0);
        self.now_us += STEP_US;
    }

    /// Steps commander and model `n` times; returns every output.
    fn run(&mut self, c: &mut Commander, n: usize) -> Vec<CommanderOutput> {
        (0..n)
            .map(|_| {
                let out = c.step(&self.inputs());
                self.advance(&out);
                out
            })
            .collect()
    }

    /// Steps until `until` holds for an output, at most `max_s` seconds; returns the outputs up to and
    /// including that one.
    fn run_until(
        &mut self,
        c: &mut Commander,
        max_s: f64,
        until: impl Fn(&CommanderOutput) -> bool,
    ) -> Vec<CommanderOutput> {
        let steps = (max_s * 1e6 / STEP_US as f64) as usize;
        let mut outs = Vec::new();
        for _ in 0..steps {
            let out = c.step(&self.inputs());
            self.advance(&out);
            let done = until(&out);
            outs.push(out);
            if done {
                return outs;
            }
        }
        panic!("not reached within {max_s} s: {:?} at D {}", c.state(), self.pos_d_m);
    }
}

fn commander() -> Commander {
    Commander::new(CommanderConfig::default()).expect("default config is valid")
}

/// A commander armed (not taking off) after one step with a converged estimate.
fn armed_on_ground(sim: &mut Sim) -> Commander {
    let mut c = commander();
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    c
}

/// A commander holding at the takeoff altitude.
fn holding(sim: &mut Sim) -> Commander {
    let mut c = armed_on_ground(sim);
    c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: None }).expect("takeoff");
    sim.run_until(&mut c, 20.0, |o| o.state == State::Hold);
    c
}

const AUTO_LOITER: FlightMode = FlightMode::Hold;
const AUTO_TAKEOFF: FlightMode = FlightMode::Takeoff;
const AUTO_LAND: FlightMode = FlightMode::Land;

#[test]
fn given_an_unconverged_estimator_when_arming_then_refused_in_words_and_nothing_changes() {
    let mut sim = Sim::new();
    sim.converged = false;
    let mut c = commander();
    sim.run(&mut c, 10);
    let before = c.clone();
    let err = c.request(sim.now_us, sim.facts, Request::Arm { force: false }).unwrap_err();
    assert_eq!(err.to_string(), "Arming denied: estimator not converged");
    assert_eq!(c, before);
    assert!(!c.armed());

    sim.converged = true;
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm once converged");
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.state, State::ArmedIdle);
    assert!(out.armed && out.motors_enabled);
    assert_eq!(out.events, vec![Event::Armed { forced: false }]);
    assert_eq!(out.intent, Intent::Idle);
    assert_eq!(out.status, SystemStatus::Active);
    assert!(out.armed);
}

#[test]
fn given_an_unconverged_estimator_when_arming_with_force_then_armed() {
    let mut sim = Sim::new();
    sim.converged = false;
    let mut c = commander();
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Arm { force: true }).expect("forced arm");
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.state, State::ArmedIdle);
    assert_eq!(out.events, vec![Event::Armed { forced: true }]);
    // Armed without a usable position: CRITICAL.
    assert_eq!(out.status, SystemStatus::Critical);
}

#[test]
fn given_hold_in_the_air_when_disarming_then_refused_unless_forced() {
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    let before = c.clone();
    let err = c.request(sim.now_us, sim.facts, Request::Disarm { force: false }).unwrap_err();
    assert_eq!(err.to_string(), "Disarming denied: in air (use force)");
    assert_eq!(c, before);
    c.request(sim.now_us, sim.facts, Request::Disarm { force: true }).expect("forced disarm");
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.state, State::Disarmed);
    assert!(!out.motors_enabled);
    assert_eq!(out.events, vec![Event::Disarmed { reason: DisarmReason::Forced }]);
}

#[test]
fn given_armed_on_the_ground_when_disarming_then_accepted() {
    let mut sim = Sim::new();
    let mut c = armed_on_ground(&mut sim);
    sim.run(&mut c, 50);
    c.request(sim.now_us, sim.facts, Request::Disarm { force: false }).expect("disarm on the ground");
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.state, State::Disarmed);
    assert_eq!(out.events, vec![Event::Disarmed { reason: DisarmReason::Requested }]);
    assert_eq!(out.status, SystemStatus::Standby);
}

#[test]
fn given_each_state_when_killed_then_motors_stop_at_once_and_only_a_disarm_resets() {
    let mut sim_takeoff = Sim::new();
    let mut taking_off = armed_on_ground(&mut sim_takeoff);
    taking_off.request(sim_takeoff.now_us, sim_takeoff.facts, Request::Takeoff { alt_rel_m: None }).expect("takeoff");
    sim_takeoff.run(&mut taking_off, 50);
    let mut sim_land = Sim::new();
    let mut landing = holding(&mut sim_land);
    landing.request(sim_land.now_us, sim_land.facts, Request::Land).expect("land");
    sim_land.run(&mut landing, 10);
    let mut sim_hold = Sim::new();
    let mut sim_idle = Sim::new();
    let mut sim_dis = Sim::new();
    let mut disarmed = commander();
    sim_dis.run(&mut disarmed, 1);
    let cases = [
        (sim_dis, disarmed),
        (sim_idle.clone(), armed_on_ground(&mut sim_idle)),
        (sim_takeoff, taking_off),
        (sim_hold.clone(), holding(&mut sim_hold)),
        (sim_land, landing),
    ];
    let mut seen = Vec::new();
    for (_, mut c) in cases {
        seen.push(c.state());
        c.request(0, Facts::default(), Request::Kill).expect("kill is never refused");
        assert_eq!(c.state(), State::Killed);
        assert!(!c.armed());
        assert_eq!(c.intent(), Intent::Idle);
        assert_eq!(c.system_status(), SystemStatus::Emergency);
        assert!(!c.armed());
        let err = c.request(0, Facts::default(), Request::Arm { force: true }).unwrap_err();
        assert_eq!(err.to_string(), "Arming denied: kill engaged (disarm to reset)");
        c.request(0, Facts::default(), Request::Disarm { force: false }).expect("disarm resets a kill");
        assert_eq!(c.state(), State::Disarmed);
    }
    assert_eq!(seen, [State::Disarmed, State::ArmedIdle, State::Takeoff, State::Hold, State::Land]);
}

#[test]
fn given_a_kill_in_the_air_then_the_vehicle_falls_with_motors_off() {
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    c.request(sim.now_us, sim.facts, Request::Kill).expect("kill");
    let outs = sim.run(&mut c, 10);
    assert_eq!(outs[0].events, vec![Event::Disarmed { reason: DisarmReason::Kill }, Event::Killed]);
    assert!(outs.iter().all(|o| !o.motors_enabled && o.state == State::Killed));
    assert!(sim.vel_d_mps > 0.5, "falling at {} m/s", sim.vel_d_mps);
}

#[test]
fn given_takeoff_requested_while_disarmed_when_armed_then_climbs_and_holds_at_the_takeoff_point() {
    let mut sim = Sim::new();
    let mut c = commander();
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: None }).expect("takeoff accepted while disarmed");
    assert_eq!(c.state(), State::Disarmed);
    assert_eq!(c.pending_takeoff_alt_m(), Some(2.5));
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.mode, AUTO_TAKEOFF);
    assert_eq!(out.events, vec![Event::ModeChanged { mode: FlightMode::Takeoff }]);
    assert_eq!(out.intent, Intent::Idle, "nothing moves before arming");

    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.state, State::Takeoff);
    assert_eq!(out.mode, AUTO_TAKEOFF);
    assert_eq!(out.landed, LandedState::Takeoff);
    assert_eq!(out.intent, Intent::Takeoff { alt_m: 2.5 });

    let outs = sim.run(&mut c, 1000);
    let first_hold = outs.iter().position(|o| o.state == State::Hold).expect("takeoff completes");
    assert!(outs[..first_hold].iter().all(|o| o.landed == LandedState::Takeoff && o.mode == AUTO_TAKEOFF));
    let done = &outs[first_hold];
    assert_eq!(done.mode, AUTO_LOITER);
    assert_eq!(done.landed, LandedState::InAir);
    assert_eq!(done.events, vec![Event::TakeoffComplete, Event::ModeChanged { mode: FlightMode::Hold }]);
    assert_eq!(done.intent, Intent::Hold { at: HoldAt::TakeoffPoint, yaw_rad: None });
    assert!((sim.pos_d_m + 2.5).abs() < 0.05, "holding at D {}", sim.pos_d_m);
    assert!(outs[first_hold..].iter().all(|o| o.state == State::Hold && o.landed == LandedState::InAir));
}

#[test]
fn given_a_takeoff_altitude_when_requested_then_it_is_the_target_and_a_bad_one_is_refused() {
    let mut sim = Sim::new();
    let mut c = armed_on_ground(&mut sim);
    let before = c.clone();
    for bad in [0.0, -1.0, f64::NAN] {
        let err = c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: Some(bad) }).unwrap_err();
        assert!(matches!(err, Refusal::InvalidAltitude(_)), "{bad}");
        assert_eq!(c, before);
    }
    c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: Some(5.0) }).expect("takeoff");
    assert!(matches!(c.intent(), Intent::Takeoff { alt_m } if alt_m == 5.0));
}

#[test]
fn given_hold_when_landing_then_descends_detects_touchdown_and_disarms_exactly_after_com_disarm_land() {
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    sim.run(&mut c, 100);
    c.request(sim.now_us, sim.facts, Request::Land).expect("land");
    let out = sim.run(&mut c, 1).remove(0);
    assert_eq!(out.mode, AUTO_LAND);
    assert_eq!(out.landed, LandedState::Landing);
    assert_eq!(out.intent, Intent::Land);
    sim.run(&mut c, 300);
    assert!((sim.vel_d_mps - 0.7).abs() < 0.05, "descending at {} m/s", sim.vel_d_mps);

    let touchdown_sim_us = {
        let mut probe = sim.clone();
        let mut cp = c.clone();
        while probe.pos_d_m < 0.0 {
            probe.run(&mut cp, 1);
        }
        probe.now_us
    };
    let landed = sim.run_until(&mut c, 10.0, |o| o.events.contains(&Event::Landed)).pop().unwrap();
    let landed_at_us = sim.now_us - STEP_US;
    assert_eq!(landed.landed, LandedState::OnGround);
    assert!(landed.armed);
    assert_eq!(landed.intent, Intent::Idle);
    assert_eq!(landed_at_us, touchdown_sim_us + 500_000, "landed after the 0.5 s dwell on the ground");

    // Armed for exactly COM_DISARM_LAND (2 s = 200 steps) after the detection, then disarmed.
    let outs = sim.run(&mut c, 201);
    assert!(outs[..199].iter().all(|o| o.armed && o.state == State::Land));
    let disarm = &outs[199];
    assert_eq!(sim.now_us - 2 * STEP_US, landed_at_us + 2_000_000);
    assert!(!disarm.armed);
    assert_eq!(disarm.state, State::Disarmed);
    assert_eq!(disarm.events[0], Event::Disarmed { reason: DisarmReason::AutoLanded });
    assert!(!disarm.armed);
    assert!(outs[198].armed);
    assert_eq!(disarm.status, SystemStatus::Standby);
    assert_eq!(disarm.landed, LandedState::OnGround);
    assert_eq!(disarm.mode, AUTO_LOITER, "back to Hold after landing");
}

#[test]
fn given_a_flight_by_hand_when_the_throttle_lands_it_then_disarmed_com_disarm_land_after_touchdown_as_a_landing() {
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    sim.facts.manual_fresh = true;
    c.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::Position)).expect("POSCTL in the air");
    assert_eq!(c.state(), State::Manual);
    // Throttle low: it descends and touches down, still in Position.
    sim.landing = true;
    sim.run_until(&mut c, 20.0, |o| o.events.contains(&Event::Landed));
    let landed_at_us = sim.now_us - STEP_US;
    let outs = sim.run_until(&mut c, 5.0, |o| !o.armed);
    assert!(outs[..outs.len() - 1].iter().all(|o| o.state == State::Manual));
    assert_eq!(sim.now_us - STEP_US, landed_at_us + 2_000_000, "COM_DISARM_LAND after the detection");
    let disarm = outs.last().expect("disarmed");
    assert_eq!(disarm.events, vec![Event::Disarmed { reason: DisarmReason::AutoLanded }], "not 'no takeoff'");
    assert_eq!(disarm.mode, FlightMode::Position, "a manual mode stays the mode to arm in");
}

#[test]
fn given_armed_without_takeoff_when_com_disarm_prflt_passes_then_auto_disarmed_not_before() {
    let mut sim = Sim::new();
    let mut c = armed_on_ground(&mut sim);
    let armed_at = sim.now_us;
    let outs = sim.run(&mut c, 1001);
    let first_disarmed = outs.iter().position(|o| !o.armed).expect("auto-disarm");
    assert_eq!(armed_at + first_disarmed as u64 * STEP_US, armed_at + 10_000_000);
    assert_eq!(outs[first_disarmed].events, vec![Event::Disarmed { reason: DisarmReason::AutoPreflight }]);
}

#[test]
fn given_set_mode_requests_then_supported_modes_switch_and_others_are_refused_in_words() {
    let mut sim = Sim::new();
    let mut c = armed_on_ground(&mut sim);
    let before = c.clone();
    let cases = [
        (FlightMode::Offboard, "Offboard denied: no offboard setpoints"),
        (FlightMode::Mission, "Mission denied: no mission"),
        (FlightMode::ReturnToLaunch, "RTL denied: landed"),
    ];
    for (mode, text) in cases {
        let err = c.request(sim.now_us, sim.facts, Request::SetMode(mode)).unwrap_err();
        assert_eq!(err.to_string(), text);
        assert!(text.len() <= 50);
        assert_eq!(c, before);
    }
    assert!(c.request(sim.now_us, sim.facts, Request::ReturnToLaunch).is_err());

    // The manual modes fly the sticks: refused without them, in words, changing nothing.
    let err = c.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::Position)).unwrap_err();
    assert_eq!(err.to_string(), "Position denied: no manual control");
    assert_eq!(c, before);
    let sticks = Facts { manual_fresh: true, ..sim.facts };
    c.request(sim.now_us, sticks, Request::SetMode(FlightMode::Position)).expect("POSCTL on the ground");
    assert_eq!((c.state(), c.mode()), (State::Manual, FlightMode::Position));
    c.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::Takeoff)).expect("AUTO TAKEOFF");
    assert_eq!((c.state(), c.mode()), (State::Takeoff, AUTO_TAKEOFF));
    sim.run(&mut c, 60);
    c.request(sim.now_us, sticks, Request::SetMode(FlightMode::Altitude)).expect("ALTCTL during takeoff");
    assert_eq!((c.state(), c.mode()), (State::Manual, FlightMode::Altitude));
    assert_eq!(c.intent(), Intent::Manual(ManualMode::Altitude), "the pilot flies from where it is");
    c.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::Hold)).expect("AUTO LOITER");
    assert_eq!((c.state(), c.mode()), (State::Hold, AUTO_LOITER));
    c.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::Land)).expect("AUTO LAND");
    assert_eq!((c.state(), c.mode()), (State::Land, AUTO_LAND));
    c.request(sim.now_us, sim.facts, Request::Hold).expect("hold aborts the landing");
    assert_eq!((c.state(), c.mode()), (State::Hold, AUTO_LOITER));
}

#[test]
fn given_a_disarmed_vehicle_when_asked_to_land_then_refused_and_a_later_hold_cancels_a_pending_takeoff() {
    let mut sim = Sim::new();
    let mut c = commander();
    sim.run(&mut c, 1);
    assert_eq!(c.request(0, Facts::default(), Request::Land).unwrap_err().to_string(), "Land denied: vehicle disarmed");
    c.request(0, Facts::default(), Request::Takeoff { alt_rel_m: Some(3.0) }).expect("takeoff");
    c.request(0, Facts::default(), Request::Hold).expect("hold");
    assert_eq!(c.pending_takeoff_alt_m(), None);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    let outs = sim.run(&mut c, 10);
    assert!(outs.iter().all(|o| o.state == State::ArmedIdle));
}

#[test]
fn given_config_when_serialised_then_round_trips_and_unknown_or_bad_fields_are_refused() {
    let cfg = CommanderConfig::default();
    assert_eq!(cfg.takeoff_alt_m, 2.5);
    assert_eq!(cfg.disarm_land_s, 2.0);
    assert_eq!(cfg.disarm_preflight_s, 10.0);
    assert_eq!(cfg.takeoff_acceptance_m, 0.1);
    let json = serde_json::to_string(&cfg).expect("serialise");
    assert_eq!(serde_json::from_str::<CommanderConfig>(&json).expect("parse"), cfg);
    assert_eq!(serde_json::from_str::<CommanderConfig>("{}").expect("defaults"), cfg);
    assert!(serde_json::from_str::<CommanderConfig>(r#"{"takeof_alt_m": 3}"#).is_err());
    let bad = CommanderConfig { takeoff_acceptance_m: 0.0, ..cfg };
    assert_eq!(Commander::new(bad).unwrap_err().field, "takeoff_acceptance_m");
}

#[test]
fn given_the_preflight_delay_disabled_when_armed_long_then_stays_armed() {
    let mut sim = Sim::new();
    let mut c = Commander::new(CommanderConfig { disarm_preflight_s: -1.0, ..CommanderConfig::default() }).unwrap();
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).unwrap();
    assert!(sim.run(&mut c, 2000).iter().all(|o| o.armed));
}

/// Arm, take off, hold 20 s, land, auto-disarm on simulated time; returns every output.
fn whole_flight() -> (Vec<CommanderOutput>, Sim) {
    let mut sim = Sim::new();
    let mut c = commander();
    let mut outs = sim.run(&mut c, 100);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    outs.extend(sim.run(&mut c, 100));
    c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: None }).expect("takeoff");
    outs.extend(sim.run_until(&mut c, 20.0, |o| o.events.contains(&Event::TakeoffComplete)));
    outs.extend(sim.run(&mut c, 2000));
    c.request(sim.now_us, sim.facts, Request::Land).expect("land");
    outs.extend(sim.run_until(&mut c, 30.0, |o| !o.armed));
    (outs, sim)
}

#[test]
fn given_a_whole_flight_on_simulated_time_then_it_arms_climbs_holds_lands_and_disarms_in_order() {
    let (outs, sim) = whole_flight();
    let events: Vec<Event> = outs.iter().flat_map(|o| o.events.iter().copied()).collect();
    assert_eq!(
        events,
        vec![
            Event::Armed { forced: false },
            Event::ModeChanged { mode: FlightMode::Takeoff },
            Event::TakeoffComplete,
            Event::ModeChanged { mode: FlightMode::Hold },
            Event::ModeChanged { mode: FlightMode::Land },
            Event::Landed,
            Event::Disarmed { reason: DisarmReason::AutoLanded },
            Event::ModeChanged { mode: FlightMode::Hold },
        ]
    );
    assert_eq!(sim.pos_d_m, 0.0);
    let hold: Vec<&CommanderOutput> = outs.iter().filter(|o| o.state == State::Hold).collect();
    assert!(hold.len() >= 2000, "held 20 s: {} steps", hold.len());
    let states: Vec<State> = outs.iter().map(|o| o.state).fold(Vec::new(), |mut v, s| {
        if v.last() != Some(&s) {
            v.push(s);
        }
        v
    });
    assert_eq!(states, [State::Disarmed, State::ArmedIdle, State::Takeoff, State::Hold, State::Land, State::Disarmed]);
    let landed_states: Vec<LandedState> = outs.iter().map(|o| o.landed).fold(Vec::new(), |mut v, s| {
        if v.last() != Some(&s) {
            v.push(s);
        }
        v
    });
    assert_eq!(
        landed_states,
        [LandedState::OnGround, LandedState::Takeoff, LandedState::InAir, LandedState::Landing, LandedState::OnGround]
    );
    let t_s = sim.now_us as f64 * 1e-6;
    assert!(t_s > 26.0 && t_s < 40.0, "flight took {t_s} s");
}

#[test]
fn given_the_same_inputs_when_run_twice_then_the_outputs_are_identical() {
    let (a, sa) = whole_flight();
    let (b, sb) = whole_flight();
    assert_eq!(a, b);
    assert_eq!(sa.now_us, sb.now_us);
}

#[test]
fn given_a_mission_asked_for_while_disarmed_when_armed_then_it_starts_and_without_one_it_is_refused() {
    let mut sim = Sim::new();
    let mut c = commander();
    sim.run(&mut c, 1);
    let err = c.request(sim.now_us, sim.facts, Request::Mission).unwrap_err();
    assert_eq!(err.to_string(), "Mission denied: no mission");
    sim.facts.mission_valid = true;
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Mission).expect("pending mission");
    assert_eq!((c.state(), c.mode()), (State::Disarmed, FlightMode::Mission));
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    let outs = sim.run(&mut c, 2);
    assert_eq!(outs[1].state, State::Mission);
    assert_eq!(outs[1].intent, Intent::Auto(AutoMode::Mission));
    assert!(outs[1].armed, "armed");
}

#[test]
fn given_a_mission_when_done_in_the_air_then_hold_and_when_it_lands_then_disarm_after_com_disarm_land() {
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    sim.facts.mission_valid = true;
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Mission).expect("mission from hold");
    sim.run(&mut c, 5);
    assert_eq!(c.state(), State::Mission);
    c.on_progress(Progress::MissionDone(true));
    let out = sim.run(&mut c, 2).pop().expect("outputs");
    assert_eq!((out.state, out.mode), (State::Hold, AUTO_LOITER));
    c.on_progress(Progress::MissionDone(false));
    c.request(sim.now_us, sim.facts, Request::Mission).expect("again");
    sim.landing = true;
    c.on_progress(Progress::Landing(true));
    let outs = sim.run_until(&mut c, 30.0, |o| o.state == State::Disarmed);
    let landed_at = outs.iter().position(|o| o.events.contains(&Event::Landed)).expect("touchdown");
    let disarmed_after_s = (outs.len() - 1 - landed_at) as f64 * STEP_US as f64 * 1e-6;
    assert!((disarmed_after_s - 2.0).abs() < 0.05, "{disarmed_after_s} s after touchdown");
    assert!(outs.last().expect("out").events.contains(&Event::Disarmed { reason: DisarmReason::AutoLanded }));
}

#[test]
fn given_return_to_launch_then_refused_landed_accepted_in_the_air_and_interrupted_by_hold() {
    let mut sim = Sim::new();
    let mut c = armed_on_ground(&mut sim);
    assert_eq!(
        c.request(sim.now_us, sim.facts, Request::ReturnToLaunch).unwrap_err().to_string(),
        "RTL denied: landed"
    );
    let mut c2 = holding(&mut sim);
    c2.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::ReturnToLaunch)).expect("RTL mode");
    assert_eq!((c2.state(), c2.mode()), (State::Rtl, FlightMode::ReturnToLaunch));
    assert_eq!(c2.intent(), Intent::Auto(AutoMode::ReturnToLaunch));
    c2.request(sim.now_us, sim.facts, Request::Hold).expect("pause");
    assert_eq!(c2.state(), State::Hold);
    c.request(sim.now_us, sim.facts, Request::Disarm { force: false }).expect("disarm on the ground");
}

#[test]
fn given_offboard_then_only_with_fresh_setpoints_and_back_to_hold_when_they_stop() {
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    let before = c.clone();
    let err = c.request(sim.now_us, sim.facts, Request::Offboard).unwrap_err();
    assert_eq!(err.to_string(), "Offboard denied: no offboard setpoints");
    assert_eq!(c, before);
    sim.facts.offboard_fresh = true;
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::SetMode(FlightMode::Offboard)).expect("offboard");
    assert_eq!((c.state(), c.mode()), (State::Offboard, FlightMode::Offboard));
    sim.run(&mut c, 10);
    assert_eq!(c.state(), State::Offboard);
    sim.facts.offboard_fresh = false;
    let out = sim.run(&mut c, 1).pop().expect("out");
    assert_eq!((out.state, out.mode), (State::Hold, AUTO_LOITER));
}

#[test]
fn given_a_reposition_then_hold_at_the_new_point_in_the_air_only() {
    let mut sim = Sim::new();
    let mut ground = armed_on_ground(&mut sim);
    let target = Vector3::new(5.0, 6.0, -3.0);
    let err =
        ground.request(sim.now_us, sim.facts, Request::Goto { pos_ned_m: Some(target), yaw_rad: None }).unwrap_err();
    assert_eq!(err.to_string(), "Reposition denied: landed");
    let mut c = holding(&mut sim);
    c.request(sim.now_us, sim.facts, Request::Goto { pos_ned_m: Some(target), yaw_rad: Some(1.0) }).expect("goto");
    assert_eq!(c.intent(), Intent::Hold { at: HoldAt::Point(target), yaw_rad: Some(1.0) });
    // QGroundControl's pause: no point, hold where it is.
    sim.facts.mission_valid = true;
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Mission).expect("mission");
    c.request(sim.now_us, sim.facts, Request::Goto { pos_ned_m: None, yaw_rad: None }).expect("pause");
    assert_eq!(c.state(), State::Hold);
}

#[test]
fn given_a_converged_global_position_then_home_is_set_on_the_ground_moved_at_arming_and_set_on_request() {
    // GIVEN no converged estimate: no home.
    let mut sim = Sim::new();
    sim.converged = false;
    let mut c = commander();
    sim.run(&mut c, 5);
    assert_eq!(c.home_ned_m(), None);
    // WHEN it converges on the ground THEN home is where the vehicle stands (before arming, as PX4).
    sim.converged = true;
    sim.run(&mut c, 1);
    assert_eq!(c.home_ned_m(), Some(Vector3::new(1.0, -2.0, 0.0)));
    // WHEN it arms somewhere else (the estimate drifted) THEN home moves there.
    sim.pos_d_m = -0.01;
    sim.run(&mut c, 1);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    assert_eq!(c.home_ned_m(), Some(Vector3::new(1.0, -2.0, -0.01)));
    // WHEN DO_SET_HOME names a point THEN home is there; a non-finite one is refused, home unchanged.
    let there = Vector3::new(5.0, 6.0, -1.0);
    c.request(sim.now_us, sim.facts, Request::SetHome { pos_ned_m: Some(there) }).expect("set home");
    assert_eq!(c.home_ned_m(), Some(there));
    let err = c.request(sim.now_us, sim.facts, Request::SetHome { pos_ned_m: Some(Vector3::new(f64::NAN, 0.0, 0.0)) });
    assert_eq!(err.unwrap_err().to_string(), "Set home: no position");
    assert_eq!(c.home_ned_m(), Some(there));
}

fn texts(outs: &[CommanderOutput]) -> Vec<String> {
    outs.iter().flat_map(|o| o.events.iter().map(Event::text)).collect()
}

#[test]
fn given_a_low_pack_on_the_ground_then_arming_is_refused_with_the_charge_unless_forced() {
    let mut sim = Sim::new();
    sim.battery_remaining = Some(0.12);
    let mut c = commander();
    sim.run(&mut c, 1);
    let refusal = c.request(sim.now_us, sim.facts, Request::Arm { force: false }).unwrap_err();
    assert_eq!(refusal.to_string(), "Arming denied: battery 12% below 15%");
    assert_eq!(c.state(), State::Disarmed);
    c.request(sim.now_us, sim.facts, Request::Arm { force: true }).expect("a forced arm skips the check, as PX4's");
}

#[test]
fn given_com_low_bat_act_3_when_the_pack_drains_in_the_air_then_warn_return_then_land_in_order() {
    // GIVEN holding in the air on a full pack.
    let mut sim = Sim::new();
    sim.battery_remaining = Some(0.9);
    let mut c = holding(&mut sim);
    // WHEN it falls below 15 %: a warning, the mode stays.
    sim.battery_remaining = Some(0.14);
    let outs = sim.run(&mut c, 2);
    assert_eq!(texts(&outs), ["Battery low: 14% remaining"]);
    assert_eq!(c.state(), State::Hold);
    // A pack that reads fuller again (less load) does not clear it in the air.
    sim.battery_remaining = Some(0.2);
    assert!(texts(&sim.run(&mut c, 2)).is_empty());
    // Below 7 %: return.
    sim.battery_remaining = Some(0.06);
    let outs = sim.run(&mut c, 2);
    assert_eq!(texts(&outs), ["Failsafe: battery critical (6%), returning", "Mode: Return"]);
    assert_eq!(c.state(), State::Rtl);
    // Below 5 %: land where it is.
    sim.battery_remaining = Some(0.04);
    let outs = sim.run(&mut c, 2);
    assert_eq!(texts(&outs), ["Failsafe: battery emergency (4%), landing", "Mode: Land"]);
    assert_eq!(c.state(), State::Land);
    assert_eq!(outs[1].battery.level, BatteryWarning::Emergency);
}

#[test]
fn given_com_low_bat_act_0_then_critical_and_emergency_are_only_said() {
    let mut sim = Sim::new();
    sim.battery_remaining = Some(0.9);
    let mut c = holding(&mut sim);
    let mut config = *c.config();
    config.low_battery_action = 0;
    c.set_config(config).unwrap();
    sim.battery_remaining = Some(0.04);
    let outs = sim.run(&mut c, 2);
    assert_eq!(texts(&outs), ["Failsafe: battery emergency (4%)"]);
    assert_eq!(c.state(), State::Hold);
    config.low_battery_action = 1;
    assert!(c.set_config(config).is_err(), "1 is not one of PX4's COM_LOW_BAT_ACT values");
    config.low_battery_action = 0;
    config.battery.crit_thr = 0.2;
    assert!(c.set_config(config).is_err(), "critical above low");
}

#[test]
fn given_gf_action_hold_when_a_breach_starts_in_the_air_then_hold_once_and_rearm_inside() {
    use crate::core::plan::geofence::Violation;
    let mut sim = Sim::new();
    let mut c = holding(&mut sim);
    let mut config = *c.config();
    config.geofence.action = 3;
    c.set_config(config).unwrap();
    sim.fence_breach = Some(Violation::MaxHorizontal);
    let outs = sim.run(&mut c, 3);
    assert_eq!(texts(&outs), ["Failsafe: fence, beyond GF_MAX_HOR_DIST, returning", "Mode: Return"]);
    // Back inside, then out again: acted on again.
    c.request(sim.now_us, sim.facts, Request::Hold).unwrap();
    sim.fence_breach = None;
    sim.run(&mut c, 1);
    sim.fence_breach = Some(Violation::InsideExclusion);
    let outs = sim.run(&mut c, 1);
    assert_eq!(texts(&outs), ["Failsafe: fence, in an exclusion zone, returning", "Mode: Return"]);
    config.geofence.action = 6;
    assert!(c.set_config(config).is_err());
}

#[test]
fn given_manual_control_already_lost_at_arming_then_its_loss_is_not_a_failsafe_until_it_returns_and_stops_again() {
    let mut sim = Sim::new();
    let mut c = commander();
    // The sticks came once (a script's one MANUAL_CONTROL), then stopped before arming.
    sim.facts.manual_fresh = true;
    sim.run(&mut c, 5);
    sim.facts.manual_fresh = false;
    sim.run(&mut c, 5);
    c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
    c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: None }).expect("takeoff");
    let outs = sim.run_until(&mut c, 20.0, |o| o.state == State::Hold);
    let failsafe = |outs: &[CommanderOutput]| {
        outs.iter()
            .flat_map(|o| &o.events)
            .any(|e| matches!(e, Event::Failsafe { trigger: Trigger::ManualControlLost, .. }))
    };
    assert!(!failsafe(&outs), "a loss that was there at arming is no failsafe");
    // They come back (nothing to say: no loss was announced), and stop again in the air: now it is one,
    // PX4's NAV_RCL_ACT (return).
    sim.facts.manual_fresh = true;
    let outs = sim.run(&mut c, 5);
    assert!(!outs.iter().flat_map(|o| &o.events).any(|e| e.text() == "Manual control regained"));
    sim.facts.manual_fresh = false;
    let outs = sim.run(&mut c, 5);
    assert!(failsafe(&outs));
    assert_eq!(c.state(), State::Rtl);
    assert!(outs.iter().flat_map(|o| &o.events).any(|e| e.text() == "Failsafe: manual control lost, returning"));
}

#[test]
fn given_com_rcl_except_hold_when_the_sticks_stop_in_a_takeoff_then_it_goes_on_and_without_it_returns() {
    for (except, want) in [(2, State::Takeoff), (0, State::Rtl)] {
        let mut sim = Sim::new();
        let mut c = Commander::new(CommanderConfig { rc_loss_except: except, ..CommanderConfig::default() }).unwrap();
        sim.facts.manual_fresh = true;
        sim.run(&mut c, 1);
        c.request(sim.now_us, sim.facts, Request::Arm { force: false }).expect("arm");
        c.request(sim.now_us, sim.facts, Request::Takeoff { alt_rel_m: None }).expect("takeoff");
        sim.run(&mut c, 100);
        sim.facts.manual_fresh = false;
        sim.run(&mut c, 2);
        assert_eq!(c.state(), want, "COM_RCL_EXCEPT {except}");
    }
}
