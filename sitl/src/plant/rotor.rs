//! Rotors (spec (b), A.2; paper Eqs 10 and 27): in, the four PWM commands (µs, held over a plant step) and
//! the rotor lift state F_i (N); out, the commanded steady lift k_F·h_i·F10(PWM_i) (N), the first-order lag
//! rate dF_i/dt (N/s), and the body thrust (N) and moments (N·m, FRD) of the forward mixer. Evaluated at
//! every RK4 stage (1 ms substeps by default).
//!
//! Rotor numbering is the paper's; array index i holds rotor i+1:
//! rotor 1 right (+y), rotor 2 rear (-x), rotor 3 front (+x), rotor 4 left (-y).

use nalgebra::Vector3;

use super::airframe::Airframe;

/// The PWM range the rotors accept (µs), the autopilot's: lower, NaN and ±inf commands are read as
/// `MOTOR_PWM_MIN_US`; higher ones are clamped to `MOTOR_PWM_MAX_US`.
pub use autopilot::core::control::distributor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US};

/// Array index of paper rotor 1, on the right arm (+y).
pub const ROTOR_RIGHT: usize = 0;
/// Array index of paper rotor 2, on the rear arm (-x).
pub const ROTOR_REAR: usize = 1;
/// Array index of paper rotor 3, on the front arm (+x).
pub const ROTOR_FRONT: usize = 2;
/// Array index of paper rotor 4, on the left arm (-y).
pub const ROTOR_LEFT: usize = 3;

/// A PWM command made safe: NaN and ±inf become [`MOTOR_PWM_MIN_US`] (the motors' "off"), finite values are
/// clamped to [1000, 2000] µs.
#[must_use]
pub fn sanitize_pwm_us(pwm_us: f64) -> f64 {
    if pwm_us.is_finite() { pwm_us.clamp(MOTOR_PWM_MIN_US, MOTOR_PWM_MAX_US) } else { MOTOR_PWM_MIN_US }
}

/// Steady-state lift of one rotor (N) at `pwm_us`: the exact upper-branch inverse of Eq 10,
/// F10(P) = (260 + sqrt(88.92 P - 30656.6)) / 44.46, with P sanitised by [`sanitize_pwm_us`].
/// F10(1000) = 11.277 N, F10(2000) = 14.477 N.
#[must_use]
pub fn lift_from_pwm_n(pwm_us: f64) -> f64 {
    let p = sanitize_pwm_us(pwm_us);
    (260.0 + (88.92 * p - 30656.6).sqrt()) / 44.46
}

/// Eq 10 forward: the PWM (µs) that gives lift `lift_n`, PWM = 1105 - 260 F + 22.23 F². Not clamped.
#[must_use]
pub fn pwm_from_lift_us(lift_n: f64) -> f64 {
    1105.0 - 260.0 * lift_n + 22.23 * lift_n * lift_n
}

/// Total thrust along -z_FRD and moments about the FRD axes produced by the four rotor lifts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wrench {
    /// T = ΣF_i (N), acting along -z of the body (up when level).
    pub thrust_n: f64,
    /// (Mx, My, Mz) in FRD (N·m).
    pub moment_frd_nm: Vector3<f64>,
}

/// The forward mixer of Eq 27 in FRD (spec A.2): T = ΣF, Mx = l(F4 - F1), My = l(F3 - F2),
/// Mz = λ(F2 + F3 - F1 - F4).
#[must_use]
pub fn mix(lift_n: &[f64; 4], arm_m: f64, yaw_moment_m: f64) -> Wrench {
    let [f1, f2, f3, f4] = *lift_n;
    Wrench {
        thrust_n: f1 + f2 + f3 + f4,
        moment_frd_nm: Vector3::new(arm_m * (f4 - f1), arm_m * (f3 - f2), yaw_moment_m * (f2 + f3 - f1 - f4)),
    }
}

/// The lift each rotor settles to under the (sanitised) commands: k_F · health_i · F10(PWM_i) (N).
#[must_use]
pub fn commanded_lift_n(pwm_us: &[f64; 4], airframe: &Airframe) -> [f64; 4] {
    std::array::from_fn(|i| airframe.thrust_scale * airframe.rotor_health[i] * lift_from_pwm_n(pwm_us[i]))
}

/// Rotor lag: dF_i/dt = (F_cmd,i - F_i)/τ_m (N/s).
#[must_use]
pub fn lift_rate_nps(lift_n: &[f64; 4], commanded_n: &[f64; 4], motor_tau_s: f64) -> [f64; 4] {
    std::array::from_fn(|i| (commanded_n[i] - lift_n[i]) / motor_tau_s)
}

/// The PWM (µs, within 1000-2000) whose steady lift on this airframe is `lift_n` for rotor `index`, i.e.
/// Eq 10 at lift/(k_F·health), clamped; 1000 when that rotor produces no lift at all.
#[must_use]
pub fn pwm_holding_lift_us(lift_n: f64, index: usize, airframe: &Airframe) -> f64 {
    let gain = airframe.thrust_scale * airframe.rotor_health[index];
    let lift_f10 = lift_n / gain;
    if gain > 0.0 && lift_f10 >= lift_from_pwm_n(MOTOR_PWM_MIN_US) {
        sanitize_pwm_us(pwm_from_lift_us(lift_f10))
    } else {
        MOTOR_PWM_MIN_US
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_pwm_limits_when_evaluating_the_lift_curve_then_it_gives_the_spec_lifts() {
        assert!((lift_from_pwm_n(1000.0) - 11.277).abs() < 1e-3);
        assert!((lift_from_pwm_n(2000.0) - 14.477).abs() < 1e-3);
    }

    #[test]
    fn given_the_nominal_mass_when_solving_eq10_for_hover_then_pwm_is_1404_7() {
        let hover_lift_n = 5.2 * 9.81 / 4.0;
        let pwm = pwm_from_lift_us(hover_lift_n);
        assert!((pwm - 1404.7).abs() < 0.2, "{pwm}");
        // The inverse really is the inverse on the upper branch.
        assert!((lift_from_pwm_n(pwm) - hover_lift_n).abs() < 1e-10);
        for p in [1000.0, 1250.0, 1500.0, 1750.0, 2000.0] {
            assert!((pwm_from_lift_us(lift_from_pwm_n(p)) - p).abs() < 1e-9, "{p}");
        }
    }

    #[test]
    fn given_out_of_range_or_non_finite_pwm_when_evaluating_lift_then_it_is_clamped_and_nan_is_minimum() {
        let min = lift_from_pwm_n(1000.0);
        let max = lift_from_pwm_n(2000.0);
        assert_eq!(lift_from_pwm_n(f64::NAN), min);
        assert_eq!(lift_from_pwm_n(f64::INFINITY), min);
        assert_eq!(lift_from_pwm_n(f64::NEG_INFINITY), min);
        assert_eq!(lift_from_pwm_n(0.0), min);
        assert_eq!(lift_from_pwm_n(-5.0e9), min);
        assert_eq!(lift_from_pwm_n(2500.0), max);
        assert!(lift_from_pwm_n(1500.0) > min && lift_from_pwm_n(1500.0) < max);
    }

    #[test]
    fn given_hand_picked_lifts_when_mixing_then_thrust_and_moments_are_the_hand_computed_ones() {
        // F1 right, F2 rear, F3 front, F4 left.
        let w = mix(&[12.0, 13.0, 14.0, 11.5], 0.24, 0.02703);
        assert!((w.thrust_n - 50.5).abs() < 1e-12);
        // Mx = 0.24 (11.5 - 12) = -0.12; My = 0.24 (14 - 13) = 0.24;
        // Mz = 0.02703 (13 + 14 - 12 - 11.5) = 0.02703 * 3.5 = 0.094605.
        assert!((w.moment_frd_nm.x + 0.12).abs() < 1e-12);
        assert!((w.moment_frd_nm.y - 0.24).abs() < 1e-12);
        assert!((w.moment_frd_nm.z - 0.094605).abs() < 1e-12);
        let equal = mix(&[12.75; 4], 0.24, 0.02703);
        assert_eq!(equal.moment_frd_nm, Vector3::zeros());
        assert_eq!(equal.thrust_n, 51.0);
    }

    #[test]
    fn given_health_and_thrust_scale_when_commanding_then_each_rotor_lift_is_scaled_alone() {
        let airframe = Airframe { thrust_scale: 0.99, rotor_health: [1.0, 0.5, 0.0, 1.0], ..Airframe::nominal() };
        let cmd = commanded_lift_n(&[1500.0; 4], &airframe);
        let f = lift_from_pwm_n(1500.0);
        assert_eq!(cmd, [0.99 * f, 0.99 * 0.5 * f, 0.0, 0.99 * f]);
        let rate = lift_rate_nps(&[f, f, f, 0.0], &cmd, 0.05);
        assert!((rate[2] + f / 0.05).abs() < 1e-12);
        assert!((rate[3] - 0.99 * f / 0.05).abs() < 1e-12);
    }

    #[test]
    fn given_a_lift_when_asking_the_holding_pwm_then_the_commanded_lift_reproduces_it() {
        let airframe = Airframe::mismatch();
        let lift = airframe.hover_lift_n();
        let pwm = pwm_holding_lift_us(lift, ROTOR_FRONT, &airframe);
        let back = commanded_lift_n(&[pwm; 4], &airframe)[ROTOR_FRONT];
        assert!((back - lift).abs() < 1e-10);
        assert_eq!(pwm_holding_lift_us(0.0, ROTOR_LEFT, &airframe), MOTOR_PWM_MIN_US);
    }
}
