//! The radio's calibration and channel map, as PX4's `rc_update`: `RCn_MIN/MAX/TRIM/REV/DZ` turn a
//! channel's PWM into [-1, 1] (a dead zone of DZ µs around TRIM, reversed when REV is -1), and
//! `RC_MAP_ROLL/PITCH/YAW/THROTTLE/FLTMODE/KILL_SW/ARM_SW` say which channel (1-18, 0 none) carries what.
//! In: an [`RcFrame`]. Out: the [`Sticks`] (None when a stick channel is missing) and the switches'
//! positions ([`Switches`]).

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::{RC_CHANNELS_MAX, RcFrame, Sticks};

/// One channel's calibration (µs; PX4's RCn_*).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RcChannelConfig {
    pub min_us: f64,
    pub max_us: f64,
    pub trim_us: f64,
    /// 1 normal, -1 reversed.
    pub rev: f64,
    /// Dead zone around the trim (µs).
    pub dz_us: f64,
}

impl Default for RcChannelConfig {
    fn default() -> Self {
        Self { min_us: 1000.0, max_us: 2000.0, trim_us: 1500.0, rev: 1.0, dz_us: 10.0 }
    }
}

impl RcChannelConfig {
    /// The channel in [-1, 1] about its trim (PX4's rc_update scaling), reversed if REV is -1.
    #[must_use]
    pub fn centred(&self, pwm_us: u16) -> f64 {
        let v = f64::from(pwm_us);
        let (lo, hi) = (self.trim_us - self.dz_us, self.trim_us + self.dz_us);
        let x = if v > hi {
            (v - hi) / (self.max_us - hi)
        } else if v < lo {
            (v - lo) / (lo - self.min_us)
        } else {
            0.0
        };
        (x * self.rev).clamp(-1.0, 1.0)
    }

    /// The channel in [0, 1] from MIN to MAX (the throttle), reversed if REV is -1.
    #[must_use]
    pub fn unipolar(&self, pwm_us: u16) -> f64 {
        let x = ((f64::from(pwm_us) - self.min_us) / (self.max_us - self.min_us)).clamp(0.0, 1.0);
        if self.rev < 0.0 { 1.0 - x } else { x }
    }
}

/// Which channel (1-18; 0 none) carries what (PX4's RC_MAP_*).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RcMap {
    pub roll: u32,
    pub pitch: u32,
    pub yaw: u32,
    pub throttle: u32,
    /// The mode switch: six slots, COM_FLTMODE1..6.
    pub fltmode: u32,
    pub kill_sw: u32,
    pub arm_sw: u32,
}

impl Default for RcMap {
    /// Mode 2 AETR on channels 1-4 (roll, pitch, throttle, yaw), no switches.
    fn default() -> Self {
        Self { roll: 1, pitch: 2, throttle: 3, yaw: 4, fltmode: 0, kill_sw: 0, arm_sw: 0 }
    }
}

/// The radio: channel calibration and map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RcConfig {
    pub channels: [RcChannelConfig; RC_CHANNELS_MAX],
    pub map: RcMap,
}

impl Default for RcConfig {
    fn default() -> Self {
        Self { channels: [RcChannelConfig::default(); RC_CHANNELS_MAX], map: RcMap::default() }
    }
}

/// A radio setting that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RcConfigError {
    #[error(
        "RC{channel}: MIN {min_us} < TRIM {trim_us} < MAX {max_us} must hold, with DZ {dz_us} below (MAX - MIN) / 2"
    )]
    Calibration { channel: usize, min_us: f64, trim_us: f64, max_us: f64, dz_us: f64 },
    #[error("RC{channel}_REV = {rev} must be 1 or -1")]
    Reverse { channel: usize, rev: f64 },
    #[error("{name} = {channel} must be 0 (none) to 18")]
    Map { name: &'static str, channel: u32 },
}

/// The switches' positions in a frame (None: not mapped, or the channel missing).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Switches {
    /// The mode switch's slot, 0-5 (COM_FLTMODE1..6).
    pub mode_slot: Option<u8>,
    pub kill: Option<bool>,
    pub arm: Option<bool>,
}

/// A switch is on in its upper half (PX4's switch threshold, 3-position switches: the top position).
const SWITCH_ON: f64 = 0.5;

impl RcConfig {
    /// Checks every channel's calibration and the map.
    ///
    /// # Errors
    /// [`RcConfigError`] naming the first channel or map entry that cannot be used.
    pub fn validate(&self) -> Result<(), RcConfigError> {
        for (i, c) in self.channels.iter().enumerate() {
            let ok = [c.min_us, c.max_us, c.trim_us, c.dz_us].iter().all(|v| v.is_finite())
                && c.min_us < c.trim_us
                && c.trim_us < c.max_us
                && c.dz_us >= 0.0
                && c.dz_us < (c.max_us - c.min_us) / 2.0
                && c.trim_us - c.dz_us > c.min_us
                && c.trim_us + c.dz_us < c.max_us;
            if !ok {
                return Err(RcConfigError::Calibration {
                    channel: i + 1,
                    min_us: c.min_us,
                    trim_us: c.trim_us,
                    max_us: c.max_us,
                    dz_us: c.dz_us,
                });
            }
            if c.rev != 1.0 && c.rev != -1.0 {
                return Err(RcConfigError::Reverse { channel: i + 1, rev: c.rev });
            }
        }
        let m = &self.map;
        let entries = [
            ("RC_MAP_ROLL", m.roll),
            ("RC_MAP_PITCH", m.pitch),
            ("RC_MAP_YAW", m.yaw),
            ("RC_MAP_THROTTLE", m.throttle),
            ("RC_MAP_FLTMODE", m.fltmode),
            ("RC_MAP_KILL_SW", m.kill_sw),
            ("RC_MAP_ARM_SW", m.arm_sw),
        ];
        for (name, channel) in entries {
            if channel as usize > RC_CHANNELS_MAX {
                return Err(RcConfigError::Map { name, channel });
            }
        }
        Ok(())
    }

    /// The PWM of the channel mapped as `mapped` (0: none) and its calibration.
    fn channel(&self, frame: &RcFrame, mapped: u32) -> Option<(u16, &RcChannelConfig)> {
        let n = u8::try_from(mapped).ok().filter(|&n| n >= 1 && usize::from(n) <= RC_CHANNELS_MAX)?;
        frame.channel_us(n).map(|v| (v, &self.channels[usize::from(n) - 1]))
    }

    /// The sticks a frame carries; None when any of the four stick channels is unmapped or missing.
    #[must_use]
    pub fn sticks(&self, frame: &RcFrame) -> Option<Sticks> {
        let m = &self.map;
        let centred = |mapped| self.channel(frame, mapped).map(|(v, c)| c.centred(v));
        let (t, tc) = self.channel(frame, m.throttle)?;
        Some(Sticks {
            roll: centred(m.roll)?,
            pitch: centred(m.pitch)?,
            yaw: centred(m.yaw)?,
            throttle: tc.unipolar(t),
        })
    }

    /// The switches' positions in a frame.
    #[must_use]
    pub fn switches(&self, frame: &RcFrame) -> Switches {
        let m = &self.map;
        let on = |mapped| self.channel(frame, mapped).map(|(v, c)| c.centred(v) >= SWITCH_ON);
        let mode_slot = self.channel(frame, m.fltmode).map(|(v, c)| mode_slot(c.centred(v)));
        Switches { mode_slot, kill: on(m.kill_sw), arm: on(m.arm_sw) }
    }
}

/// PX4's six-slot mode switch: the channel's [-1, 1] as [0, 1], in six slots centred on 0, 1/5, ... 1,
/// so a three-position switch (1000, 1500, 2000 µs) selects slots 0, 3 and 5 (COM_FLTMODE1, 4, 6).
#[must_use]
pub fn mode_slot(centred: f64) -> u8 {
    const SLOTS: f64 = 6.0;
    let x = (centred.clamp(-1.0, 1.0) + 1.0) / 2.0;
    ((x + 0.5 / SLOTS) * SLOTS).floor().clamp(0.0, SLOTS - 1.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_channel_is_centred_on_its_trim_with_a_dead_zone_and_reversible() {
        let c = RcChannelConfig::default();
        assert_eq!(c.centred(1500), 0.0);
        assert_eq!(c.centred(1509), 0.0);
        assert_eq!(c.centred(2000), 1.0);
        assert_eq!(c.centred(1000), -1.0);
        assert!((c.centred(1755) - 0.5).abs() < 1e-12);
        let rev = RcChannelConfig { rev: -1.0, ..c };
        assert_eq!(rev.centred(2000), -1.0);
        assert_eq!(c.unipolar(1000), 0.0);
        assert_eq!(c.unipolar(1750), 0.75);
        assert_eq!(rev.unipolar(1750), 0.25);
    }

    #[test]
    fn the_default_map_reads_mode_2_aetr() {
        let rc = RcConfig::default();
        let frame = RcFrame::of(&[2000, 1000, 1750, 1500, 1000, 1000, 1000, 1000]);
        let s = rc.sticks(&frame).unwrap();
        assert_eq!((s.roll, s.pitch, s.throttle, s.yaw), (1.0, -1.0, 0.75, 0.0));
        // Fewer channels than the map needs: no sticks.
        assert_eq!(rc.sticks(&RcFrame::of(&[1500, 1500, 1500])), None);
    }

    #[test]
    fn a_three_position_mode_switch_selects_slots_1_4_and_6() {
        let rc =
            RcConfig { map: RcMap { fltmode: 5, kill_sw: 6, arm_sw: 7, ..RcMap::default() }, ..RcConfig::default() };
        let slot = |pwm| rc.switches(&RcFrame::of(&[1500, 1500, 1000, 1500, pwm, 1000, 2000])).mode_slot;
        assert_eq!([slot(1000), slot(1500), slot(2000)], [Some(0), Some(3), Some(5)]);
        let sw = rc.switches(&RcFrame::of(&[1500, 1500, 1000, 1500, 1000, 1000, 2000]));
        assert_eq!((sw.kill, sw.arm), (Some(false), Some(true)));
        assert_eq!(RcConfig::default().switches(&RcFrame::of(&[1500; 8])), Switches::default());
    }

    #[test]
    fn a_calibration_that_cannot_scale_is_refused() {
        let mut rc = RcConfig::default();
        rc.channels[2].trim_us = 900.0;
        assert!(matches!(rc.validate(), Err(RcConfigError::Calibration { channel: 3, .. })));
        let mut rc = RcConfig::default();
        rc.channels[0].rev = 0.5;
        assert!(matches!(rc.validate(), Err(RcConfigError::Reverse { channel: 1, .. })));
        let rc = RcConfig { map: RcMap { kill_sw: 19, ..RcMap::default() }, ..RcConfig::default() };
        assert!(matches!(rc.validate(), Err(RcConfigError::Map { name: "RC_MAP_KILL_SW", .. })));
        assert_eq!(RcConfig::default().validate(), Ok(()));
    }
}
