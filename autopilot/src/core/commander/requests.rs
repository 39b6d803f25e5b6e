//! The commander's answers to a ground station's requests: each [`Request`] checked against the state,
//! the kill switch and what the vehicle knows (`facts`), then run as a transition of the state machine
//! with the flight mode alongside, or refused with a [`Refusal`] that says why.

use super::{Action, Commander, Conditions, Event, FlightMode, Refusal, Request, State, state_machine};
use crate::core::battery::BatteryWarning;
use crate::core::intent::HoldAt;

impl Commander {
    pub(super) fn apply(&mut self, now: u64, req: Request) -> Result<(), Refusal> {
        use Conditions as C;
        let state = self.state;
        match req {
            Request::Arm { .. } if self.kill_switch => Err(Refusal::KillSwitch),
            Request::Arm { force } => match state {
                State::Disarmed if self.mode.is_manual() && !self.facts.manual_fresh => {
                    Err(Refusal::NoManualControl(Action::Arm))
                }
                State::Disarmed if !force && self.battery.status(now).level >= BatteryWarning::Low => {
                    let status = self.battery.status(now);
                    Err(Refusal::BatteryLow {
                        remaining_pct: status.remaining_pct().unwrap_or(0),
                        low_pct: (self.config.battery.low_thr * 100.0).round() as u8,
                    })
                }
                State::Disarmed => self.transition(now, C::ARM_REQUESTED.with(C::FORCE, force), Action::Arm),
                State::Killed => Err(Refusal::NotInState { action: Action::Arm, state }),
                _ => Ok(()),
            },
            Request::Disarm { force } => match state {
                State::Disarmed => Ok(()),
                _ => self.transition(now, C::DISARM_REQUESTED.with(C::FORCE, force), Action::Disarm),
            },
            Request::Kill => match state {
                State::Killed => Ok(()),
                _ => self.transition(now, C::KILL, Action::Disarm),
            },
            Request::KillSwitch(on) => {
                self.kill_switch = on;
                match (on, state) {
                    (true, State::Killed) => Ok(()),
                    (true, _) => self.transition(now, C::KILL, Action::Disarm),
                    (false, State::Killed) => {
                        self.events.push(Event::KillSwitchReleased);
                        self.transition(now, C::DISARM_REQUESTED, Action::Disarm)
                    }
                    (false, _) => Ok(()),
                }
            }
            Request::Takeoff { alt_rel_m } => {
                let alt = alt_rel_m.unwrap_or(self.config.takeoff_alt_m);
                if !(alt.is_finite() && alt > 0.0) {
                    return Err(Refusal::InvalidAltitude(alt));
                }
                self.pending_takeoff_alt_m = Some(alt);
                match state {
                    State::Killed => Err(Refusal::NotInState { action: Action::Takeoff, state }),
                    State::Disarmed => {
                        self.pending_mission = false;
                        self.pending_manual = false;
                        self.set_mode(FlightMode::Takeoff);
                        Ok(())
                    }
                    _ => self.transition(now, C::TAKEOFF_REQUESTED, Action::Takeoff),
                }
            }
            Request::Land => match state {
                State::Disarmed | State::Killed => Err(Refusal::NotInState { action: Action::Land, state }),
                State::Land => Ok(()),
                _ => self.transition(now, C::LAND_REQUESTED, Action::Land),
            },
            Request::Hold => self.hold(now),
            Request::SetMode(mode) => match mode {
                FlightMode::Takeoff => self.apply(now, Request::Takeoff { alt_rel_m: None }),
                FlightMode::Land => self.apply(now, Request::Land),
                FlightMode::Mission => self.apply(now, Request::Mission),
                FlightMode::ReturnToLaunch => self.apply(now, Request::ReturnToLaunch),
                FlightMode::Offboard => self.apply(now, Request::Offboard),
                FlightMode::Hold => self.hold(now),
                FlightMode::Manual
                | FlightMode::Stabilized
                | FlightMode::Altitude
                | FlightMode::Position
                | FlightMode::Acro => self.manual(now, mode),
            },
            Request::ReturnToLaunch => match state {
                State::Rtl => Ok(()),
                State::Disarmed | State::ArmedIdle => Err(Refusal::Landed(Action::Return)),
                State::Killed => Err(Refusal::NotInState { action: Action::Return, state }),
                _ => self.transition(now, C::RTL_REQUESTED, Action::Return),
            },
            Request::Mission => match state {
                State::Mission => Ok(()),
                State::Killed => Err(Refusal::NotInState { action: Action::Mission, state }),
                State::Disarmed if !self.facts.mission_valid => Err(Refusal::NoMission(Action::Mission)),
                State::Disarmed => {
                    self.pending_takeoff_alt_m = None;
                    self.pending_manual = false;
                    self.pending_mission = true;
                    self.set_mode(FlightMode::Mission);
                    Ok(())
                }
                _ => self.transition(now, C::MISSION_REQUESTED, Action::Mission),
            },
            Request::Offboard => match state {
                State::Offboard => Ok(()),
                State::Disarmed | State::Killed => Err(Refusal::NotInState { action: Action::Offboard, state }),
                _ => self.transition(now, C::OFFBOARD_REQUESTED, Action::Offboard),
            },
            Request::SetHome { pos_ned_m } => {
                let p = pos_ned_m.unwrap_or(self.est.pos_ned_m);
                if !(p.iter().all(|x| x.is_finite()) && (pos_ned_m.is_some() || self.est_ok)) {
                    return Err(Refusal::NoPosition);
                }
                self.home_ned_m = Some(p);
                Ok(())
            }
            Request::Goto { pos_ned_m, yaw_rad } => {
                if !self.state.is_armed() || self.state == State::ArmedIdle || self.land_detector.landed() {
                    return Err(Refusal::Landed(Action::Reposition));
                }
                if self.state != State::Hold {
                    self.transition(now, C::HOLD_REQUESTED, Action::Reposition)?;
                }
                self.set_mode(FlightMode::Hold);
                // No point (QGroundControl's pause): stop and hold where the vehicle stops.
                self.hold_at =
                    pos_ned_m.filter(|p| p.iter().all(|x| x.is_finite())).map_or(HoldAt::Stop, HoldAt::Point);
                self.hold_yaw_rad = yaw_rad.filter(|y| y.is_finite());
                Ok(())
            }
        }
    }

    /// Hold: a mode change on the ground or in Hold; a Hold where the vehicle is in the air.
    fn hold(&mut self, now: u64) -> Result<(), Refusal> {
        match self.state {
            State::Killed => Err(Refusal::NotInState { action: Action::Hold, state: self.state }),
            State::Disarmed | State::ArmedIdle | State::Hold => {
                self.pending_takeoff_alt_m = None;
                self.pending_mission = false;
                self.pending_manual = false;
                self.set_mode(FlightMode::Hold);
                Ok(())
            }
            State::Takeoff | State::Land | State::Mission | State::Rtl | State::Offboard | State::Manual => {
                self.transition(now, Conditions::HOLD_REQUESTED, Action::Hold)
            }
        }
    }

    /// A manual mode (MANUAL, STABILIZED, ALTCTL, POSCTL): only with fresh manual control; on the ground
    /// it is the mode the vehicle arms in; in the air the pilot takes over where the vehicle is.
    fn manual(&mut self, now: u64, mode: FlightMode) -> Result<(), Refusal> {
        let action = Action::Mode(mode);
        if !self.facts.manual_fresh && self.state != State::Killed {
            return Err(Refusal::NoManualControl(action));
        }
        match self.state {
            State::Killed => Err(Refusal::NotInState { action, state: self.state }),
            State::Disarmed => {
                self.pending_takeoff_alt_m = None;
                self.pending_mission = false;
                self.pending_manual = true;
                self.set_mode(mode);
                Ok(())
            }
            State::Manual => {
                self.set_mode(mode);
                Ok(())
            }
            _ => {
                let attitude_only = mode != FlightMode::Position;
                self.transition(
                    now,
                    Conditions::MANUAL_REQUESTED.with(Conditions::ATTITUDE_ONLY, attitude_only),
                    action,
                )?;
                self.set_mode(mode);
                Ok(())
            }
        }
    }

    /// Runs the table once with the request bits; refuses, in words, when no row fires.
    pub(super) fn transition(&mut self, now: u64, request: Conditions, action: Action) -> Result<(), Refusal> {
        let c = self.conditions(now) | request;
        if let Some(t) = state_machine::fire(self.state, c) {
            self.enter(t.to, c, now);
            return Ok(());
        }
        let blocked = state_machine::blocked_by(self.state, c);
        Err(if blocked.contains(Conditions::ESTIMATOR_OK) {
            Refusal::EstimatorNotConverged(action)
        } else if blocked.contains(Conditions::MISSION_VALID) {
            Refusal::NoMission(action)
        } else if blocked.contains(Conditions::OFFBOARD_OK) {
            Refusal::NoSetpoints(action)
        } else if blocked.contains(Conditions::MANUAL_OK) {
            Refusal::NoManualControl(action)
        } else if blocked.contains(Conditions::LANDED) && action == Action::Return {
            Refusal::Landed(action)
        } else if blocked.contains(Conditions::LANDED) {
            Refusal::InAir(action)
        } else {
            Refusal::NotInState { action, state: self.state }
        })
    }
}
