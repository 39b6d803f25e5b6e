//! The attitude failure detector, as PX4's `FailureDetector`: in, the estimated roll and pitch (rad) and
//! vehicle time (µs) once per step, in the air; out, whether the attitude has failed: |roll| above
//! FD_FAIL_R for FD_FAIL_R_TTRI, or |pitch| above FD_FAIL_P for FD_FAIL_P_TTRI (each hysteresis on its
//! own axis; a threshold of 0 switches that axis off, as in PX4). What the vehicle then does (FD_ACT) is
//! the failsafe table's (`failsafe.rs`).

use serde::{Deserialize, Serialize};

use crate::core::seconds_to_us;

/// The detector's parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FailureDetectorConfig {
    /// Roll beyond which the attitude has failed (deg; FD_FAIL_R; 0: off).
    pub roll_max_deg: f64,
    /// Pitch beyond which the attitude has failed (deg; FD_FAIL_P; 0: off).
    pub pitch_max_deg: f64,
    /// How long the roll must stay beyond it (s; FD_FAIL_R_TTRI).
    pub roll_trigger_s: f64,
    /// How long the pitch must stay beyond it (s; FD_FAIL_P_TTRI).
    pub pitch_trigger_s: f64,
    /// What the vehicle does (FD_ACT: 0 only said, 1 land, 2 terminate).
    pub action: u32,
}

impl Default for FailureDetectorConfig {
    /// PX4's thresholds (60°, 0.3 s); termination, the one action that helps a vehicle on its back.
    fn default() -> Self {
        Self { roll_max_deg: 60.0, pitch_max_deg: 60.0, roll_trigger_s: 0.3, pitch_trigger_s: 0.3, action: 2 }
    }
}

/// One axis' hysteresis: since when it has been beyond its threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Axis {
    beyond_since_us: Option<u64>,
}

impl Axis {
    fn update(&mut self, now_us: u64, angle_rad: f64, max_deg: f64, trigger_s: f64) -> bool {
        let beyond = max_deg > 0.0 && (!angle_rad.is_finite() || angle_rad.abs().to_degrees() > max_deg);
        if !beyond {
            self.beyond_since_us = None;
            return false;
        }
        let since = *self.beyond_since_us.get_or_insert(now_us);
        now_us.saturating_sub(since) >= seconds_to_us(trigger_s)
    }
}

/// The detector's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FailureDetector {
    roll: Axis,
    pitch: Axis,
}

impl FailureDetector {
    /// One step in the air: whether the attitude has failed now. NaN angles count as beyond.
    pub fn update(&mut self, now_us: u64, roll_rad: f64, pitch_rad: f64, config: &FailureDetectorConfig) -> bool {
        let roll = self.roll.update(now_us, roll_rad, config.roll_max_deg, config.roll_trigger_s);
        let pitch = self.pitch.update(now_us, pitch_rad, config.pitch_max_deg, config.pitch_trigger_s);
        roll || pitch
    }

    /// On the ground (or disarmed): nothing is watched, the timers restart.
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_a_roll_beyond_60_deg_then_it_fails_after_exactly_0_3_s_and_not_before() {
        let c = FailureDetectorConfig::default();
        let mut fd = FailureDetector::default();
        let roll = 61f64.to_radians();
        assert!(!fd.update(1_000_000, roll, 0.0, &c));
        assert!(!fd.update(1_299_999, roll, 0.0, &c));
        assert!(fd.update(1_300_000, roll, 0.0, &c));
    }

    #[test]
    fn given_the_attitude_comes_back_within_the_trigger_time_then_the_timer_restarts() {
        let c = FailureDetectorConfig::default();
        let mut fd = FailureDetector::default();
        assert!(!fd.update(0, 0.0, -1.2, &c));
        assert!(!fd.update(200_000, 0.0, 0.5, &c));
        assert!(!fd.update(300_000, 0.0, -1.2, &c));
        assert!(!fd.update(599_999, 0.0, -1.2, &c));
        assert!(fd.update(600_000, 0.0, -1.2, &c));
    }

    #[test]
    fn given_a_threshold_of_0_then_that_axis_is_off_and_nan_counts_as_beyond_on_the_other() {
        let c = FailureDetectorConfig { roll_max_deg: 0.0, ..FailureDetectorConfig::default() };
        let mut fd = FailureDetector::default();
        assert!(!fd.update(0, 3.0, 0.0, &c));
        assert!(!fd.update(10_000_000, 3.0, 0.0, &c));
        assert!(!fd.update(10_000_000, 0.0, f64::NAN, &c));
        assert!(fd.update(10_300_000, 0.0, f64::NAN, &c));
    }
}
