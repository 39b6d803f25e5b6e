//! What goes into and out of the commander: the estimate and facts of one step, the requests a ground
//! station makes and why one is refused, the events the MAVLink layer reports, and one step's output.

use std::fmt;

use nalgebra::Vector3;
use thiserror::Error;

use super::failsafe::{FailsafeAction, Trigger};
use super::land_detector::LandedState;
use super::mode::{FlightMode, SystemStatus};
use super::state_machine::State;
use crate::core::battery::{BatterySample, BatteryStatus};
use crate::core::intent::Intent;
use crate::core::plan::geofence::Violation;

/// The estimate as the commander needs it (NED about the estimator's origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    /// Roll and pitch (rad, ZYX), for the attitude failure detector.
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
    /// Position (and velocity) usable for control.
    pub position_valid: bool,
    /// The estimator's converged flag: the arming check.
    pub converged: bool,
    /// The estimate has a geodetic origin (a global position): home can be set.
    pub has_origin: bool,
}

impl Default for Estimate {
    fn default() -> Self {
        Self {
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad: 0.0,
            position_valid: false,
            converged: false,
            has_origin: false,
        }
    }
}

/// One step's inputs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CommanderInputs {
    /// Vehicle time (µs).
    pub now_us: u64,
    pub estimate: Estimate,
    /// The controller's collective thrust is at its minimum.
    pub throttle_low: bool,
    /// What the vehicle knows of its plans and setpoint streams now.
    pub facts: Facts,
    /// When a ground station (MAV_TYPE_GCS) last sent a HEARTBEAT (µs of vehicle time).
    pub gcs_heartbeat_us: Option<u64>,
    /// A reading of the pack that arrived this step.
    pub battery: Option<BatterySample>,
    /// The geofence is breached, or will be before the vehicle can stop (see `core::plan::geofence`).
    pub fence_breach: Option<Violation>,
}

/// What the vehicle knows, outside the commander, that the transitions read: whether a mission can be
/// flown (one is loaded and the estimator has a geodetic origin) and whether offboard setpoints flow
/// (one younger than COM_OF_LOSS_T).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Facts {
    pub mission_valid: bool,
    pub offboard_fresh: bool,
    /// The pilot's sticks are fresh (younger than COM_RC_LOSS_T, from the source COM_RC_IN_MODE chooses).
    pub manual_fresh: bool,
}

/// What a ground station (through the MAVLink handlers) asks of the commander.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// ARM_DISARM param1 1; `force` is param2 = 21196.
    Arm { force: bool },
    /// ARM_DISARM param1 0 without the force magic; `force` disarms in the air (for callers other than
    /// ARM_DISARM, which sends param1 0 with force as a [`Request::Kill`]). Also resets a kill.
    Disarm { force: bool },
    /// ARM_DISARM param1 0, param2 21196 (MAVSDK `kill()`): stop the motors now, from any state; stays
    /// killed (arming refused) until a [`Request::Disarm`].
    Kill,
    /// The radio's kill switch moved: on stops the motors at once, from any state, and refuses arming
    /// while on; off ends a kill (disarmed, ready to arm again).
    KillSwitch(bool),
    /// NAV_TAKEOFF, to `alt_rel_m` above home (None: `takeoff_alt_m`). Accepted while disarmed: remembered
    /// and started on arming.
    Takeoff { alt_rel_m: Option<f64> },
    /// NAV_LAND here.
    Land,
    /// Hold here (AUTO LOITER).
    Hold,
    /// DO_SET_MODE / SET_MODE: a mode this vehicle flies (the MAVLink layer decodes and refuses the rest).
    SetMode(FlightMode),
    /// NAV_RETURN_TO_LAUNCH or AUTO RTL: climb, return, land (from the air).
    ReturnToLaunch,
    /// AUTO MISSION or MISSION_START: fly the mission (asked for while disarmed: starts on arming).
    Mission,
    /// OFFBOARD: follow the streamed setpoints (only while they flow).
    Offboard,
    /// DO_SET_HOME: home at `pos_ned_m` (None: where the vehicle is).
    SetHome { pos_ned_m: Option<Vector3<f64>> },
    /// DO_REPOSITION: hold at `pos_ned_m` (None: here, QGroundControl's pause) with `yaw_rad` (None:
    /// keep), flown to from where the vehicle is; in the air only.
    Goto { pos_ned_m: Option<Vector3<f64>>, yaw_rad: Option<f64> },
}

/// What was refused, for the words of a [`Refusal`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    Arm,
    Disarm,
    Takeoff,
    Land,
    Hold,
    Mission,
    Return,
    Offboard,
    Reposition,
    /// A change to this flight mode.
    Mode(FlightMode),
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Arm => "Arming",
            Self::Disarm => "Disarming",
            Self::Takeoff => "Takeoff",
            Self::Land => "Land",
            Self::Hold => "Hold",
            Self::Mission => "Mission",
            Self::Return => "RTL",
            Self::Offboard => "Offboard",
            Self::Reposition => "Reposition",
            Self::Mode(mode) => return write!(f, "{mode}"),
        })
    }
}

/// Why a request was refused; `Display` is a STATUSTEXT (under 50 characters).
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum Refusal {
    #[error("{0} denied: estimator not converged")]
    EstimatorNotConverged(Action),
    #[error("{0} denied: in air (use force)")]
    InAir(Action),
    #[error("{action} denied: {state}")]
    NotInState { action: Action, state: State },
    #[error("Takeoff denied: altitude {0} m invalid")]
    InvalidAltitude(f64),
    #[error("{0} denied: no mission")]
    NoMission(Action),
    #[error("{0} denied: no offboard setpoints")]
    NoSetpoints(Action),
    #[error("{0} denied: landed")]
    Landed(Action),
    #[error("Set home: no position")]
    NoPosition,
    #[error("Arming denied: battery {remaining_pct}% below {low_pct}%")]
    BatteryLow { remaining_pct: u8, low_pct: u8 },
    #[error("{0} denied: no manual control")]
    NoManualControl(Action),
    #[error("Arming denied: kill switch engaged")]
    KillSwitch,
}

/// Why the vehicle disarmed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DisarmReason {
    /// A disarm request on the ground.
    Requested,
    /// A forced disarm request (possibly in the air).
    Forced,
    /// `disarm_land_s` after touchdown.
    AutoLanded,
    /// `disarm_preflight_s` armed without taking off.
    AutoPreflight,
    /// A kill.
    Kill,
}

/// Something the MAVLink layer reports: arm and mode changes want a HEARTBEAT at once, all a STATUSTEXT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    Armed {
        forced: bool,
    },
    Disarmed {
        reason: DisarmReason,
    },
    Killed,
    ModeChanged {
        mode: FlightMode,
    },
    Landed,
    TakeoffComplete,
    /// A failsafe fired; `action` is what the vehicle does (None: nothing, it is only said).
    Failsafe {
        trigger: Trigger,
        action: Option<FailsafeAction>,
    },
    /// A failsafe's condition cleared (the vehicle stays in the mode the failsafe chose).
    FailsafeCleared {
        trigger: Trigger,
    },
    /// The battery fell below BAT_LOW_THR while armed (a warning: no action).
    BatteryLow {
        remaining_pct: u8,
    },
    /// The radio's kill switch went off (the vehicle disarms, ready to arm again).
    KillSwitchReleased,
}

impl Event {
    /// The STATUSTEXT for this event.
    #[must_use]
    pub fn text(&self) -> String {
        match self {
            Self::Armed { forced: false } => "Armed".into(),
            Self::Armed { forced: true } => "Armed (forced)".into(),
            Self::Disarmed { reason } => match reason {
                DisarmReason::Requested => "Disarmed".into(),
                DisarmReason::Forced => "Disarmed (forced)".into(),
                DisarmReason::AutoLanded => "Disarmed after landing".into(),
                DisarmReason::AutoPreflight => "Disarmed: no takeoff".into(),
                DisarmReason::Kill => "Disarmed by kill".into(),
            },
            Self::Killed => "Kill switch engaged".into(),
            Self::ModeChanged { mode, .. } => format!("Mode: {mode}"),
            Self::Landed => "Landing detected".into(),
            Self::TakeoffComplete => "Takeoff complete".into(),
            Self::Failsafe { trigger, action: Some(action) } => {
                format!("Failsafe: {}, {}", trigger.what(), action.doing())
            }
            Self::Failsafe { trigger, action: None } => format!("Failsafe: {}", trigger.what()),
            Self::FailsafeCleared { trigger: Trigger::DatalinkLost } => "GCS link regained".into(),
            Self::FailsafeCleared { trigger: Trigger::ManualControlLost } => "Manual control regained".into(),
            Self::FailsafeCleared { trigger: Trigger::PositionLost } => "Position regained".into(),
            Self::FailsafeCleared { trigger } => format!("Cleared: {}", trigger.what()),
            Self::BatteryLow { remaining_pct } => format!("Battery low: {remaining_pct}% remaining"),
            Self::KillSwitchReleased => "Kill switch released".into(),
        }
    }

    /// Whether the HEARTBEAT changed (armed flag, mode or status): send one at once.
    #[must_use]
    pub const fn changes_heartbeat(&self) -> bool {
        matches!(self, Self::Armed { .. } | Self::Disarmed { .. } | Self::Killed | Self::ModeChanged { .. })
    }
}

/// One step's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct CommanderOutput {
    pub state: State,
    pub mode: FlightMode,
    /// Health (HEARTBEAT system_status).
    pub status: SystemStatus,
    /// On the ground, taking off, in the air, landing (EXTENDED_SYS_STATE).
    pub landed: LandedState,
    pub armed: bool,
    pub motors_enabled: bool,
    /// What the navigator is to fly.
    pub intent: Intent,
    /// The pack's latest reading and warning level.
    pub battery: BatteryStatus,
    /// What happened since the previous step (requests included), in order.
    pub events: Vec<Event>,
}
