//! The control stage: the controller's lifecycle around its update. In, per control tick: the estimate,
//! the commander's output (motors enabled, landed state) and the navigator's reference. Out: four PWM
//! commands (µs, the paper's rotor order), clamped to [1000, 2000] and never NaN; 1000 on every rotor while
//! idle, disarmed or killed, and while on the ground without a valid position. Whenever the motors idle the
//! controller is rebuilt, so nothing adapts or integrates on the ground.

use crate::core::commander::{CommanderOutput, LandedState};
use crate::core::config::{VehicleConfig, VehicleError};
use crate::core::control::distributor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US};
use crate::core::control::{ControlInput, Controller, ControllerConfig, Reference, distributor, try_new_controller};
use crate::core::estimator::EstimatorState;

/// The controller and the PWM it last gave. See the module docs.
pub(crate) struct ControlStage {
    controller: Box<dyn Controller>,
    /// The controller has run since it was last (re)built.
    dirty: bool,
    pwm_us: [f64; 4],
    /// At or below this mean PWM (µs) the thrust counts as low, for the land detector: 30 % of the hover
    /// thrust on the normalized scale (PX4's, 0 at the lowest rotor lift, 1 at the highest), as PX4's land
    /// detector reads "low thrust". The paper's rotors lift 88 % of the hover lift at 1000 µs, so 30 % of
    /// the hover lift itself lies below the lift curve (435 µs) and no command could ever reach it.
    throttle_low_pwm_us: f64,
}

/// The mean PWM (µs) at 30 % of the hover thrust on the normalized scale of `limits`.
fn throttle_low_pwm_us(airframe: &crate::core::control::Airframe, limits: &distributor::ActuatorLimits) -> f64 {
    let span_n = limits.rotor_max_n - limits.rotor_min_n;
    let hover_frac = (airframe.hover_rotor_lift_n() - limits.rotor_min_n) / span_n;
    distributor::pwm_from_lift_us(limits.rotor_min_n + 0.3 * hover_frac * span_n)
}

impl ControlStage {
    /// The controller `config` names, motors at minimum.
    pub fn new(config: &VehicleConfig) -> Result<Self, VehicleError> {
        let controller = try_new_controller(config.controller, &config.control)?;
        let throttle_low_pwm_us = throttle_low_pwm_us(&config.control.aco.airframe, &config.control.aco.limits);
        Ok(Self { controller, dirty: false, pwm_us: [MOTOR_PWM_MIN_US; 4], throttle_low_pwm_us })
    }

    pub fn controller(&self) -> &dyn Controller {
        self.controller.as_ref()
    }

    /// The motor commands of the last step (µs).
    pub fn pwm_us(&self) -> [f64; 4] {
        self.pwm_us
    }

    /// Whether the collective thrust is at its minimum (or not a number).
    pub fn throttle_low(&self) -> bool {
        let mean_pwm_us = self.pwm_us.iter().sum::<f64>() / 4.0;
        mean_pwm_us.is_nan() || mean_pwm_us <= self.throttle_low_pwm_us
    }

    /// New gains and limits from the next update (see [`Controller::reconfigure`]).
    pub fn reconfigure(&mut self, control: &ControllerConfig) {
        self.controller.reconfigure(control);
    }

    /// One step: the controller runs when `tick` (a control sample arrived); the motors stop whenever the
    /// commander disables them. Returns the PWM (µs).
    pub fn step(
        &mut self,
        tick: bool,
        state: &EstimatorState,
        out: &CommanderOutput,
        reference: Option<Reference>,
        config: &VehicleConfig,
    ) -> [f64; 4] {
        if tick {
            self.pwm_us = self.control(state, out, reference, config);
        }
        if !out.motors_enabled {
            self.pwm_us = [MOTOR_PWM_MIN_US; 4];
        }
        self.pwm_us
    }

    /// Rebuilds the controller if it has run, so that no adaptation or integrator carries over.
    fn reset(&mut self, config: &VehicleConfig) {
        if self.dirty
            && let Ok(c) = try_new_controller(config.controller, &config.control)
        {
            self.controller = c;
            self.dirty = false;
        }
    }

    fn control(
        &mut self,
        state: &EstimatorState,
        out: &CommanderOutput,
        reference: Option<Reference>,
        config: &VehicleConfig,
    ) -> [f64; 4] {
        let Some(reference) = reference else {
            self.reset(config);
            return [MOTOR_PWM_MIN_US; 4];
        };
        let on_ground = matches!(out.landed, LandedState::OnGround | LandedState::Undefined);
        if on_ground && !state.flags.position_valid {
            self.reset(config);
            return [MOTOR_PWM_MIN_US; 4];
        }
        let input = ControlInput {
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            euler_rad: state.euler_rad,
            rate_frd_radps: state.rate_frd_radps,
            specific_force_frd_mps2: state.specific_force_frd_mps2,
        };
        self.dirty = true;
        self.controller
            .update(&input, &reference)
            .map(|p| if p.is_finite() { p.clamp(MOTOR_PWM_MIN_US, MOTOR_PWM_MAX_US) } else { MOTOR_PWM_MIN_US })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::Airframe;
    use crate::core::control::distributor::ActuatorLimits;

    #[test]
    fn the_low_thrust_threshold_is_reachable_above_1000_us_and_below_hover() {
        let airframe = Airframe::default();
        let pwm = throttle_low_pwm_us(&airframe, &ActuatorLimits::default());
        let hover = distributor::pwm_from_lift_us(airframe.hover_rotor_lift_n());
        println!("throttle low at or below {pwm:.1} µs (hover {hover:.1} µs)");
        assert!(MOTOR_PWM_MIN_US < pwm && pwm < hover, "{pwm} µs (hover {hover} µs)");
    }
}
