//! The motor test (PX4's actuator test, MAV_CMD_ACTUATOR_TEST and MAV_CMD_DO_MOTOR_TEST): one motor at a
//! fraction of its output range for a time, on vehicle time, while disarmed. In: the decoded
//! [`MotorTestRequest`]s (the vehicle has already refused them when armed or COM_MOT_TEST_EN is not 1),
//! and per step the vehicle time and whether it is armed. Out: the four PWM commands while a test runs
//! (the tested motor at `1000 + 1000·thrust` µs, the others at 1000), `None` otherwise.
//!
//! One motor at a time: a new test replaces the running one (PX4 keeps every output it was asked to
//! test); a stop for the running motor ends it (one naming another motor changes nothing); the test ends
//! at its timeout (the first step after `start + timeout`, PX4's `now > timeout`), whenever the vehicle
//! is armed, and at any disarm, kill or flight termination command ([`MotorTest::stop`]: whoever sends
//! one wants the motors stopped).

use crate::core::control::distributor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US};
use crate::core::mavlink::MotorTestRequest;

/// A test running: the motor (0-based output), its PWM (µs) and the last vehicle time it runs at (µs).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Running {
    index: usize,
    pwm_us: f64,
    until_us: u64,
}

/// The motor test. See the module docs.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct MotorTest {
    running: Option<Running>,
    /// The PWM it gave at the last step (None: no test ran then).
    last_pwm_us: Option<[f64; 4]>,
}

impl MotorTest {
    /// A request accepted at `now_us`.
    pub fn request(&mut self, now_us: u64, request: MotorTestRequest) {
        match request {
            MotorTestRequest::Run { motor, thrust, timeout_us } => {
                let thrust = if thrust.is_finite() { thrust.clamp(0.0, 1.0) } else { 0.0 };
                self.running = Some(Running {
                    index: usize::from(motor.saturating_sub(1)).min(3),
                    pwm_us: MOTOR_PWM_MIN_US + (MOTOR_PWM_MAX_US - MOTOR_PWM_MIN_US) * thrust,
                    until_us: now_us.saturating_add(timeout_us),
                });
            }
            MotorTestRequest::Stop { motor } => {
                if self.running.is_some_and(|r| r.index + 1 == usize::from(motor)) {
                    self.running = None;
                }
            }
        }
    }

    /// Ends any test (from the next step).
    pub fn stop(&mut self) {
        self.running = None;
    }

    /// One step at `now_us`: the PWM while a test runs (it ends when `armed` or past its timeout).
    pub fn step(&mut self, now_us: u64, armed: bool) -> Option<[f64; 4]> {
        if armed || self.running.is_some_and(|r| now_us > r.until_us) {
            self.running = None;
        }
        self.last_pwm_us = self.running.map(|r| {
            let mut pwm_us = [MOTOR_PWM_MIN_US; 4];
            pwm_us[r.index] = r.pwm_us;
            pwm_us
        });
        self.last_pwm_us
    }

    /// The PWM the test gave at the last step, if it ran then.
    pub fn last_pwm_us(&self) -> Option<[f64; 4]> {
        self.last_pwm_us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_a_run_when_stepped_then_only_its_motor_moves_until_the_timeout_then_all_stop() {
        let mut t = MotorTest::default();
        t.request(1_000, MotorTestRequest::Run { motor: 3, thrust: 0.2, timeout_us: 2_000_000 });
        assert_eq!(t.step(3_000, false), Some([1000.0, 1000.0, 1200.0, 1000.0]));
        assert_eq!(t.step(2_001_000, false), Some([1000.0, 1000.0, 1200.0, 1000.0]), "still at start + timeout");
        assert_eq!(t.step(2_003_000, false), None, "ended after it");
        assert_eq!(t.last_pwm_us(), None);
    }

    #[test]
    fn given_a_running_test_when_armed_or_stopped_then_it_ends_and_a_stop_for_another_motor_changes_nothing() {
        let mut t = MotorTest::default();
        let run = |motor| MotorTestRequest::Run { motor, thrust: 1.0, timeout_us: 3_000_000 };
        t.request(0, run(1));
        t.request(0, run(2));
        assert_eq!(t.step(2_000, false), Some([1000.0, 2000.0, 1000.0, 1000.0]), "the new test replaced the old");
        t.request(2_000, MotorTestRequest::Stop { motor: 1 });
        assert!(t.step(4_000, false).is_some());
        t.request(4_000, MotorTestRequest::Stop { motor: 2 });
        assert_eq!(t.step(6_000, false), None);
        t.request(6_000, run(4));
        assert_eq!(t.step(8_000, true), None, "arming ends it");
        assert_eq!(t.step(10_000, false), None, "and it does not resume");
    }
}
