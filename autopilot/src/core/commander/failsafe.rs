//! The failsafe table: the conditions under which the vehicle changes mode by itself, the parameter that
//! chooses what it does, and what it says. In: the commander's state and parameters, vehicle time (µs),
//! when a ground station last sent a HEARTBEAT. Out: which failsafes are active, and for a newly active
//! one the action to take; the commander applies it through its transition table and announces it
//! (STATUSTEXT, HEARTBEAT mode). Every timer runs on vehicle time, so a failsafe fires identically at
//! `--speed 1` and in lockstep.
//!
//! | trigger | parameters | default | action |
//! |---|---|---|---|
//! | no ground-station HEARTBEAT (`MAV_TYPE_GCS`) for `COM_DL_LOSS_T` s, after one was heard | `COM_DL_LOSS_T`, `NAV_DLL_ACT` | 10 s, 0 (off) | PX4's NAV_DLL_ACT: 1 hold, 2 return, 3 land, 5 terminate |
//! | offboard setpoints older than `COM_OF_LOSS_T` in offboard mode | `COM_OF_LOSS_T` | 0.5 s | hold |
//!
//! An action is taken only in the air (armed, not landed); the vehicle stays in the failsafe's mode when
//! the trigger clears (regaining the link is announced), until a pilot changes it, as PX4 does.

use serde::{Deserialize, Serialize};

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
        }
    }
}

/// What set a failsafe off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Trigger {
    /// No ground-station HEARTBEAT for `COM_DL_LOSS_T`.
    DatalinkLost,
    /// Offboard setpoints stopped in offboard mode.
    OffboardLost,
}

impl Trigger {
    /// The condition, for the announcement.
    #[must_use]
    pub const fn what(self) -> &'static str {
        match self {
            Self::DatalinkLost => "GCS link lost",
            Self::OffboardLost => "offboard setpoints lost",
        }
    }
}

/// Whether the ground-station link is lost at `now_us`: a GCS HEARTBEAT was heard (`last_us`) and none for
/// more than `timeout_s` since. Never lost before the first one (nothing to lose yet).
#[must_use]
pub fn datalink_lost(now_us: u64, last_us: Option<u64>, timeout_s: f64) -> bool {
    last_us.is_some_and(|t| now_us.saturating_sub(t) > seconds_to_us(timeout_s))
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
    fn given_heartbeats_then_lost_only_after_one_was_heard_and_the_timeout_passed() {
        assert!(!datalink_lost(100_000_000, None, 10.0), "never heard: nothing to lose");
        assert!(!datalink_lost(10_000_000, Some(0), 10.0));
        assert!(datalink_lost(10_000_001, Some(0), 10.0));
    }
}
