//! Manual control: the pilot's sticks and switches, from the radio on the airframe (`RC_CHANNELS` on the
//! plant link, or `RC_CHANNELS_OVERRIDE` from a ground station, PX4's "RC") and from a ground station's
//! joystick (`MANUAL_CONTROL`, PX4's "MAVLink"), as one type. In: raw [`RcFrame`]s (PWM µs per channel)
//! and [`Sticks`] as a joystick sends them, with the vehicle time they arrived. Out ([`ManualInput`]): the
//! sticks in use (fresh, from the source `COM_RC_IN_MODE` chooses), the switch positions, and the pilot's
//! [`PilotAction`]s (a mode-switch slot, kill switch, arm switch, arming gesture), each once, on its edge.
//!
//! `rc` maps and calibrates the radio (PX4's `RC_MAP_*` and `RCn_MIN/MAX/TRIM/REV/DZ`); `input` keeps
//! freshness (`COM_RC_LOSS_T`), the source choice, the switch edges and the gestures (`MAN_ARM_GESTURE`).

use serde::{Deserialize, Serialize};

pub mod input;
pub mod rc;

pub use input::{ManualConfig, ManualInput, ManualSource, ManualStatus, PilotAction, RcInMode};
pub use rc::{RcChannelConfig, RcConfig, RcMap};

/// How many RC channels a frame carries at most (RC_CHANNELS' 18).
pub const RC_CHANNELS_MAX: usize = 18;

/// One frame of the radio receiver: PWM per channel (µs; 0 where the receiver has no value), how many
/// channels it has, and the signal strength (0-254, 255 unknown), as RC_CHANNELS carries them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RcFrame {
    pub channels_us: [u16; RC_CHANNELS_MAX],
    pub count: u8,
    pub rssi: u8,
}

impl Default for RcFrame {
    fn default() -> Self {
        Self { channels_us: [0; RC_CHANNELS_MAX], count: 0, rssi: u8::MAX }
    }
}

impl RcFrame {
    /// A frame of `channels_us` (at most 18; the rest 0), signal strength unknown.
    #[must_use]
    pub fn of(channels_us: &[u16]) -> Self {
        let mut frame = Self::default();
        let n = channels_us.len().min(RC_CHANNELS_MAX);
        frame.channels_us[..n].copy_from_slice(&channels_us[..n]);
        frame.count = n as u8;
        frame
    }

    /// Channel `n` (1-based) in µs, if the frame has it and it carries a value.
    #[must_use]
    pub fn channel_us(&self, n: u8) -> Option<u16> {
        let i = usize::from(n).checked_sub(1)?;
        (i < usize::from(self.count.min(RC_CHANNELS_MAX as u8)))
            .then(|| self.channels_us[i])
            .filter(|&v| v != 0 && v != u16::MAX)
    }
}

/// The four sticks, as PX4's `manual_control_setpoint`: roll (+ right), pitch (+ forward, nose down) and
/// yaw (+ right) in [-1, 1], throttle in [0, 1] (0.5 is centre, where Altitude and Position hold).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sticks {
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    pub throttle: f64,
}

impl Default for Sticks {
    /// Centred, throttle at half (PX4's hold point for Altitude and Position).
    fn default() -> Self {
        Self { roll: 0.0, pitch: 0.0, yaw: 0.0, throttle: 0.5 }
    }
}

impl Sticks {
    /// Clamped into range; `None` when any value is not a number.
    #[must_use]
    pub fn sanitized(self) -> Option<Self> {
        let all = [self.roll, self.pitch, self.yaw, self.throttle];
        all.iter().all(|v| v.is_finite()).then(|| Self {
            roll: self.roll.clamp(-1.0, 1.0),
            pitch: self.pitch.clamp(-1.0, 1.0),
            yaw: self.yaw.clamp(-1.0, 1.0),
            throttle: self.throttle.clamp(0.0, 1.0),
        })
    }

    /// MANUAL_CONTROL as PX4 reads it: x pitch, y roll, r yaw in [-1000, 1000], z throttle in [0, 1000];
    /// an axis the sender marks invalid (`i16::MAX`) reads as centred.
    #[must_use]
    pub fn from_manual_control(x: i16, y: i16, z: i16, r: i16) -> Self {
        let axis = |v: i16, centre: f64| if v == i16::MAX { centre } else { f64::from(v) / 1000.0 };
        Self { pitch: axis(x, 0.0), roll: axis(y, 0.0), throttle: axis(z, 0.5), yaw: axis(r, 0.0) }
            .sanitized()
            .unwrap_or_default()
    }

    /// The MANUAL_CONTROL axes (x, y, z, r) of these sticks (telemetry, and ground-station tools).
    #[must_use]
    pub fn to_manual_control(&self) -> (i16, i16, i16, i16) {
        let s = |v: f64| (v * 1000.0).round().clamp(-1000.0, 1000.0) as i16;
        (s(self.pitch), s(self.roll), s(self.throttle), s(self.yaw))
    }
}

/// PX4's stick shaping (`math::expo_deadzone`): a dead zone `dz` around centre, the rest rescaled to the
/// full range, then the cubic expo `(1 - e) x + e x³`. `x`, `dz` in [-1, 1] / [0, 1), `e` in [0, 1].
#[must_use]
pub fn expo_deadzone(x: f64, expo: f64, dz: f64) -> f64 {
    let x = x.clamp(-1.0, 1.0);
    let dz = dz.clamp(0.0, 0.99);
    let e = expo.clamp(0.0, 1.0);
    let y = if x.abs() <= dz { 0.0 } else { (x - dz * x.signum()) / (1.0 - dz) };
    (1.0 - e) * y + e * y * y * y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_control_axes_map_as_px4_reads_them() {
        let s = Sticks::from_manual_control(500, -250, 750, 1000);
        assert_eq!(s, Sticks { pitch: 0.5, roll: -0.25, throttle: 0.75, yaw: 1.0 });
        assert_eq!(s.to_manual_control(), (500, -250, 750, 1000));
        // Out of range clamps; invalid axes read as centred.
        let s = Sticks::from_manual_control(-2000, i16::MAX, 1500, i16::MAX);
        assert_eq!(s, Sticks { pitch: -1.0, roll: 0.0, throttle: 1.0, yaw: 0.0 });
    }

    #[test]
    fn expo_deadzone_is_zero_inside_the_dead_zone_and_full_at_the_ends() {
        assert_eq!(expo_deadzone(0.05, 0.6, 0.1), 0.0);
        assert!((expo_deadzone(1.0, 0.6, 0.1) - 1.0).abs() < 1e-12);
        assert!((expo_deadzone(-1.0, 0.6, 0.1) + 1.0).abs() < 1e-12);
        // Half stick with a 0.1 dead zone and no expo: (0.5 - 0.1) / 0.9.
        assert!((expo_deadzone(0.5, 0.0, 0.1) - 0.4 / 0.9).abs() < 1e-12);
    }

    #[test]
    fn a_channel_is_read_only_when_the_frame_has_it() {
        let f = RcFrame::of(&[1500, 0, 1200]);
        assert_eq!(f.channel_us(1), Some(1500));
        assert_eq!(f.channel_us(2), None);
        assert_eq!(f.channel_us(3), Some(1200));
        assert_eq!(f.channel_us(4), None);
        assert_eq!(f.channel_us(0), None);
    }
}
