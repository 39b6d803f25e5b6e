//! Short history of the estimated NED position (m) and velocity (m/s), one entry per IMU sample
//! (time in µs), kept for [`HISTORY_SPAN_US`], so that a delayed GPS measurement can be compared with the
//! state at the time it was valid.
//!
//! Corrections applied to the current state after an entry was recorded (every measurement update and
//! reset) are accumulated and added to the entries on look-up: the delayed state is "what we now believe
//! the state was then". This is the constant-error approximation: the correction is taken to hold over the
//! delay, which is sound while the delay (~0.1 s) is short against the filter's error dynamics (seconds),
//! and costs O(1) per correction whatever the IMU rate.

use std::collections::VecDeque;

use nalgebra::Vector3;

/// How far back the history reaches (µs): GPS older than this cannot be fused.
pub const HISTORY_SPAN_US: u64 = 500_000;

#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    time_us: u64,
    pos_ned_m: Vector3<f64>,
    vel_ned_mps: Vector3<f64>,
    /// The correction accumulators when the entry was recorded.
    pos_correction_m: Vector3<f64>,
    vel_correction_mps: Vector3<f64>,
}

/// The delayed-state buffer.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct History {
    entries: VecDeque<Entry>,
    pos_correction_m: Vector3<f64>,
    vel_correction_mps: Vector3<f64>,
}

impl History {
    /// Records the state at `time_us` (after the prediction to it) and forgets entries beyond the span.
    pub fn push(&mut self, time_us: u64, pos_ned_m: &Vector3<f64>, vel_ned_mps: &Vector3<f64>) {
        self.entries.push_back(Entry {
            time_us,
            pos_ned_m: *pos_ned_m,
            vel_ned_mps: *vel_ned_mps,
            pos_correction_m: self.pos_correction_m,
            vel_correction_mps: self.vel_correction_mps,
        });
        while self.entries.front().is_some_and(|e| e.time_us + HISTORY_SPAN_US < time_us) {
            self.entries.pop_front();
        }
    }

    /// Notes a correction just applied to the current state.
    pub fn add_correction(&mut self, dpos_ned_m: &Vector3<f64>, dvel_ned_mps: &Vector3<f64>) {
        self.pos_correction_m += dpos_ned_m;
        self.vel_correction_mps += dvel_ned_mps;
    }

    fn corrected(&self, e: &Entry) -> (Vector3<f64>, Vector3<f64>) {
        (
            e.pos_ned_m + (self.pos_correction_m - e.pos_correction_m),
            e.vel_ned_mps + (self.vel_correction_mps - e.vel_correction_mps),
        )
    }

    /// The corrected position and velocity at `time_us`, linearly interpolated between entries; the newest
    /// entry (the current state) for times at or after it; `None` when empty or older than the oldest.
    #[must_use]
    pub fn state_at(&self, time_us: u64) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let newest = self.entries.back()?;
        if time_us >= newest.time_us {
            return Some(self.corrected(newest));
        }
        let after = self.entries.partition_point(|e| e.time_us <= time_us);
        if after == 0 {
            return None;
        }
        let (e0, e1) = (&self.entries[after - 1], &self.entries[after]);
        let (p0, v0) = self.corrected(e0);
        let (p1, v1) = self.corrected(e1);
        let w = (time_us - e0.time_us) as f64 / (e1.time_us - e0.time_us) as f64;
        Some((p0 + (p1 - p0) * w, v0 + (v1 - v0) * w))
    }

    /// Forgets everything.
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> History {
        // 1 m/s north, one entry every 2 ms for 1 s.
        let mut h = History::default();
        for k in 0..=500_u32 {
            let t_s = f64::from(k) * 0.002;
            h.push(u64::from(k) * 2000, &Vector3::new(t_s, 0.0, 0.0), &Vector3::new(1.0, 0.0, 0.0));
        }
        h
    }

    #[test]
    fn given_a_ramp_when_looked_up_between_entries_then_it_interpolates() {
        let h = ramp();
        let (p, v) = h.state_at(901_000).unwrap();
        assert!((p.x - 0.901).abs() < 1e-12, "{p}");
        assert!((v.x - 1.0).abs() < 1e-12);
    }

    #[test]
    fn given_a_time_beyond_the_span_when_looked_up_then_none_and_after_the_newest_then_the_newest() {
        let h = ramp();
        assert!(h.state_at(1_000_000 - HISTORY_SPAN_US - 1).is_none());
        assert!(h.state_at(1_000_000 - HISTORY_SPAN_US).is_some());
        assert!((h.state_at(2_000_000).unwrap().0.x - 1.0).abs() < 1e-12);
    }

    #[test]
    fn given_a_correction_after_recording_when_looked_up_then_old_entries_carry_it() {
        let mut h = ramp();
        h.add_correction(&Vector3::new(0.0, 0.25, 0.0), &Vector3::new(0.0, 0.0, -0.1));
        let (p, v) = h.state_at(900_000).unwrap();
        assert!((p - Vector3::new(0.9, 0.25, 0.0)).norm() < 1e-12, "{p}");
        assert!((v - Vector3::new(1.0, 0.0, -0.1)).norm() < 1e-12, "{v}");
        // An entry recorded after the correction already includes it: not added twice.
        h.push(1_002_000, &Vector3::new(1.002, 0.25, 0.0), &Vector3::new(1.0, 0.0, -0.1));
        let (p, _) = h.state_at(1_002_000).unwrap();
        assert!((p - Vector3::new(1.002, 0.25, 0.0)).norm() < 1e-12, "{p}");
    }
}
