//! `HIL_ACTUATOR_CONTROLS`: the autopilot's four motor commands ([`ActuatorCommand`]), the armed and
//! motor-test flags, and the PWM <-> control mapping.

use mavlink::dialects::common::{HIL_ACTUATOR_CONTROLS_DATA, HilActuatorControlsFlags, MavModeFlag};

/// The motor command range (µs), the distributor's: `controls[i] = (pwm_us - MOTOR_PWM_MIN_US) / (MOTOR_PWM_MAX_US -
/// MOTOR_PWM_MIN_US)`.
pub use crate::core::control::distributor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US};

/// `MAV_MODE_FLAG_SAFETY_ARMED` in `HIL_ACTUATOR_CONTROLS.mode`.
pub const MODE_FLAG_SAFETY_ARMED: u8 = 128;

/// Motor command PWM (µs) -> HIL control in [0, 1]: non-finite -> 1000 µs, clamped to 1000-2000 µs.
#[must_use]
pub fn pwm_us_to_control(pwm_us: f64) -> f32 {
    let pwm_us = if pwm_us.is_finite() { pwm_us.clamp(MOTOR_PWM_MIN_US, MOTOR_PWM_MAX_US) } else { MOTOR_PWM_MIN_US };
    ((pwm_us - MOTOR_PWM_MIN_US) / (MOTOR_PWM_MAX_US - MOTOR_PWM_MIN_US)) as f32
}

/// HIL control -> PWM (µs): non-finite -> 1000 µs, clamped to [0, 1] (negative reverse-thrust values of
/// other vehicles mean 1000 µs here).
#[must_use]
pub fn control_to_pwm_us(control: f32) -> f64 {
    let control = if control.is_finite() { f64::from(control).clamp(0.0, 1.0) } else { 0.0 };
    MOTOR_PWM_MIN_US + control * (MOTOR_PWM_MAX_US - MOTOR_PWM_MIN_US)
}
// ---------------------------------------------------------------------------------------------------------
// HIL_ACTUATOR_CONTROLS
// ---------------------------------------------------------------------------------------------------------

/// The autopilot's answer to one sensor sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorCommand {
    /// The `time_usec` of the `HIL_SENSOR` this answers (µs, the plant's clock).
    pub time_us: u64,
    /// Motor commands of the paper's rotors 1..4 (µs, 1000-2000).
    pub pwm_us: [f64; 4],
    /// `MAV_MODE_FLAG_SAFETY_ARMED`.
    pub armed: bool,
    /// `MAV_MODE_FLAG_TEST_ENABLED`: a motor test drives the outputs of the disarmed vehicle.
    pub motor_test: bool,
}

impl ActuatorCommand {
    /// Whether the motors run on `pwm_us`: armed, or a motor test (see "Who runs the motors" in [`crate::core::plant_link`]).
    #[must_use]
    pub fn motors_running(&self) -> bool {
        self.armed || self.motor_test
    }

    /// What the motors get: `pwm_us` while they run, 1000 µs each otherwise.
    #[must_use]
    pub fn effective_pwm_us(&self) -> [f64; 4] {
        if self.motors_running() { self.pwm_us } else { [MOTOR_PWM_MIN_US; 4] }
    }
}

/// [`ActuatorCommand`] -> `HIL_ACTUATOR_CONTROLS`: `controls[0..4]` from the PWM (see [`pwm_us_to_control`]),
/// the rest 0; `mode` = SAFETY_ARMED when armed, TEST_ENABLED during a motor test, else empty; `flags` =
/// LOCKSTEP.
#[must_use]
pub fn encode_actuator_controls(cmd: &ActuatorCommand) -> HIL_ACTUATOR_CONTROLS_DATA {
    let mut controls = [0.0_f32; 16];
    for (control, pwm_us) in controls.iter_mut().zip(cmd.pwm_us) {
        *control = pwm_us_to_control(pwm_us);
    }
    HIL_ACTUATOR_CONTROLS_DATA {
        time_usec: cmd.time_us,
        flags: HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP,
        controls,
        mode: (if cmd.armed { MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED } else { MavModeFlag::empty() })
            | if cmd.motor_test { MavModeFlag::MAV_MODE_FLAG_TEST_ENABLED } else { MavModeFlag::empty() },
    }
}

/// `HIL_ACTUATOR_CONTROLS` -> [`ActuatorCommand`] (see [`control_to_pwm_us`]).
#[must_use]
pub fn decode_actuator_controls(msg: &HIL_ACTUATOR_CONTROLS_DATA) -> ActuatorCommand {
    ActuatorCommand {
        time_us: msg.time_usec,
        pwm_us: [0, 1, 2, 3].map(|i| control_to_pwm_us(msg.controls[i])),
        armed: msg.mode.bits() & MODE_FLAG_SAFETY_ARMED != 0,
        motor_test: msg.mode.contains(MavModeFlag::MAV_MODE_FLAG_TEST_ENABLED),
    }
}
