//! The failsafe table: the conditions under which the vehicle changes mode by itself, the parameter that
//! chooses what it does, and what it says. In: the commander's state and parameters, vehicle time (µs),
//! when a ground station last sent a HEARTBEAT. Out: which failsafes are active, and for a newly active
//! one the action to take; the commander applies it through its transition table and announces it
//! (STATUSTEXT, HEARTBEAT mode). Every timer runs on vehicle time, so a failsafe fires identically at
//! real time (`sitl run`'s default) and at `--speed max` (lockstep, as fast as possible).
//!
//! | trigger | parameters | default | action |
//! |---|---|---|---|
//! | no ground-station HEARTBEAT (`MAV_TYPE_GCS`) for `COM_DL_LOSS_T` s, after one was heard | `COM_DL_LOSS_T`, `NAV_DLL_ACT` | 10 s, 0 (off) | PX4's NAV_DLL_ACT: 1 hold, 2 return, 3 land, 5 terminate |
//! | offboard setpoints older than `COM_OF_LOSS_T` in offboard mode | `COM_OF_LOSS_T` | 0.5 s | hold |
//! | manual control (sticks) older than `COM_RC_LOSS_T`, after it was present (and not already lost when the vehicle armed), unless the mode is exempt by `COM_RCL_EXCEPT` (1 mission, 2 hold and takeoff, 4 offboard; landing and returning are never interrupted) | `COM_RC_LOSS_T`, `NAV_RCL_ACT`, `COM_RCL_EXCEPT` | 0.5 s, 2 (return), 0 | PX4's NAV_RCL_ACT: 1 hold, 2 return, 3 land, 5 terminate (0: only said) |
//! | battery below `BAT_LOW_THR` while armed | `BAT_LOW_THR` | 15 % | warning (and arming refused below it) |
//! | battery below `BAT_CRIT_THR` / `BAT_EMERGEN_THR` while armed | `COM_LOW_BAT_ACT`, thresholds | 3, 7 %, 5 % | PX4's COM_LOW_BAT_ACT: 0 warn, 2 land, 3 return at critical and land at emergency |
//! | geofence breached, or predicted to be before the vehicle can stop, in the air | `GF_ACTION`, `GF_MAX_HOR_DIST`, `GF_MAX_VER_DIST`, the uploaded fence | 2, 0 (off), 0 (off) | PX4's GF_ACTION: 0 none, 1 warning, 2 hold, 3 return, 4 terminate, 5 land |
//! | no valid position for `COM_POS_FS_DELAY` in the air, in a mode that flies to positions | `COM_POS_FS_DELAY` | 1 s | land, flown level (PX4's Descend; until then the navigator flies level and holds the height) |
//! | roll beyond `FD_FAIL_R` for `FD_FAIL_R_TTRI`, or pitch beyond `FD_FAIL_P` for `FD_FAIL_P_TTRI`, in the air (`failure_detector`) | those, `FD_ACT` | 60°, 0.3 s, 2 | `FD_ACT`: 0 said only, 1 land, 2 terminate |
//!
//! An action is taken only in the air (armed, not landed); the vehicle stays in the failsafe's mode when
//! the trigger clears (regaining the link is announced), until a pilot changes it, as PX4 does.

use serde::{Deserialize, Serialize};

use super::{Action, Conditions, Event, State};
use crate::core::battery::{BatterySample, BatteryWarning};
use crate::core::plan::geofence::Violation;
use crate::core::seconds_to_us;

/// What a failsafe makes the vehicle do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FailsafeAction {
    /// Stop and hold where the vehicle stops.
    Hold,
    /// Return to launch and land.
    Return,
    /// Land where it is.
    Land,
    /// Stop the motors (flight termination).
    Terminate,
    /// The pilot keeps flying, in Altitude mode (a position loss in Position mode).
    Altitude,
}

impl FailsafeAction {
    /// PX4's encoding of `NAV_DLL_ACT` (and its siblings): 0 disabled (`Ok(None)`), 1 hold, 2 return,
    /// 3 land, 5 terminate; anything else is not an action (`Err`).
    ///
    /// # Errors
    /// For a number that is not one of those.
    pub const fn from_px4(n: u32) -> Result<Option<Self>, u32> {
        match n {
            0 => Ok(None),
            1 => Ok(Some(Self::Hold)),
            2 => Ok(Some(Self::Return)),
            3 => Ok(Some(Self::Land)),
            5 => Ok(Some(Self::Terminate)),
            other => Err(other),
        }
    }

    /// What the vehicle does, for the announcement.
    #[must_use]
    pub const fn doing(self) -> &'static str {
        match self {
            Self::Hold => "holding",
            Self::Return => "returning",
            Self::Land => "landing",
            Self::Terminate => "terminating",
            Self::Altitude => "altitude mode",
        }
    }
}

/// PX4's `COM_LOW_BAT_ACT` at battery `level`: 0 warn only (`Ok(None)`), 2 land at critical and
/// emergency, 3 return at critical and land at emergency; nothing below critical.
///
/// # Errors
/// `Err(n)` for a number that is not one of 0, 2, 3.
pub const fn low_battery_action(n: u32, level: BatteryWarning) -> Result<Option<FailsafeAction>, u32> {
    let critical = matches!(level, BatteryWarning::Critical);
    let emergency = matches!(level, BatteryWarning::Emergency);
    match n {
        0 => Ok(None),
        2 if critical || emergency => Ok(Some(FailsafeAction::Land)),
        3 if critical => Ok(Some(FailsafeAction::Return)),
        3 if emergency => Ok(Some(FailsafeAction::Land)),
        2 | 3 => Ok(None),
        other => Err(other),
    }
}

/// `FD_ACT`, what the attitude failure detector makes the vehicle do: 0 only said (`Ok(None)`), 1 land,
/// 2 terminate.
///
/// # Errors
/// `Err(n)` for any other number.
pub const fn attitude_failure_action(n: u32) -> Result<Option<FailsafeAction>, u32> {
    match n {
        0 => Ok(None),
        1 => Ok(Some(FailsafeAction::Land)),
        2 => Ok(Some(FailsafeAction::Terminate)),
        other => Err(other),
    }
}

/// PX4's `GF_ACTION`: 0 none (`Ok(None)`: not even said), 1 warning (`Ok(Some(None))`: said only), 2 hold,
/// 3 return, 4 terminate, 5 land.
///
/// # Errors
/// `Err(n)` for any other number.
pub const fn geofence_action(n: u32) -> Result<Option<Option<FailsafeAction>>, u32> {
    match n {
        0 => Ok(None),
        1 => Ok(Some(None)),
        2 => Ok(Some(Some(FailsafeAction::Hold))),
        3 => Ok(Some(Some(FailsafeAction::Return))),
        4 => Ok(Some(Some(FailsafeAction::Terminate))),
        5 => Ok(Some(Some(FailsafeAction::Land))),
        other => Err(other),
    }
}

/// What set a failsafe off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Trigger {
    /// No ground-station HEARTBEAT for `COM_DL_LOSS_T`.
    DatalinkLost,
    /// Offboard setpoints stopped in offboard mode.
    OffboardLost,
    /// The battery fell below BAT_CRIT_THR or BAT_EMERGEN_THR (with the state of charge, %).
    Battery { level: BatteryWarning, remaining_pct: u8 },
    /// The geofence is breached, or would be before the vehicle could stop.
    Geofence(Violation),
    /// The pilot's manual control (radio or joystick) stopped for COM_RC_LOSS_T.
    ManualControlLost,
    /// The estimate has had no valid position for COM_POS_FS_DELAY in a mode that needs one.
    PositionLost,
    /// The attitude failure detector: roll or pitch (deg, as estimated when it fired) beyond FD_FAIL_R /
    /// FD_FAIL_P for their trigger times.
    AttitudeFailure { roll_deg: i16, pitch_deg: i16 },
}

impl Trigger {
    /// The condition, for the announcement.
    #[must_use]
    pub fn what(self) -> String {
        match self {
            Self::DatalinkLost => "GCS link lost".into(),
            Self::OffboardLost => "offboard setpoints lost".into(),
            Self::Battery { level, remaining_pct } => format!("battery {} ({remaining_pct}%)", level.word()),
            Self::Geofence(v) => format!("fence, {v}"),
            Self::ManualControlLost => "manual control lost".into(),
            Self::PositionLost => "position lost".into(),
            // The axis beyond its threshold (the larger angle), so the text fits a STATUSTEXT.
            Self::AttitudeFailure { roll_deg, pitch_deg } if roll_deg.unsigned_abs() >= pitch_deg.unsigned_abs() => {
                format!("attitude roll {roll_deg} deg")
            }
            Self::AttitudeFailure { pitch_deg, .. } => format!("attitude pitch {pitch_deg} deg"),
        }
    }
}

/// Whether the ground-station link is lost at `now_us`: a GCS HEARTBEAT was heard (`last_us`) and none for
/// more than `timeout_s` since. Never lost before the first one (nothing to lose yet).
#[must_use]
pub fn datalink_lost(now_us: u64, last_us: Option<u64>, timeout_s: f64) -> bool {
    last_us.is_some_and(|t| now_us.saturating_sub(t) > seconds_to_us(timeout_s))
}

/// The failsafe rows applied by the commander: each watches its condition every step and, when it starts
/// while armed, says so and takes its action in the air.
impl super::Commander {
    /// The datalink row of the failsafe table ([`failsafe`]): on losing the link while armed, say so and,
    /// in the air, take `NAV_DLL_ACT`'s action; on regaining it, say so (the mode stays).
    pub(super) fn datalink_failsafe(&mut self, now: u64, gcs_heartbeat_us: Option<u64>) {
        let lost = datalink_lost(now, gcs_heartbeat_us, self.config.datalink_loss_s);
        if lost == self.datalink_lost {
            return;
        }
        self.datalink_lost = lost;
        if !self.state.is_armed() {
            return;
        }
        let trigger = Trigger::DatalinkLost;
        if !lost {
            self.events.push(Event::FailsafeCleared { trigger });
            return;
        }
        let action = FailsafeAction::from_px4(self.config.datalink_loss_action).ok().flatten();
        self.fail(now, trigger, action);
    }

    /// The manual-control row: manual control that was present stops (the vehicle's facts say it is no
    /// longer fresh) while armed: said, and in the air `NAV_RCL_ACT`'s action, unless the mode is exempt
    /// (`COM_RCL_EXCEPT`; a landing or return is never interrupted); regaining it is said.
    pub(super) fn manual_failsafe(&mut self, now: u64) {
        let fresh = self.facts.manual_fresh;
        self.manual_seen |= fresh;
        // Armed without manual control (a script that never sent any since): nothing to lose until it
        // comes back, as PX4 ignores a loss that was already there at arming.
        if fresh || !self.state.is_armed() {
            self.manual_lost_at_arming = self.state == State::Disarmed && !fresh;
        }
        let lost = self.manual_seen && !fresh && !self.manual_lost_at_arming;
        if lost == self.manual_lost {
            return;
        }
        self.manual_lost = lost;
        if !self.state.is_armed() {
            return;
        }
        let trigger = Trigger::ManualControlLost;
        if !lost {
            self.events.push(Event::FailsafeCleared { trigger });
            return;
        }
        let except = self.config.rc_loss_except;
        let exempt = match self.state {
            State::Mission => except & 1 != 0,
            // PX4 exempts a takeoff with the hold bit too.
            State::Hold | State::Takeoff => except & 2 != 0,
            State::Offboard => except & 4 != 0,
            State::Land | State::Rtl => true,
            _ => false,
        };
        let action = FailsafeAction::from_px4(self.config.rc_loss_action).ok().flatten().filter(|_| !exempt);
        self.fail(now, trigger, action);
    }

    /// The battery rows of the failsafe table: the monitor takes the reading; a level that rose while
    /// armed is said (low) or acted on (critical, emergency: COM_LOW_BAT_ACT).
    pub(super) fn battery_failsafe(&mut self, now: u64, sample: Option<BatterySample>) {
        let before = self.battery.status(now).level;
        self.battery.update(now, sample, self.state.is_armed());
        let status = self.battery.status(now);
        if status.level <= before || !self.state.is_armed() {
            return;
        }
        let remaining_pct = status.remaining_pct().unwrap_or(0);
        if status.level == BatteryWarning::Low {
            self.events.push(Event::BatteryLow { remaining_pct });
            return;
        }
        let trigger = Trigger::Battery { level: status.level, remaining_pct };
        let action = low_battery_action(self.config.low_battery_action, status.level).ok().flatten();
        self.fail(now, trigger, action);
    }

    /// The geofence row: a breach (or a predicted one) that starts while armed in the air is acted on per
    /// GF_ACTION (0: not even said); it re-arms once the vehicle is inside again.
    pub(super) fn geofence_failsafe(&mut self, now: u64, breach: Option<Violation>) {
        let in_air = self.state.is_armed() && self.state != State::ArmedIdle && !self.land_detector.landed();
        let breached = breach.is_some() && in_air;
        if breached == self.fence_breached {
            return;
        }
        self.fence_breached = breached;
        let (Some(violation), true) = (breach, breached) else { return };
        if let Ok(Some(action)) = geofence_action(self.config.geofence.action) {
            self.fail(now, Trigger::Geofence(violation), action);
        }
    }

    /// The position row: in the air, in a mode that flies to positions (hold, takeoff, mission, return,
    /// offboard, Position by hand), the estimate without a valid position for `COM_POS_FS_DELAY`: land
    /// where it is, flown level without a position (PX4's Descend); a landing or an attitude mode (the pilot's
    /// Stabilized or Altitude) needs no position and is left alone. Regaining the position is said; the
    /// vehicle keeps landing.
    pub(super) fn position_failsafe(&mut self, now: u64) {
        let in_air = self.state.is_armed() && self.state != State::ArmedIdle && !self.land_detector.landed();
        let needs_position = match self.state {
            State::Hold | State::Takeoff | State::Mission | State::Rtl | State::Offboard => true,
            State::Manual => self.mode == super::FlightMode::Position,
            _ => false,
        };
        let invalid = !self.est.position_valid;
        self.position_invalid_since_us =
            if invalid && in_air { Some(self.position_invalid_since_us.unwrap_or(now)) } else { None };
        let delay_over = self
            .position_invalid_since_us
            .is_some_and(|t| now.saturating_sub(t) >= seconds_to_us(self.config.position_loss_delay_s));
        if self.position_lost {
            if !invalid {
                self.position_lost = false;
                self.events.push(Event::FailsafeCleared { trigger: Trigger::PositionLost });
            }
            return;
        }
        if delay_over && needs_position {
            self.position_lost = true;
            // A pilot flying Position with fresh sticks keeps flying, in Altitude (PX4's COM_POSCTL_NAVL 0).
            let pilot = self.state == State::Manual && self.facts.manual_fresh;
            let action = if pilot { FailsafeAction::Altitude } else { FailsafeAction::Land };
            self.fail(now, Trigger::PositionLost, Some(action));
        }
    }

    /// The attitude row: in the air, the failure detector (FD_FAIL_R/P for FD_FAIL_R/P_TTRI) fires:
    /// FD_ACT's action (terminate by default), said with the angles; once per flight (it re-arms on the
    /// ground).
    pub(super) fn attitude_failsafe(&mut self, now: u64, roll_rad: f64, pitch_rad: f64) {
        let in_air = self.state.is_armed() && self.state != State::ArmedIdle && !self.land_detector.landed();
        if !in_air {
            self.failure_detector.reset();
            self.attitude_failed = false;
            return;
        }
        let failed = self.failure_detector.update(now, roll_rad, pitch_rad, &self.config.failure_detector);
        if !failed || self.attitude_failed {
            return;
        }
        self.attitude_failed = true;
        let deg = |a: f64| if a.is_finite() { a.to_degrees().round() as i16 } else { i16::MAX };
        let trigger = Trigger::AttitudeFailure { roll_deg: deg(roll_rad), pitch_deg: deg(pitch_rad) };
        let action = attitude_failure_action(self.config.failure_detector.action).ok().flatten();
        self.fail(now, trigger, action);
    }

    /// A failsafe fired: take `action` if the vehicle is in the air, and say so (what happened and what
    /// the vehicle does, or only what happened).
    fn fail(&mut self, now: u64, trigger: Trigger, action: Option<FailsafeAction>) {
        let in_air = self.state != State::ArmedIdle && self.state != State::Killed && !self.land_detector.landed();
        let Some(action) = action.filter(|_| in_air) else {
            self.events.push(Event::Failsafe { trigger, action: None });
            return;
        };
        self.events.push(Event::Failsafe { trigger, action: Some(action) });
        let (request, what) = match action {
            FailsafeAction::Hold => (Conditions::HOLD_REQUESTED, Action::Hold),
            FailsafeAction::Return => (Conditions::RTL_REQUESTED, Action::Return),
            FailsafeAction::Land => (Conditions::LAND_REQUESTED, Action::Land),
            FailsafeAction::Terminate => (Conditions::KILL, Action::Disarm),
            // The pilot stays in control (the Manual state): only the mode changes.
            FailsafeAction::Altitude => {
                self.set_mode(super::FlightMode::Altitude);
                return;
            }
        };
        // Already in that mode (holding, returning, landing): nothing to change.
        let _ = self.transition(now, request, what);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_px4_numbers_then_actions_and_the_gap_at_4_is_refused() {
        assert_eq!(FailsafeAction::from_px4(0), Ok(None));
        assert_eq!(FailsafeAction::from_px4(2), Ok(Some(FailsafeAction::Return)));
        assert_eq!(FailsafeAction::from_px4(5), Ok(Some(FailsafeAction::Terminate)));
        assert_eq!(FailsafeAction::from_px4(4), Err(4));
        assert_eq!(FailsafeAction::from_px4(6), Err(6));
    }

    #[test]
    fn given_com_low_bat_act_then_px4s_actions_per_level() {
        use BatteryWarning as W;
        assert_eq!(low_battery_action(0, W::Emergency), Ok(None));
        assert_eq!(low_battery_action(2, W::Critical), Ok(Some(FailsafeAction::Land)));
        assert_eq!(low_battery_action(3, W::Critical), Ok(Some(FailsafeAction::Return)));
        assert_eq!(low_battery_action(3, W::Emergency), Ok(Some(FailsafeAction::Land)));
        assert_eq!(low_battery_action(3, W::Low), Ok(None));
        assert_eq!(low_battery_action(1, W::Critical), Err(1));
    }

    #[test]
    fn given_heartbeats_then_lost_only_after_one_was_heard_and_the_timeout_passed() {
        assert!(!datalink_lost(100_000_000, None, 10.0), "never heard: nothing to lose");
        assert!(!datalink_lost(10_000_000, Some(0), 10.0));
        assert!(datalink_lost(10_000_001, Some(0), 10.0));
    }
}
