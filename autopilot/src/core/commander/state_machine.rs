//! The commander's state machine as data, after Crazyflie's `supervisor_state_machine.c`. In: the current
//! [`State`] and a [`Conditions`] bitmask (requests, which last one call, and levels such as `LANDED`, which
//! the commander recomputes every step). Out: the next state, from the first row of [`TRANSITIONS`] that
//! leaves the current state, has all its trigger bits set, none of its blocker bits set and all of its
//! required bits set. No row fires: the state stays. Pure and total; no time, no side effects (the
//! commander runs entry actions when the state changes).

use std::fmt;

use serde::{Deserialize, Serialize};

/// Where the vehicle is in its arm / fly / land cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum State {
    /// Motors off, safe to handle.
    Disarmed,
    /// Armed on the ground, motors at idle, waiting for a takeoff (or auto-disarm).
    ArmedIdle,
    /// Climbing to the takeoff altitude above the takeoff point.
    Takeoff,
    /// Holding a position (AUTO LOITER, or POSCTL / ALTCTL without sticks).
    Hold,
    /// Descending at the land speed; on the ground until auto-disarm.
    Land,
    /// Motors stopped by a kill; stays until a disarm request.
    Killed,
    /// Flying the mission (AUTO MISSION).
    Mission,
    /// Returning to launch and landing there (AUTO RTL).
    Rtl,
    /// Following offboard setpoints (OFFBOARD).
    Offboard,
    /// Flown by the pilot's sticks (MANUAL, STABILIZED, ALTCTL, POSCTL), on the ground or in the air.
    Manual,
}

impl State {
    /// Every state, in declaration order.
    pub const ALL: [Self; 10] = [
        Self::Disarmed,
        Self::ArmedIdle,
        Self::Takeoff,
        Self::Hold,
        Self::Land,
        Self::Killed,
        Self::Mission,
        Self::Rtl,
        Self::Offboard,
        Self::Manual,
    ];

    /// This state as a one-bit [`StateSet`].
    #[must_use]
    pub const fn set(self) -> StateSet {
        StateSet(1 << self as u16)
    }

    /// Whether the vehicle is armed in this state (motors may turn).
    #[must_use]
    pub const fn is_armed(self) -> bool {
        matches!(
            self,
            Self::ArmedIdle
                | Self::Takeoff
                | Self::Hold
                | Self::Land
                | Self::Mission
                | Self::Rtl
                | Self::Offboard
                | Self::Manual
        )
    }
}

impl fmt::Display for State {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Disarmed => "vehicle disarmed",
            Self::ArmedIdle => "armed on the ground",
            Self::Takeoff => "taking off",
            Self::Hold => "holding",
            Self::Land => "landing",
            Self::Killed => "kill engaged (disarm to reset)",
            Self::Mission => "flying the mission",
            Self::Rtl => "returning",
            Self::Offboard => "in offboard control",
            Self::Manual => "flown by hand",
        })
    }
}

/// A set of states (bit `s as u8` for state `s`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StateSet(pub u16);

impl StateSet {
    pub const ARMED: Self = Self(
        State::ArmedIdle.set().0
            | State::Takeoff.set().0
            | State::Hold.set().0
            | State::Land.set().0
            | State::Mission.set().0
            | State::Rtl.set().0
            | State::Offboard.set().0
            | State::Manual.set().0,
    );
    pub const NOT_KILLED: Self = Self(Self::ARMED.0 | State::Disarmed.set().0);

    #[must_use]
    pub const fn contains(self, s: State) -> bool {
        self.0 & s.set().0 != 0
    }

    const fn or(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }
}

/// The inputs of [`next`] as a bitmask. Request bits (`*_REQUESTED`, `FORCE`, `KILL`) hold for one
/// evaluation; the others are levels the commander derives from the estimate, the land detector and its
/// timers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Conditions(pub u32);

impl Conditions {
    pub const NONE: Self = Self(0);
    pub const ARM_REQUESTED: Self = Self(1 << 0);
    pub const DISARM_REQUESTED: Self = Self(1 << 1);
    /// The arm/disarm request carries the force magic (21196).
    pub const FORCE: Self = Self(1 << 2);
    /// A takeoff is requested or pending (remembered from before arming).
    pub const TAKEOFF_REQUESTED: Self = Self(1 << 3);
    pub const LAND_REQUESTED: Self = Self(1 << 4);
    /// Hold (AUTO LOITER) or a hold-like mode (POSCTL, ALTCTL) is requested.
    pub const HOLD_REQUESTED: Self = Self(1 << 5);
    /// The land detector says the vehicle is on the ground.
    pub const LANDED: Self = Self(1 << 6);
    /// Within the acceptance of the takeoff altitude.
    pub const TAKEOFF_ALT_REACHED: Self = Self(1 << 7);
    /// Estimator converged and its position finite: arming and takeoff allowed.
    pub const ESTIMATOR_OK: Self = Self(1 << 8);
    /// The auto-disarm timer of the current state ran out (after landing, or before takeoff).
    pub const AUTO_DISARM_EXPIRED: Self = Self(1 << 9);
    /// Kill: stop the motors now.
    pub const KILL: Self = Self(1 << 10);
    /// Mission mode is requested or pending (asked for while disarmed).
    pub const MISSION_REQUESTED: Self = Self(1 << 11);
    pub const RTL_REQUESTED: Self = Self(1 << 12);
    pub const OFFBOARD_REQUESTED: Self = Self(1 << 13);
    /// A mission is loaded and can be flown (the navigator says so).
    pub const MISSION_VALID: Self = Self(1 << 14);
    /// The mission flew its last item in the air.
    pub const MISSION_DONE: Self = Self(1 << 15);
    /// Offboard setpoints are fresh.
    pub const OFFBOARD_OK: Self = Self(1 << 16);
    /// Offboard setpoints stopped (the negation of `OFFBOARD_OK`, as a trigger).
    pub const OFFBOARD_LOST: Self = Self(1 << 17);
    /// An automatic mode is descending to land.
    pub const AUTO_LANDING: Self = Self(1 << 18);
    /// A manual mode (MANUAL, STABILIZED, ALTCTL, POSCTL) is requested or pending (asked for while
    /// disarmed).
    pub const MANUAL_REQUESTED: Self = Self(1 << 19);
    /// The pilot's manual control is fresh (younger than COM_RC_LOSS_T).
    pub const MANUAL_OK: Self = Self(1 << 20);
    /// The manual mode asked for flies on attitude and height alone (MANUAL, STABILIZED, ALTCTL): it
    /// needs no position, so a pilot can take over after a GPS loss, as in PX4.
    pub const ATTITUDE_ONLY: Self = Self(1 << 21);

    /// Every bit any row reads.
    pub const ALL: Self = Self((1 << 22) - 1);
    /// How many bits there are.
    pub const COUNT: u32 = 22;

    #[must_use]
    pub const fn or(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }

    #[must_use]
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    #[must_use]
    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }

    /// `self` with the bits of `other` set when `on`.
    #[must_use]
    pub const fn with(self, other: Self, on: bool) -> Self {
        if on { self.or(other) } else { self }
    }

    #[must_use]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    const fn and_not(self, other: Self) -> Self {
        Self(self.0 & !other.0)
    }
}

impl std::ops::BitOr for Conditions {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        self.or(rhs)
    }
}

/// One row: from any state of `from`, when every bit of `trigger` is set, no bit of `blockers` is set and
/// every bit of `required` is set, go to `to`. `required` are Crazyflie's negated blockers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transition {
    pub from: StateSet,
    pub trigger: Conditions,
    pub blockers: Conditions,
    pub required: Conditions,
    pub to: State,
}

const fn row(from: StateSet, trigger: Conditions, required: Conditions, to: State) -> Transition {
    Transition { from, trigger, blockers: Conditions::NONE, required, to }
}

use Conditions as C;
use State as S;

const AUTO: StateSet = S::Mission.set().or(S::Rtl.set()).or(S::Offboard.set());
/// Every state that flies (or may): the automatic ones and the pilot's.
const TAKEOFF_HOLD_LAND: StateSet = S::Takeoff.set().or(S::Hold.set()).or(S::Land.set()).or(AUTO).or(S::Manual.set());

/// The transitions, in priority order: requests first (kill, disarm, arm, takeoff, mode changes, hold,
/// land), then the automatic ones (takeoff complete, mission done, offboard lost, auto-disarm). Force is
/// its own row rather than an "or" in a blocker, so each row stays a conjunction.
pub const TRANSITIONS: &[Transition] = &[
    // Kill stops the motors from anywhere.
    row(StateSet::NOT_KILLED, C::KILL, C::NONE, S::Killed),
    // A kill and a disarm together stay killed.
    Transition {
        from: S::Killed.set(),
        trigger: C::DISARM_REQUESTED,
        blockers: C::KILL,
        required: C::NONE,
        to: S::Disarmed,
    },
    // Disarm: forced anywhere, otherwise only on the ground.
    row(StateSet::ARMED, C::DISARM_REQUESTED.or(C::FORCE), C::NONE, S::Disarmed),
    row(StateSet::ARMED, C::DISARM_REQUESTED, C::LANDED, S::Disarmed),
    // Arm: forced, or with a converged estimator.
    row(S::Disarmed.set(), C::ARM_REQUESTED.or(C::FORCE), C::NONE, S::ArmedIdle),
    row(S::Disarmed.set(), C::ARM_REQUESTED, C::ESTIMATOR_OK, S::ArmedIdle),
    // Takeoff (a pending one starts once armed); again in the air: climb or descend to the new altitude.
    row(S::ArmedIdle.set(), C::TAKEOFF_REQUESTED, C::ESTIMATOR_OK, S::Takeoff),
    row(TAKEOFF_HOLD_LAND, C::TAKEOFF_REQUESTED, C::ESTIMATOR_OK, S::Takeoff),
    // Mission (a pending one starts once armed), with a mission to fly.
    row(
        S::ArmedIdle.set().or(TAKEOFF_HOLD_LAND),
        C::MISSION_REQUESTED,
        C::MISSION_VALID.or(C::ESTIMATOR_OK),
        S::Mission,
    ),
    // Return, from the air only.
    Transition {
        from: TAKEOFF_HOLD_LAND,
        trigger: C::RTL_REQUESTED,
        blockers: C::LANDED,
        required: C::ESTIMATOR_OK,
        to: S::Rtl,
    },
    // Offboard, only while setpoints flow.
    row(
        S::ArmedIdle.set().or(TAKEOFF_HOLD_LAND),
        C::OFFBOARD_REQUESTED,
        C::OFFBOARD_OK.or(C::ESTIMATOR_OK),
        S::Offboard,
    ),
    // A manual mode, from the ground or the air, only with fresh manual control (a pending one starts once
    // armed).
    row(S::ArmedIdle.set().or(TAKEOFF_HOLD_LAND), C::MANUAL_REQUESTED, C::MANUAL_OK.or(C::ESTIMATOR_OK), S::Manual),
    // An attitude mode needs no position: only fresh manual control.
    row(S::ArmedIdle.set().or(TAKEOFF_HOLD_LAND), C::MANUAL_REQUESTED.or(C::ATTITUDE_ONLY), C::MANUAL_OK, S::Manual),
    // Hold interrupts a takeoff, a landing, an automatic mode or the pilot where the vehicle is.
    row(S::Takeoff.set().or(S::Land.set()).or(AUTO).or(S::Manual.set()), C::HOLD_REQUESTED, C::NONE, S::Hold),
    row(
        S::ArmedIdle.set().or(S::Takeoff.set()).or(S::Hold.set()).or(AUTO).or(S::Manual.set()),
        C::LAND_REQUESTED,
        C::NONE,
        S::Land,
    ),
    // Automatic.
    row(S::Takeoff.set(), C::TAKEOFF_ALT_REACHED, C::NONE, S::Hold),
    Transition {
        from: S::Mission.set(),
        trigger: C::MISSION_DONE,
        blockers: C::AUTO_LANDING,
        required: C::NONE,
        to: S::Hold,
    },
    row(S::Offboard.set(), C::OFFBOARD_LOST, C::NONE, S::Hold),
    row(S::Land.set(), C::AUTO_DISARM_EXPIRED, C::LANDED, S::Disarmed),
    row(S::Mission.set().or(S::Rtl.set()), C::AUTO_DISARM_EXPIRED, C::LANDED.or(C::AUTO_LANDING), S::Disarmed),
    row(S::ArmedIdle.set(), C::AUTO_DISARM_EXPIRED, C::NONE, S::Disarmed),
    row(S::Manual.set(), C::AUTO_DISARM_EXPIRED, C::LANDED, S::Disarmed),
];

impl Transition {
    /// The row leaves `state` and its trigger is set (it fires unless blocked).
    #[must_use]
    pub const fn triggered(&self, state: State, c: Conditions) -> bool {
        self.from.contains(state) && c.contains(self.trigger)
    }

    /// The bits that stop a triggered row: blockers present and required bits missing.
    #[must_use]
    pub const fn blocked_by(&self, c: Conditions) -> Conditions {
        Conditions(c.0 & self.blockers.0).or(self.required.and_not(c))
    }
}

/// The row that fires from `state` under `c`, if any (a row may lead back to `state`).
#[must_use]
pub fn fire(state: State, c: Conditions) -> Option<&'static Transition> {
    TRANSITIONS.iter().find(|t| t.triggered(state, c) && t.blocked_by(c).is_empty())
}

/// The next state: the target of the first row that fires, or `state` when none does.
#[must_use]
pub fn next(state: State, c: Conditions) -> State {
    fire(state, c).map_or(state, |t| t.to)
}

/// When no row fires: what blocked the first triggered row (its missing or blocking bits), for the words
/// of a refusal. Empty when no row was triggered at all.
#[must_use]
pub fn blocked_by(state: State, c: Conditions) -> Conditions {
    TRANSITIONS.iter().find(|t| t.triggered(state, c)).map_or(Conditions::NONE, |t| t.blocked_by(c))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_bits() -> impl Iterator<Item = Conditions> {
        (0..Conditions::COUNT).map(|i| Conditions(1 << i))
    }

    #[test]
    fn given_each_row_when_its_trigger_and_required_bits_are_set_then_it_goes_to_its_target() {
        for (i, t) in TRANSITIONS.iter().enumerate() {
            let c = t.trigger | t.required;
            for s in State::ALL.into_iter().filter(|&s| t.from.contains(s)) {
                // An earlier row may claim the same state and bits; then that row must be the one firing.
                let first = fire(s, c).expect("a row fires");
                let first_i = TRANSITIONS.iter().position(|r| r == first).expect("row in table");
                assert!(first_i <= i, "row {i} from {s:?}: row {first_i} fired");
                if first_i == i {
                    assert_eq!(next(s, c), t.to, "row {i} from {s:?}");
                }
            }
        }
    }

    #[test]
    fn given_each_row_when_a_required_bit_is_missing_then_that_row_does_not_fire() {
        for (i, t) in TRANSITIONS.iter().enumerate() {
            for bit in all_bits().filter(|&b| t.required.contains(b)) {
                let c = Conditions((t.trigger | t.required).0 & !bit.0);
                for s in State::ALL.into_iter().filter(|&s| t.from.contains(s)) {
                    assert_ne!(fire(s, c), Some(t), "row {i} from {s:?} without {bit:?}");
                }
            }
        }
    }

    #[test]
    fn given_the_expected_transitions_when_evaluated_then_each_holds() {
        use Conditions as C;
        let cases: &[(State, Conditions, State)] = &[
            (S::Disarmed, C::ARM_REQUESTED | C::ESTIMATOR_OK, S::ArmedIdle),
            (S::Disarmed, C::ARM_REQUESTED | C::FORCE, S::ArmedIdle),
            (S::Disarmed, C::KILL, S::Killed),
            (S::ArmedIdle, C::KILL, S::Killed),
            (S::Takeoff, C::KILL, S::Killed),
            (S::Hold, C::KILL | C::LANDED, S::Killed),
            (S::Land, C::KILL | C::DISARM_REQUESTED, S::Killed),
            (S::Killed, C::DISARM_REQUESTED, S::Disarmed),
            (S::ArmedIdle, C::DISARM_REQUESTED | C::LANDED, S::Disarmed),
            (S::Hold, C::DISARM_REQUESTED | C::FORCE, S::Disarmed),
            (S::ArmedIdle, C::TAKEOFF_REQUESTED | C::ESTIMATOR_OK, S::Takeoff),
            (S::Hold, C::TAKEOFF_REQUESTED | C::ESTIMATOR_OK, S::Takeoff),
            (S::Takeoff, C::TAKEOFF_ALT_REACHED, S::Hold),
            (S::Takeoff, C::HOLD_REQUESTED, S::Hold),
            (S::Land, C::HOLD_REQUESTED, S::Hold),
            (S::Hold, C::LAND_REQUESTED, S::Land),
            (S::Takeoff, C::LAND_REQUESTED | C::TAKEOFF_ALT_REACHED, S::Land),
            (S::ArmedIdle, C::LAND_REQUESTED, S::Land),
            (S::Land, C::AUTO_DISARM_EXPIRED | C::LANDED, S::Disarmed),
            (S::ArmedIdle, C::AUTO_DISARM_EXPIRED, S::Disarmed),
            (S::ArmedIdle, C::AUTO_DISARM_EXPIRED | C::TAKEOFF_REQUESTED | C::ESTIMATOR_OK, S::Takeoff),
            (S::ArmedIdle, C::MISSION_REQUESTED | C::MISSION_VALID | C::ESTIMATOR_OK, S::Mission),
            (S::Hold, C::MISSION_REQUESTED | C::MISSION_VALID | C::ESTIMATOR_OK, S::Mission),
            (S::Hold, C::RTL_REQUESTED | C::ESTIMATOR_OK, S::Rtl),
            (S::Mission, C::RTL_REQUESTED | C::ESTIMATOR_OK, S::Rtl),
            (S::Hold, C::OFFBOARD_REQUESTED | C::OFFBOARD_OK | C::ESTIMATOR_OK, S::Offboard),
            (S::Offboard, C::OFFBOARD_LOST, S::Hold),
            (S::Mission, C::MISSION_DONE, S::Hold),
            (S::Mission, C::AUTO_DISARM_EXPIRED | C::LANDED | C::AUTO_LANDING, S::Disarmed),
            (S::Rtl, C::AUTO_DISARM_EXPIRED | C::LANDED | C::AUTO_LANDING, S::Disarmed),
            (S::Rtl, C::HOLD_REQUESTED, S::Hold),
            (S::Mission, C::LAND_REQUESTED, S::Land),
            (S::Offboard, C::TAKEOFF_REQUESTED | C::ESTIMATOR_OK, S::Takeoff),
            (S::ArmedIdle, C::MANUAL_REQUESTED | C::MANUAL_OK | C::ESTIMATOR_OK, S::Manual),
            (S::Mission, C::MANUAL_REQUESTED | C::MANUAL_OK | C::ESTIMATOR_OK, S::Manual),
            (S::Manual, C::HOLD_REQUESTED, S::Hold),
            (S::Manual, C::RTL_REQUESTED | C::ESTIMATOR_OK, S::Rtl),
            (S::Manual, C::AUTO_DISARM_EXPIRED | C::LANDED, S::Disarmed),
            (S::Manual, C::AUTO_DISARM_EXPIRED, S::Manual),
        ];
        for &(from, c, to) in cases {
            assert_eq!(next(from, c), to, "{from:?} under {c:?}");
        }
    }

    #[test]
    fn given_a_blocked_transition_when_evaluated_then_the_state_stays_and_the_blocker_is_named() {
        use Conditions as C;
        let cases: &[(State, Conditions, Conditions)] = &[
            (S::Disarmed, C::ARM_REQUESTED, C::ESTIMATOR_OK),
            (S::Hold, C::DISARM_REQUESTED, C::LANDED),
            (S::Takeoff, C::DISARM_REQUESTED, C::LANDED),
            (S::ArmedIdle, C::TAKEOFF_REQUESTED, C::ESTIMATOR_OK),
            (S::Land, C::AUTO_DISARM_EXPIRED, C::LANDED),
            (S::Killed, C::DISARM_REQUESTED | C::KILL, C::KILL),
            (S::Hold, C::MISSION_REQUESTED | C::ESTIMATOR_OK, C::MISSION_VALID),
            (S::Hold, C::RTL_REQUESTED | C::ESTIMATOR_OK | C::LANDED, C::LANDED),
            (S::Hold, C::OFFBOARD_REQUESTED | C::ESTIMATOR_OK, C::OFFBOARD_OK),
            (S::Mission, C::MISSION_DONE | C::AUTO_LANDING, C::AUTO_LANDING),
            (S::Mission, C::AUTO_DISARM_EXPIRED | C::LANDED, C::AUTO_LANDING),
            (S::Hold, C::MANUAL_REQUESTED | C::ESTIMATOR_OK, C::MANUAL_OK),
        ];
        for &(from, c, missing) in cases {
            assert_eq!(next(from, c), from, "{from:?} under {c:?}");
            assert_eq!(blocked_by(from, c), missing, "{from:?} under {c:?}");
        }
    }

    #[test]
    fn given_triggers_no_row_of_the_state_reads_when_evaluated_then_nothing_changes() {
        use Conditions as C;
        let cases: &[(State, Conditions)] = &[
            (S::Disarmed, C::TAKEOFF_REQUESTED | C::ESTIMATOR_OK | C::LANDED),
            (S::Disarmed, C::DISARM_REQUESTED | C::FORCE),
            (S::Disarmed, C::LAND_REQUESTED | C::HOLD_REQUESTED | C::AUTO_DISARM_EXPIRED),
            (S::Hold, C::ARM_REQUESTED | C::HOLD_REQUESTED | C::TAKEOFF_ALT_REACHED | C::AUTO_DISARM_EXPIRED),
            (S::Land, C::LAND_REQUESTED | C::LANDED),
            (S::Killed, C::ARM_REQUESTED | C::FORCE | C::KILL | C::TAKEOFF_REQUESTED | C::ESTIMATOR_OK),
            (S::Takeoff, C(1 << 25)),
            (S::Hold, C::MANUAL_REQUESTED | C::ESTIMATOR_OK),
        ];
        for &(from, c) in cases {
            assert_eq!(next(from, c), from, "{from:?} under {c:?}");
            assert!(fire(from, c).is_none(), "{from:?} {c:?} {:?}", fire(from, c));
        }
        for s in State::ALL {
            assert_eq!(next(s, Conditions::NONE), s);
        }
    }

    #[test]
    fn given_any_state_and_any_conditions_with_kill_then_the_motors_stop() {
        for s in State::ALL {
            for bits in 0..(1u32 << Conditions::COUNT) {
                let to = next(s, Conditions(bits) | Conditions::KILL);
                assert_eq!(to, S::Killed, "{s:?} under {bits:#b}");
            }
        }
    }

    #[test]
    fn given_every_state_when_all_bits_but_kill_are_tried_then_killed_is_left_only_by_a_disarm() {
        for bits in 0..(1u32 << Conditions::COUNT) {
            let c = Conditions(bits & !Conditions::KILL.0);
            let to = next(S::Killed, c);
            let expect = if c.contains(Conditions::DISARM_REQUESTED) { S::Disarmed } else { S::Killed };
            assert_eq!(to, expect, "{bits:#b}");
        }
        assert_eq!(Conditions::ALL.0 & Conditions::KILL.0, Conditions::KILL.0);
    }
}
