//! PX4-like landing detection from the estimate. In, once per commander step: the time (`now_us`, µs), the
//! NED velocity (m/s), the down position and the ground's down position (m), whether the collective thrust
//! is at its minimum, and whether the vehicle is armed. Out: landed or not. Ground contact is
//! |v_D| < `max_vel_d_mps`, horizontal speed < `max_vel_ne_mps` and (low thrust, or within `ground_height_m`
//! of the ground); held for `dwell_s` it means landed. Any failing condition means in the air at once (PX4
//! releases faster than it sets, too). Disarmed means landed. Non-finite inputs are never ground contact.

use crate::core::seconds_to_us;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The detector's thresholds (PX4 `LNDMC_*` in spirit; tighter, as the brief asks).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LandDetectorConfig {
    /// Largest |v_D| of ground contact (m/s).
    pub max_vel_d_mps: f64,
    /// Largest horizontal speed of ground contact (m/s).
    pub max_vel_ne_mps: f64,
    /// Height above the ground within which the vehicle counts as down (m).
    pub ground_height_m: f64,
    /// How long ground contact must last to declare landed (s).
    pub dwell_s: f64,
}

impl Default for LandDetectorConfig {
    fn default() -> Self {
        Self { max_vel_d_mps: 0.2, max_vel_ne_mps: 0.5, ground_height_m: 0.1, dwell_s: 0.5 }
    }
}

/// One input sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandDetectorSample {
    pub vel_ned_mps: Vector3<f64>,
    pub pos_d_m: f64,
    /// The ground's down coordinate (m, NED), when known.
    pub ground_d_m: Option<f64>,
    /// The collective thrust is at its minimum.
    pub throttle_low: bool,
    pub armed: bool,
}

/// What a phase of flight makes of the detector's answer (EXTENDED_SYS_STATE).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LandedState {
    Undefined,
    OnGround,
    InAir,
    Takeoff,
    Landing,
}

/// The flight phase the commander is running, for [`LandDetector::landed_state`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Takeoff,
    Landing,
    Other,
}

/// The detector's state: whether landed, since when ground contact has lasted, since when landed.
#[derive(Debug, Clone, PartialEq)]
pub struct LandDetector {
    config: LandDetectorConfig,
    landed: bool,
    contact_since_us: Option<u64>,
    landed_since_us: Option<u64>,
    updated: bool,
}

impl LandDetector {
    /// Starts landed (a vehicle boots on the ground), with no sample yet.
    #[must_use]
    pub fn new(config: LandDetectorConfig) -> Self {
        Self { config, landed: true, contact_since_us: None, landed_since_us: None, updated: false }
    }

    /// New thresholds, from the next update (the landed state and its timers carry on).
    pub fn set_config(&mut self, config: LandDetectorConfig) {
        self.config = config;
    }

    /// Takes one sample; returns whether landed.
    pub fn update(&mut self, now_us: u64, s: &LandDetectorSample) -> bool {
        self.updated = true;
        if !s.armed {
            self.contact_since_us.get_or_insert(now_us);
            if !self.landed {
                self.landed = true;
                self.landed_since_us = Some(now_us);
            }
            self.landed_since_us.get_or_insert(now_us);
            return true;
        }
        let contact = self.ground_contact(s);
        if self.landed && !contact && s.throttle_low {
            // Landed with the motors at their minimum: a bounce or a slide is still a landing, not a
            // takeoff (which needs thrust).
            return true;
        }
        if contact {
            let since = *self.contact_since_us.get_or_insert(now_us);
            if !self.landed && now_us.saturating_sub(since) >= seconds_to_us(self.config.dwell_s) {
                self.landed = true;
                self.landed_since_us = Some(now_us);
            }
        } else {
            self.contact_since_us = None;
            self.landed = false;
            self.landed_since_us = None;
        }
        self.landed
    }

    fn ground_contact(&self, s: &LandDetectorSample) -> bool {
        let c = &self.config;
        let v = s.vel_ned_mps;
        if !(v.iter().all(|x| x.is_finite()) && s.pos_d_m.is_finite()) {
            return false;
        }
        let slow = v.z.abs() < c.max_vel_d_mps && v.xy().norm() < c.max_vel_ne_mps;
        let near_ground = s.ground_d_m.is_some_and(|g| g.is_finite() && (s.pos_d_m - g).abs() <= c.ground_height_m);
        slow && (s.throttle_low || near_ground)
    }

    #[must_use]
    pub fn landed(&self) -> bool {
        self.landed
    }

    /// When the detector last declared landed (µs), while it still says so.
    #[must_use]
    pub fn landed_since_us(&self) -> Option<u64> {
        if self.landed { self.landed_since_us } else { None }
    }

    /// EXTENDED_SYS_STATE's view: TAKEOFF throughout a takeoff, LANDING while landing and not yet down,
    /// ON_GROUND / IN_AIR otherwise; UNDEFINED before the first sample.
    #[must_use]
    pub fn landed_state(&self, phase: Phase) -> LandedState {
        match (self.updated, phase, self.landed) {
            (false, _, _) => LandedState::Undefined,
            (true, Phase::Takeoff, _) => LandedState::Takeoff,
            (true, Phase::Landing, false) => LandedState::Landing,
            (true, _, true) => LandedState::OnGround,
            (true, _, false) => LandedState::InAir,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEP_US: u64 = 10_000;

    fn sample(vel_d: f64, pos_d: f64, throttle_low: bool) -> LandDetectorSample {
        LandDetectorSample {
            vel_ned_mps: Vector3::new(0.0, 0.0, vel_d),
            pos_d_m: pos_d,
            ground_d_m: Some(0.0),
            throttle_low,
            armed: true,
        }
    }

    /// Feeds `s` every 10 ms from `from_us` for `dur_us`; returns the first time it said landed, if any.
    fn run(d: &mut LandDetector, from_us: u64, dur_us: u64, s: &LandDetectorSample) -> Option<u64> {
        (0..=dur_us / STEP_US).map(|i| from_us + i * STEP_US).find(|&t| d.update(t, s))
    }

    fn airborne() -> LandDetector {
        let mut d = LandDetector::new(LandDetectorConfig::default());
        assert!(!d.update(0, &sample(-1.0, -3.0, false)));
        d
    }

    #[test]
    fn given_still_on_the_ground_when_half_a_second_passes_then_landed_exactly_after_the_dwell() {
        let mut d = airborne();
        let t = run(&mut d, 1_000_000, 2_000_000, &sample(0.0, 0.0, false));
        assert_eq!(t, Some(1_500_000));
        assert_eq!(d.landed_since_us(), Some(1_500_000));
    }

    #[test]
    fn given_low_thrust_and_still_above_the_ground_then_landed_after_the_dwell() {
        let mut d = airborne();
        assert_eq!(run(&mut d, 0, 1_000_000, &sample(0.05, -2.0, true)), Some(500_000));
    }

    #[test]
    fn given_a_hover_in_the_air_then_never_landed() {
        let mut d = airborne();
        assert_eq!(run(&mut d, 0, 5_000_000, &sample(0.0, -2.0, false)), None);
        assert_eq!(d.landed_state(Phase::Other), LandedState::InAir);
    }

    #[test]
    fn given_a_descent_faster_than_the_threshold_near_the_ground_then_not_landed() {
        let mut d = airborne();
        assert_eq!(run(&mut d, 0, 2_000_000, &sample(0.3, -0.05, true)), None);
        let mut s = sample(0.0, 0.0, true);
        s.vel_ned_mps.x = 0.6;
        assert_eq!(run(&mut d, 0, 2_000_000, &s), None);
    }

    #[test]
    fn given_contact_interrupted_before_the_dwell_then_the_dwell_restarts() {
        let mut d = airborne();
        assert_eq!(run(&mut d, 0, 400_000, &sample(0.0, 0.0, false)), None);
        assert!(!d.update(410_000, &sample(0.5, 0.0, false)));
        assert_eq!(run(&mut d, 420_000, 2_000_000, &sample(0.0, 0.0, false)), Some(920_000));
    }

    #[test]
    fn given_landed_when_the_vehicle_climbs_then_in_air_at_once() {
        let mut d = airborne();
        run(&mut d, 0, 1_000_000, &sample(0.0, 0.0, false));
        assert!(d.landed());
        assert!(!d.update(1_010_000, &sample(-0.5, -0.02, false)));
        assert_eq!(d.landed_since_us(), None);
    }

    #[test]
    fn given_disarmed_then_landed_immediately_and_non_finite_input_is_never_contact() {
        let mut d = airborne();
        let mut s = sample(-3.0, -10.0, false);
        s.armed = false;
        assert!(d.update(7, &s));
        let mut d = airborne();
        assert_eq!(run(&mut d, 0, 2_000_000, &sample(f64::NAN, 0.0, true)), None);
    }

    #[test]
    fn given_each_phase_then_the_landed_state_follows_the_detector() {
        let mut d = LandDetector::new(LandDetectorConfig::default());
        assert_eq!(d.landed_state(Phase::Other), LandedState::Undefined);
        d.update(0, &sample(0.0, 0.0, false));
        d.update(600_000, &sample(0.0, 0.0, false));
        assert_eq!(d.landed_state(Phase::Other), LandedState::OnGround);
        assert_eq!(d.landed_state(Phase::Takeoff), LandedState::Takeoff);
        assert_eq!(d.landed_state(Phase::Landing), LandedState::OnGround);
        d.update(610_000, &sample(0.5, -1.0, false));
        assert_eq!(d.landed_state(Phase::Other), LandedState::InAir);
        assert_eq!(d.landed_state(Phase::Landing), LandedState::Landing);
    }
}
