//! The commander: arming, flight modes and landing detection. In, once per control step (any rate, ~50-250
//! Hz): [`CommanderInputs`] (vehicle time `now_us` in µs, the estimate in NED m and m/s with its health
//! flags, whether the thrust is at its minimum, the vehicle's [`Facts`]: a mission to fly, offboard
//! setpoints flowing). In, as they happen: the navigator's [`Progress`] (mission done, an automatic landing).
//! In, whenever a ground station asks: a [`Request`] (arm, disarm, kill, takeoff, land, hold, set mode),
//! answered at once with `Ok` or a [`Refusal`] whose text fits a STATUSTEXT; a refused request changes
//! nothing. Out, per step: a [`CommanderOutput`] with the [`State`], the flight mode, the health and the
//! landed state (their wire numbers are the MAVLink layer's), the [`Intent`] the navigator should fly, and
//! the [`Event`]s since the last step (for an immediate HEARTBEAT and a STATUSTEXT).
//!
//! Decisions are made by the transition table of [`state_machine`] (`next(state, conditions)`); this
//! module computes the conditions, runs entry actions (the takeoff's altitude, where Hold holds, home) and
//! keeps the flight mode alongside the state; `requests` answers a ground station's requests. It owns home; the navigator owns every point flown and the
//! yaw (see `core::intent`). All delays are measured on `now_us`, so they
//! hold at any simulation speed-up. Semantics follow PX4: takeoff may be asked for before arming and starts
//! once armed; takeoff ends in Hold at the takeoff point; a landing disarms `disarm_land_s` after touchdown;
//! an armed vehicle that has not taken off disarms after `disarm_preflight_s`; disarming in the air needs
//! force; kill stops the motors from any state and stays until a disarm.

use nalgebra::Vector3;

mod config;
pub mod failsafe;
pub mod failure_detector;
mod interface;
pub mod land_detector;
pub mod mode;
mod requests;
pub mod state_machine;

#[cfg(test)]
mod tests;

use config::BATTERY_ORDER;
pub use config::{CommanderConfig, ConfigError};
pub use failsafe::{FailsafeAction, Trigger};
pub use interface::{Action, CommanderInputs, CommanderOutput, DisarmReason, Estimate, Event, Facts, Refusal, Request};
pub use land_detector::{LandDetector, LandDetectorConfig, LandedState};
pub use mode::{FlightMode, SystemStatus};
pub use state_machine::{Conditions, State};

use crate::core::battery::BatteryMonitor;
use crate::core::intent::{AutoMode, HoldAt, Intent, ManualMode, Progress};
use failure_detector::FailureDetector;
pub use failure_detector::FailureDetectorConfig;
use land_detector::{LandDetectorSample, Phase};

use crate::core::seconds_to_us;

/// The commander. See the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct Commander {
    config: CommanderConfig,
    state: State,
    mode: FlightMode,
    pending_takeoff_alt_m: Option<f64>,
    /// Mission mode asked for while disarmed: the mission starts on arming.
    pending_mission: bool,
    /// A manual mode asked for while disarmed (the mode shows it): flown once armed.
    pending_manual: bool,
    /// The vehicle left the ground since it was armed (the Manual state's auto-disarm: COM_DISARM_LAND
    /// after a flight, COM_DISARM_PRFLT before one).
    flew: bool,
    /// The radio's kill switch is on: the motors stay stopped and arming is refused until it is off.
    kill_switch: bool,
    /// Manual control was fresh at some point (nothing to lose before), and a loss episode is under way.
    manual_seen: bool,
    manual_lost: bool,
    /// Manual control was not fresh when the vehicle armed: its loss is ignored until it comes back.
    manual_lost_at_arming: bool,
    facts: Facts,
    /// The navigator's progress: the mission flew its last item; an automatic mode descends to land.
    mission_done: bool,
    auto_landing: bool,
    land_detector: LandDetector,
    /// The latest finite estimate.
    est: Estimate,
    est_ok: bool,
    home_ned_m: Option<Vector3<f64>>,
    /// The ground's down coordinate when there is no home: where the vehicle was while disarmed.
    arm_ground_d_m: f64,
    /// The takeoff's altitude above the ground (m) and the down coordinate it reaches (m), as it started.
    takeoff_alt_m: f64,
    takeoff_d_m: f64,
    /// Where Hold holds, and a reposition's yaw (rad; None: keep).
    hold_at: HoldAt,
    hold_yaw_rad: Option<f64>,
    armed_idle_since_us: u64,
    touchdown_us: Option<u64>,
    /// The ground-station link counts as lost (a datalink failsafe episode is under way).
    datalink_lost: bool,
    battery: BatteryMonitor,
    /// A geofence breach episode is under way (the action was taken at its start).
    fence_breached: bool,
    /// Since when the estimate has had no valid position in the air, and whether the position failsafe
    /// has fired for this loss.
    position_invalid_since_us: Option<u64>,
    position_lost: bool,
    /// The attitude failure detector, and whether it fired in this flight.
    failure_detector: FailureDetector,
    attitude_failed: bool,
    events: Vec<Event>,
}

impl Commander {
    /// A disarmed commander in Hold mode, on the ground.
    ///
    /// # Errors
    /// [`ConfigError`] when the configuration is out of range.
    pub fn new(config: CommanderConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            state: State::Disarmed,
            mode: FlightMode::Hold,
            pending_takeoff_alt_m: None,
            pending_mission: false,
            pending_manual: false,
            flew: false,
            kill_switch: false,
            manual_seen: false,
            manual_lost: false,
            manual_lost_at_arming: false,
            facts: Facts::default(),
            mission_done: false,
            auto_landing: false,
            land_detector: LandDetector::new(config.land_detector),
            est: Estimate::default(),
            est_ok: false,
            home_ned_m: None,
            arm_ground_d_m: 0.0,
            takeoff_alt_m: 0.0,
            takeoff_d_m: 0.0,
            hold_at: HoldAt::Stop,
            hold_yaw_rad: None,
            armed_idle_since_us: 0,
            touchdown_us: None,
            datalink_lost: false,
            battery: BatteryMonitor::new(config.battery).map_err(|_| ConfigError {
                field: "battery",
                value: config.battery.low_thr,
                must: BATTERY_ORDER,
            })?,
            fence_breached: false,
            position_invalid_since_us: None,
            position_lost: false,
            failure_detector: FailureDetector::default(),
            attitude_failed: false,
            events: Vec::new(),
        })
    }

    #[must_use]
    pub fn config(&self) -> &CommanderConfig {
        &self.config
    }

    /// New parameters (a PARAM_SET), from the next step: timers, speeds and altitudes; a takeoff or
    /// landing under way keeps the target it latched.
    ///
    /// # Errors
    /// [`ConfigError`] when out of range; nothing changes then.
    pub fn set_config(&mut self, config: CommanderConfig) -> Result<(), ConfigError> {
        config.validate()?;
        if config.land_detector != self.config.land_detector {
            self.land_detector.set_config(config.land_detector);
        }
        // Checked above with the rest.
        let _ = self.battery.set_config(config.battery);
        self.config = config;
        Ok(())
    }

    #[must_use]
    pub fn state(&self) -> State {
        self.state
    }

    #[must_use]
    pub fn mode(&self) -> FlightMode {
        self.mode
    }

    /// Home (NED m): its down coordinate is the ground. None until the first converged global position.
    #[must_use]
    pub fn home_ned_m(&self) -> Option<Vector3<f64>> {
        self.home_ned_m
    }

    /// The altitude (m above home) of a takeoff asked for while disarmed, if any.
    #[must_use]
    pub fn pending_takeoff_alt_m(&self) -> Option<f64> {
        self.pending_takeoff_alt_m
    }

    #[must_use]
    pub fn armed(&self) -> bool {
        self.state.is_armed()
    }

    /// Standby disarmed, Active armed, Critical armed without a usable position, Emergency killed.
    #[must_use]
    pub fn system_status(&self) -> SystemStatus {
        match self.state {
            State::Killed => SystemStatus::Emergency,
            State::Disarmed => SystemStatus::Standby,
            _ if !self.est.position_valid => SystemStatus::Critical,
            _ => SystemStatus::Active,
        }
    }

    /// EXTENDED_SYS_STATE landed_state.
    #[must_use]
    pub fn landed_state(&self) -> LandedState {
        let phase = match self.state {
            State::Takeoff => Phase::Takeoff,
            State::Land => Phase::Landing,
            State::Mission | State::Rtl if self.auto_landing => Phase::Landing,
            _ => Phase::Other,
        };
        if self.state == State::Disarmed { LandedState::OnGround } else { self.land_detector.landed_state(phase) }
    }

    /// What the navigator is to fly.
    #[must_use]
    pub fn intent(&self) -> Intent {
        match self.state {
            State::Disarmed | State::ArmedIdle | State::Killed => Intent::Idle,
            State::Takeoff => Intent::Takeoff { alt_m: self.takeoff_alt_m },
            State::Hold => Intent::Hold { at: self.hold_at, yaw_rad: self.hold_yaw_rad },
            State::Land if self.land_detector.landed() => Intent::Idle,
            State::Land => Intent::Land,
            State::Mission => Intent::Auto(AutoMode::Mission),
            State::Rtl => Intent::Auto(AutoMode::ReturnToLaunch),
            State::Offboard => Intent::Auto(AutoMode::Offboard),
            State::Manual => Intent::Manual(self.mode.manual().unwrap_or(ManualMode::Position)),
        }
    }

    /// Starts armed in Hold above `hold_ned_m` (m, NED; home below it), instead of disarmed on the
    /// ground: for experiments that begin in the air, as the paper's do (`sitl run --scenario`); the
    /// navigator holds the point (its own airborne start). Call before the first step; no Armed event is
    /// raised (there was no arming), the first HEARTBEAT shows it armed.
    pub fn start_airborne(&mut self, hold_ned_m: Vector3<f64>) {
        self.home_ned_m = Some(Vector3::new(hold_ned_m.x, hold_ned_m.y, 0.0));
        self.state = State::Hold;
        self.hold_at = HoldAt::Stop;
        self.set_mode(FlightMode::Hold);
    }

    /// The navigator's progress (events, in order), read by the transitions from the next step or request.
    pub fn on_progress(&mut self, progress: Progress) {
        match progress {
            Progress::MissionDone(done) => self.mission_done = done,
            Progress::Landing(landing) => self.auto_landing = landing,
        }
    }

    /// Handles a request at `now_us`, at once, with what the vehicle knows now (`facts`).
    ///
    /// # Errors
    /// [`Refusal`] saying why; the commander is then exactly as before.
    pub fn request(&mut self, now_us: u64, facts: Facts, req: Request) -> Result<(), Refusal> {
        let mut next = self.clone();
        next.facts = facts;
        next.apply(now_us, req)?;
        *self = next;
        Ok(())
    }

    /// Takes one step's inputs, runs the automatic transitions and returns the outputs.
    pub fn step(&mut self, inputs: &CommanderInputs) -> CommanderOutput {
        let now = inputs.now_us;
        self.take_estimate(inputs);
        let was_landed = self.land_detector.landed();
        let sample = LandDetectorSample {
            vel_ned_mps: self.est.vel_ned_mps,
            pos_d_m: self.est.pos_ned_m.z,
            ground_d_m: Some(self.ground_d_m()),
            throttle_low: inputs.throttle_low,
            armed: self.state != State::Disarmed,
        };
        let landed = self.land_detector.update(now, &sample);
        if landed && !was_landed && self.state != State::Disarmed {
            self.events.push(Event::Landed);
        }
        if !landed && self.state.is_armed() && self.state != State::ArmedIdle {
            self.flew = true;
        }
        let landing = matches!(self.state, State::Land | State::Manual)
            || (matches!(self.state, State::Mission | State::Rtl) && self.auto_landing);
        self.touchdown_us = if landing && landed { Some(self.touchdown_us.unwrap_or(now)) } else { None };
        self.datalink_failsafe(now, inputs.gcs_heartbeat_us);
        self.manual_failsafe(now);
        self.battery_failsafe(now, inputs.battery);
        self.geofence_failsafe(now, inputs.fence_breach);
        self.position_failsafe(now);
        self.attitude_failsafe(now, inputs.estimate.roll_rad, inputs.estimate.pitch_rad);
        // A few rounds at most: arming with a pending takeoff goes ArmedIdle -> Takeoff on the next step.
        for _ in 0..State::ALL.len() {
            let c = self.conditions(now);
            match state_machine::fire(self.state, c) {
                Some(t) if t.to != self.state => self.enter(t.to, c, now),
                _ => break,
            }
        }
        CommanderOutput {
            state: self.state,
            mode: self.mode,
            status: self.system_status(),
            landed: self.landed_state(),
            armed: self.armed(),
            motors_enabled: self.armed(),
            intent: self.intent(),
            battery: self.battery.status(now),
            events: std::mem::take(&mut self.events),
        }
    }

    fn take_estimate(&mut self, inputs: &CommanderInputs) {
        self.facts = inputs.facts;
        let e = &inputs.estimate;
        let finite = e.pos_ned_m.iter().chain(e.vel_ned_mps.iter()).all(|x| x.is_finite());
        if finite {
            self.est.pos_ned_m = e.pos_ned_m;
            self.est.vel_ned_mps = e.vel_ned_mps;
        }
        if e.yaw_rad.is_finite() {
            self.est.yaw_rad = e.yaw_rad;
        }
        self.est.position_valid = e.position_valid && finite;
        self.est.converged = e.converged && finite;
        self.est_ok = self.est.position_valid && self.est.converged;
        if self.state == State::Disarmed {
            self.arm_ground_d_m = self.est.pos_ned_m.z;
            // Home: where the vehicle first has a converged global position on the ground (as PX4: ground
            // stations and MAVSDK want it before arming); arming moves it to where the vehicle arms.
            if self.home_ned_m.is_none() && self.est.converged && e.has_origin {
                self.home_ned_m = Some(self.est.pos_ned_m);
            }
        }
    }

    fn ground_d_m(&self) -> f64 {
        self.home_ned_m.map_or(self.arm_ground_d_m, |h| h.z)
    }

    /// The level conditions at `now_us` (no request bits except a pending takeoff).
    fn conditions(&self, now_us: u64) -> Conditions {
        use Conditions as C;
        let expired = |delay_s: f64, since: Option<u64>| {
            delay_s >= 0.0 && since.is_some_and(|t| now_us.saturating_sub(t) >= seconds_to_us(delay_s))
        };
        let auto_disarm = match self.state {
            State::ArmedIdle => expired(self.config.disarm_preflight_s, Some(self.armed_idle_since_us)),
            State::Land | State::Mission | State::Rtl => expired(self.config.disarm_land_s, self.touchdown_us),
            // Flown by hand: disarmed on the ground after a flight as after a landing, before one as
            // when armed without taking off.
            State::Manual if self.flew => expired(self.config.disarm_land_s, self.touchdown_us),
            State::Manual => expired(self.config.disarm_preflight_s, self.touchdown_us),
            _ => false,
        };
        let alt_reached = self.state == State::Takeoff
            && (self.est.pos_ned_m.z - self.takeoff_d_m).abs() <= self.config.takeoff_acceptance_m;
        C::NONE
            .with(C::TAKEOFF_REQUESTED, self.pending_takeoff_alt_m.is_some())
            .with(C::LANDED, self.land_detector.landed())
            .with(C::TAKEOFF_ALT_REACHED, alt_reached)
            .with(C::ESTIMATOR_OK, self.est_ok)
            .with(C::AUTO_DISARM_EXPIRED, auto_disarm)
            .with(C::MISSION_REQUESTED, self.pending_mission)
            .with(C::MISSION_VALID, self.facts.mission_valid)
            .with(C::MISSION_DONE, self.mission_done)
            .with(C::OFFBOARD_OK, self.facts.offboard_fresh)
            .with(C::OFFBOARD_LOST, !self.facts.offboard_fresh)
            .with(C::AUTO_LANDING, self.auto_landing)
            .with(C::MANUAL_REQUESTED, self.pending_manual)
            .with(C::MANUAL_OK, self.facts.manual_fresh)
            .with(C::ATTITUDE_ONLY, self.pending_manual && self.mode.is_manual() && self.mode != FlightMode::Position)
    }

    fn set_mode(&mut self, mode: FlightMode) {
        if mode != self.mode {
            self.mode = mode;
            self.events.push(Event::ModeChanged { mode });
        }
    }

    /// Entry actions of `to` (also for a row back into the same state: a new takeoff altitude).
    fn enter(&mut self, to: State, c: Conditions, now: u64) {
        use Conditions as C;
        let from = self.state;
        let pos = self.est.pos_ned_m;
        if to != State::ArmedIdle && to != State::Takeoff {
            self.pending_takeoff_alt_m = None;
        }
        if to != State::ArmedIdle {
            self.pending_mission = false;
            self.pending_manual = false;
        }
        self.state = to;
        match to {
            State::Disarmed => {
                let reason = if c.contains(C::DISARM_REQUESTED) {
                    if c.contains(C::FORCE) && !c.contains(C::LANDED) {
                        DisarmReason::Forced
                    } else {
                        DisarmReason::Requested
                    }
                } else if matches!(from, State::Land | State::Mission | State::Rtl)
                    || (from == State::Manual && self.flew)
                {
                    // Flown by hand and landed with the throttle: a landing, as the automatic ones.
                    DisarmReason::AutoLanded
                } else {
                    DisarmReason::AutoPreflight
                };
                self.events.push(Event::Disarmed { reason });
                // A manual mode stays the mode to arm in (as PX4); any other becomes Hold.
                if !self.mode.is_manual() {
                    self.set_mode(FlightMode::Hold);
                }
            }
            State::ArmedIdle => {
                self.armed_idle_since_us = now;
                self.flew = false;
                // Armed in a manual mode: flown by hand from the next step.
                self.pending_manual = self.mode.is_manual();
                self.home_ned_m = Some(pos);
                self.events.push(Event::Armed { forced: c.contains(C::FORCE) });
            }
            State::Takeoff => {
                // The altitude is the commander's (the request's); the navigator latches where it climbs.
                self.takeoff_alt_m = self.pending_takeoff_alt_m.take().unwrap_or(self.config.takeoff_alt_m);
                self.takeoff_d_m = self.ground_d_m() - self.takeoff_alt_m;
                self.set_mode(FlightMode::Takeoff);
            }
            State::Hold => {
                self.hold_yaw_rad = None;
                if from == State::Takeoff && !c.contains(C::HOLD_REQUESTED) {
                    self.hold_at = HoldAt::TakeoffPoint;
                    self.events.push(Event::TakeoffComplete);
                } else {
                    // Stop and hold where the vehicle stops, as PX4's Hold does.
                    self.hold_at = HoldAt::Stop;
                }
                if from == State::Offboard && c.contains(C::OFFBOARD_LOST) && !c.contains(C::HOLD_REQUESTED) {
                    let trigger = Trigger::OffboardLost;
                    self.events.push(Event::Failsafe { trigger, action: Some(FailsafeAction::Hold) });
                }
                self.set_mode(FlightMode::Hold);
            }
            State::Land => {
                self.touchdown_us = self.land_detector.landed().then_some(now);
                self.set_mode(FlightMode::Land);
            }
            State::Killed => {
                if from.is_armed() {
                    self.events.push(Event::Disarmed { reason: DisarmReason::Kill });
                }
                self.events.push(Event::Killed);
            }
            State::Mission => self.set_mode(FlightMode::Mission),
            State::Rtl => self.set_mode(FlightMode::ReturnToLaunch),
            State::Offboard => self.set_mode(FlightMode::Offboard),
            State::Manual => {
                // Entered with the mode already shown (a mode change sets it after the transition).
                self.touchdown_us = self.land_detector.landed().then_some(now);
            }
        }
    }
}
