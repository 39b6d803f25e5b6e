//! The pilot's input over time, as PX4's `manual_control` module keeps it. In: radio frames and joystick
//! sticks with the vehicle time they arrived (µs). Out, per step ([`ManualInput::step`]): the sticks in use
//! and their source ([`ManualStatus`]; none once the chosen source is older than `COM_RC_LOSS_T`), and the
//! [`PilotAction`]s since the last step: a mode-switch slot (on change, and once as the radio first
//! appears), the kill switch (on change, and its first position), the arm switch (on change only: a switch
//! found on does not arm) and the arming gestures (throttle low with yaw right, or left, held for
//! `COM_RC_ARM_HYST`; off when an arm switch is mapped, as PX4).
//!
//! `COM_RC_IN_MODE` chooses the source as PX4: 0 the radio only, 1 the joystick only, 2 either (the one in
//! use is kept while it is fresh, the other takes over when it is lost), 3 the first one seen, for good, 4
//! none. Switches are read only from the radio, and only while the radio is the source.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::rc::{RcConfig, RcConfigError, Switches};
use super::{RcFrame, Sticks};
use crate::core::commander::FlightMode;
use crate::core::seconds_to_us;

/// PX4's COM_RC_IN_MODE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RcInMode {
    RcOnly,
    JoystickOnly,
    Either,
    KeepFirst,
    Disabled,
}

impl RcInMode {
    /// PX4's number: 0 RC only, 1 joystick only, 2 either with fallback, 3 keep the first, 4 none.
    #[must_use]
    pub const fn from_px4(n: u32) -> Option<Self> {
        match n {
            0 => Some(Self::RcOnly),
            1 => Some(Self::JoystickOnly),
            2 => Some(Self::Either),
            3 => Some(Self::KeepFirst),
            4 => Some(Self::Disabled),
            _ => None,
        }
    }

    fn accepts(self, source: ManualSource) -> bool {
        match self {
            Self::RcOnly => source == ManualSource::Rc,
            Self::JoystickOnly => source == ManualSource::Joystick,
            Self::Either | Self::KeepFirst => true,
            Self::Disabled => false,
        }
    }
}

/// Where the sticks come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ManualSource {
    /// The radio: RC_CHANNELS from the airframe's board, or RC_CHANNELS_OVERRIDE.
    Rc,
    /// A ground station's joystick: MANUAL_CONTROL.
    Joystick,
}

/// The manual-control parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ManualConfig {
    /// The radio's calibration and map (RCn_*, RC_MAP_*).
    pub rc: RcConfig,
    /// Which source flies (COM_RC_IN_MODE, see [`RcInMode::from_px4`]).
    pub in_mode: u32,
    /// Manual control is lost after this long without input (s; COM_RC_LOSS_T).
    pub loss_s: f64,
    /// Arm and disarm with the sticks (MAN_ARM_GESTURE).
    pub arm_gesture: bool,
    /// How long a gesture is held (s; COM_RC_ARM_HYST).
    pub arm_hyst_s: f64,
    /// The modes of the mode switch's six slots (COM_FLTMODE1..6; PX4's numbers, -1 none).
    pub fltmodes: [i32; 6],
}

impl Default for ManualConfig {
    fn default() -> Self {
        Self { rc: RcConfig::default(), in_mode: 3, loss_s: 0.5, arm_gesture: true, arm_hyst_s: 1.0, fltmodes: [-1; 6] }
    }
}

/// A manual-control setting that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ManualConfigError {
    #[error(transparent)]
    Rc(#[from] RcConfigError),
    #[error("COM_RC_IN_MODE = {0} must be 0 to 4")]
    InMode(u32),
    #[error("{name} = {value} must be finite and positive")]
    NotPositive { name: &'static str, value: f64 },
    #[error("COM_FLTMODE{slot} = {mode} is not a mode this vehicle flies (-1 none, 0-8, 10, 11)")]
    FlightMode { slot: usize, mode: i32 },
}

impl ManualConfig {
    /// # Errors
    /// [`ManualConfigError`] naming the first unusable value.
    pub fn validate(&self) -> Result<(), ManualConfigError> {
        self.rc.validate()?;
        RcInMode::from_px4(self.in_mode).ok_or(ManualConfigError::InMode(self.in_mode))?;
        for (name, value) in [("COM_RC_LOSS_T", self.loss_s), ("COM_RC_ARM_HYST", self.arm_hyst_s)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ManualConfigError::NotPositive { name, value });
            }
        }
        for (i, &mode) in self.fltmodes.iter().enumerate() {
            if mode != -1 && !FLTMODES_FLOWN.contains(&mode) {
                return Err(ManualConfigError::FlightMode { slot: i + 1, mode });
            }
        }
        Ok(())
    }

    fn in_mode(&self) -> RcInMode {
        RcInMode::from_px4(self.in_mode).unwrap_or(RcInMode::KeepFirst)
    }
}

/// The flight mode of PX4's COM_FLTMODE number `n`, or the refusal's words.
///
/// # Errors
/// The STATUSTEXT for a number that is not a mode this vehicle flies.
pub fn fltmode_flight_mode(n: i32) -> Result<FlightMode, &'static str> {
    Ok(match n {
        0 => FlightMode::Manual,
        1 => FlightMode::Altitude,
        2 => FlightMode::Position,
        3 => FlightMode::Mission,
        4 => FlightMode::Hold,
        5 => FlightMode::ReturnToLaunch,
        6 => FlightMode::Acro,
        7 => FlightMode::Offboard,
        8 => FlightMode::Stabilized,
        10 => FlightMode::Takeoff,
        11 => FlightMode::Land,
        _ => return Err("Mode switch: no such mode"),
    })
}

/// PX4's COM_FLTMODE numbers this vehicle flies: 0 Manual, 1 Altitude, 2 Position, 3 Mission, 4 Hold,
/// 5 Return, 6 Acro, 7 Offboard, 8 Stabilized, 10 Takeoff, 11 Land.
pub const FLTMODES_FLOWN: [i32; 11] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 11];

/// Something the pilot did with a switch or the sticks, once, as it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PilotAction {
    /// The mode switch moved to a slot (0-5) assigned the PX4 mode number `mode` (COM_FLTMODE).
    ModeSwitch { slot: u8, mode: i32 },
    /// The kill switch moved (on: stop the motors).
    KillSwitch(bool),
    /// The arm switch moved (on: arm, off: disarm).
    ArmSwitch(bool),
    /// Throttle low and yaw right held for COM_RC_ARM_HYST.
    ArmGesture,
    /// Throttle low and yaw left held for COM_RC_ARM_HYST.
    DisarmGesture,
}

/// The sticks in use now.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ManualStatus {
    /// The sticks, when the chosen source is fresh.
    pub sticks: Option<Sticks>,
    pub source: Option<ManualSource>,
    /// The last radio frame (fresh or not), for telemetry and the log.
    pub rc: Option<RcFrame>,
    /// When it arrived (µs of vehicle time; the log's `input_rc.timestamp_last_signal`).
    pub rc_at_us: Option<u64>,
    /// Whether the radio is fresh (RC_CHANNELS telemetry, SYS_STATUS).
    pub rc_fresh: bool,
}

/// A gesture: throttle low (< 0.1) and yaw at one end (beyond 0.9).
const GESTURE_THROTTLE: f64 = 0.1;
const GESTURE_YAW: f64 = 0.9;

#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample<T> {
    at_us: u64,
    value: T,
}

/// The pilot's input. See the module docs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ManualInput {
    rc: Option<Sample<RcFrame>>,
    /// The radio's sticks as last mapped (None: the frame lacked a stick channel).
    rc_sticks: Option<Sample<Sticks>>,
    joystick: Option<Sample<Sticks>>,
    /// The source in use (kept while fresh), and the first ever (COM_RC_IN_MODE 3).
    source: Option<ManualSource>,
    first: Option<ManualSource>,
    /// The switches as last seen (None: not yet).
    switches: Option<Switches>,
    /// Since when a gesture has been held (µs), and whether it already fired.
    gesture_since_us: Option<(bool, u64)>,
    gesture_fired: bool,
    actions: Vec<PilotAction>,
}

impl ManualInput {
    /// A radio frame at `now_us`.
    pub fn on_rc(&mut self, now_us: u64, frame: RcFrame, config: &ManualConfig) {
        self.rc = Some(Sample { at_us: now_us, value: frame });
        // A frame without signal (the receiver's own failsafe: no channels, or RSSI 0) is not input.
        let sticks = (frame.count > 0 && frame.rssi != 0).then(|| config.rc.sticks(&frame)).flatten();
        if let Some(sticks) = sticks.and_then(Sticks::sanitized) {
            self.rc_sticks = Some(Sample { at_us: now_us, value: sticks });
        }
    }

    /// A joystick's sticks at `now_us` (MANUAL_CONTROL).
    pub fn on_joystick(&mut self, now_us: u64, sticks: Sticks) {
        if let Some(value) = sticks.sanitized() {
            self.joystick = Some(Sample { at_us: now_us, value });
        }
    }

    fn fresh<T: Copy>(sample: Option<Sample<T>>, now_us: u64, loss_us: u64) -> Option<T> {
        sample.filter(|s| now_us.saturating_sub(s.at_us) <= loss_us).map(|s| s.value)
    }

    /// The sticks that would be in use at `now_us` (as [`Self::step`] chooses them), without stepping.
    #[must_use]
    pub fn sticks(&self, now_us: u64, config: &ManualConfig) -> Option<Sticks> {
        self.select(now_us, config).1
    }

    /// The source chosen at `now_us` (None: none is fresh), its sticks, and whether the radio is fresh.
    fn select(&self, now_us: u64, config: &ManualConfig) -> (Option<ManualSource>, Option<Sticks>, bool) {
        let loss_us = seconds_to_us(config.loss_s);
        let mode = config.in_mode();
        let rc = Self::fresh(self.rc_sticks, now_us, loss_us).filter(|_| mode.accepts(ManualSource::Rc));
        let joystick = Self::fresh(self.joystick, now_us, loss_us).filter(|_| mode.accepts(ManualSource::Joystick));
        let fresh = |s: ManualSource| match s {
            ManualSource::Rc => rc,
            ManualSource::Joystick => joystick,
        };
        let current = self.source.filter(|&s| fresh(s).is_some());
        let chosen = match mode {
            RcInMode::KeepFirst => self
                .first
                .or_else(|| [ManualSource::Rc, ManualSource::Joystick].into_iter().find(|&s| fresh(s).is_some())),
            _ => {
                current.or_else(|| [ManualSource::Rc, ManualSource::Joystick].into_iter().find(|&s| fresh(s).is_some()))
            }
        };
        let sticks = chosen.and_then(fresh);
        (chosen.filter(|_| sticks.is_some()), sticks, rc.is_some())
    }

    /// The status at `now_us`, and the pilot's actions since the last step (see the module docs).
    pub fn step(&mut self, now_us: u64, config: &ManualConfig) -> (ManualStatus, Vec<PilotAction>) {
        let (chosen, sticks, rc_fresh) = self.select(now_us, config);
        if sticks.is_some() {
            self.source = chosen;
            self.first = self.first.or(chosen);
        }
        let rc_in_use = sticks.is_some() && chosen == Some(ManualSource::Rc);
        if rc_in_use && let Some(frame) = self.rc {
            self.read_switches(&config.rc.switches(&frame.value), config);
        }
        match sticks {
            Some(s) if config.arm_gesture && config.rc.map.arm_sw == 0 => self.gesture(now_us, &s, config),
            _ => {
                self.gesture_since_us = None;
                self.gesture_fired = false;
            }
        }
        let status = ManualStatus {
            sticks,
            source: chosen,
            rc: self.rc.map(|s| s.value),
            rc_at_us: self.rc.map(|s| s.at_us),
            rc_fresh,
        };
        (status, std::mem::take(&mut self.actions))
    }

    fn read_switches(&mut self, now: &Switches, config: &ManualConfig) {
        let before = self.switches;
        if let Some(slot) = now.mode_slot
            && before.is_none_or(|b| b.mode_slot != Some(slot))
        {
            let mode = config.fltmodes[usize::from(slot).min(5)];
            if mode >= 0 {
                self.actions.push(PilotAction::ModeSwitch { slot, mode });
            }
        }
        if let Some(kill) = now.kill
            && before.map_or(kill, |b| b.kill != Some(kill))
        {
            self.actions.push(PilotAction::KillSwitch(kill));
        }
        if let (Some(arm), Some(b)) = (now.arm, before)
            && b.arm.is_some_and(|was| was != arm)
        {
            self.actions.push(PilotAction::ArmSwitch(arm));
        }
        self.switches = Some(*now);
    }

    fn gesture(&mut self, now_us: u64, s: &Sticks, config: &ManualConfig) {
        let held = (s.throttle < GESTURE_THROTTLE && s.yaw.abs() > GESTURE_YAW).then_some(s.yaw > 0.0);
        match (held, self.gesture_since_us) {
            (Some(right), Some((was_right, since))) if right == was_right => {
                if !self.gesture_fired && now_us.saturating_sub(since) >= seconds_to_us(config.arm_hyst_s) {
                    self.gesture_fired = true;
                    self.actions.push(if right { PilotAction::ArmGesture } else { PilotAction::DisarmGesture });
                }
            }
            (Some(right), _) => {
                self.gesture_since_us = Some((right, now_us));
                self.gesture_fired = false;
            }
            (None, _) => {
                self.gesture_since_us = None;
                self.gesture_fired = false;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::core::manual::RcMap;

    const MS: u64 = 1_000;

    fn centre() -> Sticks {
        Sticks::default()
    }

    #[test]
    fn sticks_are_lost_after_com_rc_loss_t() {
        let cfg = ManualConfig::default();
        let mut m = ManualInput::default();
        m.on_joystick(0, centre());
        assert_eq!(m.step(500 * MS, &cfg).0.source, Some(ManualSource::Joystick));
        assert_eq!(m.step(501 * MS, &cfg).0.sticks, None);
    }

    #[test]
    fn either_mode_falls_back_and_keep_first_does_not() {
        let rc_frame = RcFrame::of(&[1500, 1500, 1000, 1500]);
        for (in_mode, after_loss) in [(2, Some(ManualSource::Joystick)), (3, None)] {
            let cfg = ManualConfig { in_mode, ..ManualConfig::default() };
            let mut m = ManualInput::default();
            m.on_rc(0, rc_frame, &cfg);
            m.on_joystick(0, centre());
            assert_eq!(m.step(0, &cfg).0.source, Some(ManualSource::Rc), "mode {in_mode}");
            m.on_joystick(400 * MS, centre());
            assert_eq!(m.step(600 * MS, &cfg).0.source, after_loss, "mode {in_mode}");
        }
        // Radio only ignores the joystick; none ignores both.
        for in_mode in [0, 4] {
            let cfg = ManualConfig { in_mode, ..ManualConfig::default() };
            let mut m = ManualInput::default();
            m.on_joystick(0, centre());
            assert_eq!(m.step(0, &cfg).0.sticks, None, "mode {in_mode}");
        }
    }

    #[test]
    fn a_frame_without_signal_is_no_input() {
        let cfg = ManualConfig::default();
        let mut m = ManualInput::default();
        m.on_rc(0, RcFrame { rssi: 0, ..RcFrame::of(&[1500, 1500, 1000, 1500]) }, &cfg);
        assert_eq!(m.step(0, &cfg).0.sticks, None);
    }

    #[test]
    fn the_arming_gesture_fires_once_after_its_hold_time() {
        let cfg = ManualConfig::default();
        let mut m = ManualInput::default();
        let right = Sticks { throttle: 0.0, yaw: 1.0, ..centre() };
        let mut fired = Vec::new();
        for ms in (0..=1500).step_by(20) {
            m.on_joystick(ms * MS, right);
            let (_, actions) = m.step(ms * MS, &cfg);
            fired.extend(actions.into_iter().map(|a| (ms, a)));
        }
        assert_eq!(fired, vec![(1000, PilotAction::ArmGesture)]);
        // An arm switch mapped turns the gesture off.
        let cfg = ManualConfig {
            rc: RcConfig { map: RcMap { arm_sw: 5, ..RcMap::default() }, ..RcConfig::default() },
            ..ManualConfig::default()
        };
        let mut m = ManualInput::default();
        let mut any = false;
        for ms in (0..=1500).step_by(20) {
            m.on_joystick(ms * MS, right);
            any |= !m.step(ms * MS, &cfg).1.is_empty();
        }
        assert!(!any);
    }

    #[test]
    fn switches_act_on_their_edges_and_an_arm_switch_found_on_does_not_arm() {
        let cfg = ManualConfig {
            rc: RcConfig {
                map: RcMap { fltmode: 5, kill_sw: 6, arm_sw: 7, ..RcMap::default() },
                ..RcConfig::default()
            },
            fltmodes: [2, -1, -1, 1, -1, 3],
            ..ManualConfig::default()
        };
        let mut m = ManualInput::default();
        let frame = |mode, kill, arm| RcFrame::of(&[1500, 1500, 1000, 1500, mode, kill, arm]);
        m.on_rc(0, frame(1000, 1000, 2000), &cfg);
        // The first frame: the mode switch's mode is asked for; a kill switch found off is nothing to do.
        assert_eq!(m.step(0, &cfg).1, vec![PilotAction::ModeSwitch { slot: 0, mode: 2 }]);
        m.on_rc(20 * MS, frame(1500, 2000, 1000), &cfg);
        assert_eq!(
            m.step(20 * MS, &cfg).1,
            vec![
                PilotAction::ModeSwitch { slot: 3, mode: 1 },
                PilotAction::KillSwitch(true),
                PilotAction::ArmSwitch(false)
            ]
        );
        m.on_rc(40 * MS, frame(1500, 2000, 1000), &cfg);
        assert!(m.step(40 * MS, &cfg).1.is_empty());
        m.on_rc(60 * MS, frame(1500, 2000, 2000), &cfg);
        assert_eq!(m.step(60 * MS, &cfg).1, vec![PilotAction::ArmSwitch(true)]);
    }

    #[derive(Debug, Clone)]
    enum Ev {
        Rc(Vec<u16>, u8),
        Joy(i16, i16, i16, i16),
        Wait(u64),
    }

    fn any_event() -> impl Strategy<Value = Ev> {
        prop_oneof![
            (proptest::collection::vec(prop_oneof![3 => 900_u16..2100, 1 => any::<u16>()], 0..19), any::<u8>())
                .prop_map(|(c, rssi)| Ev::Rc(c, rssi)),
            (any::<i16>(), any::<i16>(), any::<i16>(), any::<i16>()).prop_map(|(x, y, z, r)| Ev::Joy(x, y, z, r)),
            (0_u64..800_000).prop_map(Ev::Wait),
        ]
    }

    proptest! {
        /// Any sequence of radio frames, joystick samples and waits, under any COM_RC_IN_MODE: the sticks are
        /// in range, come only from a source the mode accepts, only while that source is younger than
        /// COM_RC_LOSS_T, and an arm switch found on never arms.
        #[test]
        fn any_input_sequence_gives_sticks_in_range_from_an_accepted_fresh_source(
            in_mode in 0_u32..5, events in proptest::collection::vec(any_event(), 1..80),
        ) {
            let cfg = ManualConfig {
                in_mode,
                rc: RcConfig { map: RcMap { fltmode: 5, kill_sw: 6, arm_sw: 7, ..RcMap::default() }, ..RcConfig::default() },
                fltmodes: [2, 1, 3, 4, 5, 8],
                ..ManualConfig::default()
            };
            let mode = RcInMode::from_px4(in_mode).unwrap();
            let mut m = ManualInput::default();
            let mut now = 0;
            let (mut last_rc, mut last_joy): (Option<u64>, Option<u64>) = (None, None);
            let mut arm_switch_seen = false;
            for ev in events {
                match ev {
                    Ev::Rc(c, rssi) => {
                        let frame = RcFrame { rssi, ..RcFrame::of(&c) };
                        m.on_rc(now, frame, &cfg);
                        if frame.count > 0 && rssi != 0 && cfg.rc.sticks(&frame).is_some() {
                            last_rc = Some(now);
                        }
                    }
                    Ev::Joy(x, y, z, r) => {
                        m.on_joystick(now, Sticks::from_manual_control(x, y, z, r));
                        last_joy = Some(now);
                    }
                    Ev::Wait(us) => now += us,
                }
                let (status, actions) = m.step(now, &cfg);
                if let Some(s) = status.sticks {
                    for v in [s.roll, s.pitch, s.yaw] {
                        prop_assert!((-1.0..=1.0).contains(&v));
                    }
                    prop_assert!((0.0..=1.0).contains(&s.throttle));
                    let source = status.source.expect("a source with the sticks");
                    prop_assert!(mode.accepts(source), "{source:?} under mode {in_mode}");
                    let last = match source { ManualSource::Rc => last_rc, ManualSource::Joystick => last_joy };
                    prop_assert!(last.is_some_and(|t| now - t <= seconds_to_us(cfg.loss_s)), "stale sticks");
                }
                for a in actions {
                    if let PilotAction::ArmSwitch(true) = a {
                        prop_assert!(arm_switch_seen, "an arm switch found on armed");
                    }
                }
                arm_switch_seen |= m.switches.is_some_and(|s| s.arm.is_some());
            }
        }
    }

    #[test]
    fn an_unflown_mode_on_the_switch_is_refused_when_set() {
        let cfg = ManualConfig { fltmodes: [12, -1, -1, -1, -1, -1], ..ManualConfig::default() };
        assert_eq!(cfg.validate(), Err(ManualConfigError::FlightMode { slot: 1, mode: 12 }));
        assert_eq!(
            ManualConfig { in_mode: 5, ..ManualConfig::default() }.validate(),
            Err(ManualConfigError::InMode(5))
        );
        assert_eq!(ManualConfig::default().validate(), Ok(()));
    }
}
