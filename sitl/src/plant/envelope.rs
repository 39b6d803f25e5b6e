//! What an airframe can physically hold, whatever the controller: in, an [`Airframe`] (its mass, payload,
//! thrust scale and rotor health); out, the bounds of a hover with one degraded rotor or an added payload,
//! from the paper's lift curve (Eq 10: a rotor lifts between F10(1000 µs) = 11.277 N and F10(2000 µs) =
//! 14.477 N, times k_F and its health).
//!
//! A steady hover needs ΣF = (m + m_p)g with the roll and pitch moments zero; with the yaw moment zero
//! too it keeps its heading. With rotor i at health h and the others healthy (F_max = k_F·F10(2000)):
//! - every moment balanced needs all four lifts equal to (m + m_p)g/4 (the mixer of Eq 27 leaves no other
//!   solution), so h·F_max >= (m + m_p)g/4;
//! - giving up yaw, roll and pitch balance ask F1 = F4 and F2 = F3, so the degraded rotor's partner is held
//!   to its lift: 2·h·F_max + 2·F_max >= (m + m_p)g;
//! - a payload on healthy rotors: 4·F_max >= (m + m_p)g.
//!
//! On the nominal airframe (5.2 kg, k_F 1): h >= 0.881 (at most 11.9 % thrust loss) keeping the heading,
//! h >= 0.762 (23.8 %) spinning in yaw, and at most 0.703 kg of payload with zero margin left to control.

use super::airframe::Airframe;
use super::rotor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US, lift_from_pwm_n};

/// The hover bounds of one airframe (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct HoverEnvelope {
    /// Σ of the four healthy rotors' greatest lift over the weight (with the payload).
    pub thrust_to_weight: f64,
    /// The least health of one rotor (the others healthy) at which a hover keeps every moment balanced.
    pub min_health_full_control: f64,
    /// The least health of one rotor (the others healthy) at which a hover keeps roll and pitch, yaw given up.
    pub min_health_without_yaw: f64,
    /// The greatest payload (kg, on top of the airframe's own) healthy rotors can hover with at full PWM.
    pub max_payload_kg: f64,
}

/// The greatest lift of a healthy rotor of this airframe (N): k_F·F10(2000 µs).
#[must_use]
pub fn max_rotor_lift_n(airframe: &Airframe) -> f64 {
    airframe.thrust_scale * lift_from_pwm_n(MOTOR_PWM_MAX_US)
}

/// The least lift of a healthy rotor of this airframe (N): k_F·F10(1000 µs).
#[must_use]
pub fn min_rotor_lift_n(airframe: &Airframe) -> f64 {
    airframe.thrust_scale * lift_from_pwm_n(MOTOR_PWM_MIN_US)
}

/// The hover bounds of `airframe` (its payload included; its own rotor health ignored: the bounds are
/// for one rotor degraded from healthy).
#[must_use]
pub fn hover_envelope(airframe: &Airframe) -> HoverEnvelope {
    let f_max = max_rotor_lift_n(airframe);
    let weight = airframe.weight_n();
    HoverEnvelope {
        thrust_to_weight: 4.0 * f_max / weight,
        min_health_full_control: weight / 4.0 / f_max,
        min_health_without_yaw: (weight / (2.0 * f_max) - 1.0).max(0.0),
        max_payload_kg: 4.0 * f_max / airframe.gravity_mps2 - airframe.mass_kg,
    }
}

/// How much of a hover is physically possible.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Feasibility {
    /// Every moment can be balanced: a controller can hold position and heading.
    Full,
    /// Roll and pitch can be balanced, yaw cannot: position can be held while the vehicle spins.
    WithoutYaw,
    /// The rotors cannot carry the weight with roll and pitch balanced: no controller can hover.
    Infeasible,
}

/// How much of a hover `airframe` as it is (its rotors' health and its payload, taken at the body origin)
/// allows: every moment balanced needs the four lifts equal to the weight/4, within each rotor's greatest
/// lift; roll and pitch alone need F1 = F4 and F2 = F3, each pair within its weaker rotor's greatest lift.
#[must_use]
pub fn feasibility(airframe: &Airframe) -> Feasibility {
    let f_max = max_rotor_lift_n(airframe);
    let lift = airframe.rotor_health.map(|h| h * f_max);
    let weight = airframe.weight_n();
    // Rotor 1 (right) pairs with 4 (left) for roll, 2 (rear) with 3 (front) for pitch.
    let pairs = 2.0 * lift[0].min(lift[3]) + 2.0 * lift[1].min(lift[2]);
    if lift.iter().all(|&f| f >= weight / 4.0) {
        Feasibility::Full
    } else if pairs >= weight {
        Feasibility::WithoutYaw
    } else {
        Feasibility::Infeasible
    }
}

/// [`feasibility`] of `airframe` with rotor 1 at `health` and the others healthy.
#[must_use]
pub fn rotor_feasibility(airframe: &Airframe, health: f64) -> Feasibility {
    feasibility(&Airframe { rotor_health: [health, 1.0, 1.0, 1.0], ..airframe.clone() })
}

/// [`feasibility`] of `airframe` (healthy rotors) carrying `payload_kg` more at its origin.
#[must_use]
pub fn payload_feasibility(airframe: &Airframe, payload_kg: f64) -> Feasibility {
    let payload = super::payload::Payload { mass_kg: payload_kg, ..airframe.payload };
    feasibility(&Airframe { rotor_health: [1.0; 4], payload, ..airframe.clone() })
}

/// The greatest payload (kg) the autopilot's controllers can hover with: their thrust limiter caps the
/// collective at `ActuatorLimits::thrust_hi_n` = 0.97·4·F_max (3 % kept for attitude control), so they stop
/// short of the physical [`HoverEnvelope::max_payload_kg`].
#[must_use]
pub fn max_payload_within_limiter_kg(airframe: &Airframe) -> f64 {
    let limits = autopilot::core::control::distributor::ActuatorLimits::default();
    limits.thrust_hi_n * airframe.thrust_scale / airframe.gravity_mps2 - airframe.mass_kg
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::payload::Payload;
    use crate::plant::rigid_body::{HeldInputs, RigidBodyState, derivative};
    use crate::plant::rotor::{commanded_lift_n, mix};
    use nalgebra::{Quaternion, Vector3};

    #[test]
    fn given_the_nominal_airframe_then_the_bounds_are_the_hand_computed_0_881_0_762_and_0_703_kg() {
        // F10(2000) = (260 + sqrt(88.92·2000 - 30656.6))/44.46 = 14.47694 N; weight 5.2·9.81 = 51.012 N.
        let e = hover_envelope(&Airframe::nominal());
        let f_max = (260.0 + (88.92_f64 * 2000.0 - 30656.6).sqrt()) / 44.46;
        assert!((e.thrust_to_weight - 4.0 * f_max / 51.012).abs() < 1e-12, "{e:?}");
        assert!((e.thrust_to_weight - 1.1352).abs() < 1e-4, "{e:?}");
        assert!((e.min_health_full_control - 0.8809).abs() < 1e-4, "{e:?}");
        assert!((e.min_health_without_yaw - 0.7618).abs() < 1e-4, "{e:?}");
        assert!((e.max_payload_kg - 0.7029).abs() < 1e-4, "{e:?}");
        // The mismatch plant (5.4 kg, k_F 0.99) has less: 0.924 and 0.848.
        let m = hover_envelope(&Airframe::mismatch());
        assert!((m.min_health_full_control - 0.9240).abs() < 1e-4 && (m.min_health_without_yaw - 0.8481).abs() < 1e-4);
    }

    #[test]
    fn given_the_issue_magnitudes_then_70_and_50_percent_rotors_and_20_and_40_percent_payloads_are_infeasible() {
        let a = Airframe::nominal();
        assert_eq!(rotor_feasibility(&a, 0.9), Feasibility::Full);
        assert_eq!(rotor_feasibility(&a, 0.8), Feasibility::WithoutYaw);
        assert_eq!(rotor_feasibility(&a, 0.7), Feasibility::Infeasible);
        assert_eq!(rotor_feasibility(&a, 0.5), Feasibility::Infeasible);
        assert_eq!(payload_feasibility(&a, 0.05 * 5.2), Feasibility::Full);
        assert_eq!(payload_feasibility(&a, 0.10 * 5.2), Feasibility::Full);
        assert_eq!(payload_feasibility(&a, 0.20 * 5.2), Feasibility::Infeasible);
        assert_eq!(payload_feasibility(&a, 0.40 * 5.2), Feasibility::Infeasible);
        // A payload shrinks the rotor margin: with 0.3 kg on board, a 90 % rotor no longer holds heading.
        let loaded = Airframe { payload: Payload { mass_kg: 0.3, ..Payload::default() }, ..a.clone() };
        assert_eq!(rotor_feasibility(&loaded, 0.9), Feasibility::WithoutYaw);
        // Two weak rotors on one arm pair count once: rotors 1 and 4 at 0.8 hold roll and pitch as one at 0.8
        // does (0.8 >= 0.762), rotors 1 and 2 at 0.8 do not (2·0.8 + 2·0.8 < 4·0.881).
        let pair = |h: [f64; 4]| feasibility(&Airframe { rotor_health: h, ..a.clone() });
        assert_eq!(pair([0.8, 1.0, 1.0, 0.8]), Feasibility::WithoutYaw);
        assert_eq!(pair([0.8, 0.8, 1.0, 1.0]), Feasibility::Infeasible);
        // The controllers' limiter: 0.97·4·14.477/9.81 - 5.2 = 0.526 kg, short of the physical 0.703 kg.
        assert!((max_payload_within_limiter_kg(&a) - (0.97 * 4.0 * 14.47694 / 9.81 - 5.2)).abs() < 1e-4);
    }

    /// The plant's own equations at a hover: the derivative with the given lifts, level and at rest.
    fn hover_derivative(airframe: &Airframe, lifts: [f64; 4]) -> (f64, Vector3<f64>) {
        let state = RigidBodyState {
            pos_ned_m: Vector3::new(0.0, 0.0, -10.0),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: Quaternion::identity(),
            rate_frd_radps: Vector3::zeros(),
            rotor_lift_n: lifts,
        };
        let d = derivative(&state, &HeldInputs { lift_cmd_n: lifts, wind_ned_mps: Vector3::zeros() }, airframe);
        (d.acc_ned_mps2.z, d.ang_acc_frd_radps2)
    }

    #[test]
    fn given_the_plant_at_the_bounds_then_its_own_equations_hover_there_and_fall_just_below() {
        // Numerically, through the plant's rotor curve, mixer and equations of motion rather than the
        // closed forms: search the best lifts the PWM range allows with the moments balanced.
        let nominal = Airframe::nominal();
        let e = hover_envelope(&nominal);
        for (health, keep_yaw) in [(e.min_health_full_control, true), (e.min_health_without_yaw, false)] {
            for (scale, holds) in [(1.0 + 1e-9, true), (1.0 - 1e-3, false)] {
                let airframe = Airframe { rotor_health: [health * scale, 1.0, 1.0, 1.0], ..nominal.clone() };
                // Rotor 1 at full PWM, rotor 4 matched to it (roll), rotors 2 and 3 equal (pitch) and as
                // high as the heading allows (yaw: equal to rotor 1's; without: full PWM).
                let f1 = commanded_lift_n(&[MOTOR_PWM_MAX_US; 4], &airframe)[0];
                let f23 = if keep_yaw { f1 } else { max_rotor_lift_n(&airframe) };
                let best_up_mps2 = -hover_derivative(&airframe, [f1, f23, f23, f1]).0;
                let w = mix(&[f1, f23, f23, f1], airframe.arm_m, airframe.yaw_moment_m);
                assert!(w.moment_frd_nm.x.abs() < 1e-12 && w.moment_frd_nm.y.abs() < 1e-12);
                assert_eq!(best_up_mps2 >= -1e-9, holds, "h {} yaw {keep_yaw}: {best_up_mps2}", health * scale);
            }
        }
        // At the payload bound, four rotors at full PWM hold the weight and no more.
        let loaded = Airframe { payload: Payload { mass_kg: e.max_payload_kg, ..Payload::default() }, ..nominal };
        let (acc_d, ang) = hover_derivative(&loaded, [max_rotor_lift_n(&loaded); 4]);
        assert!(acc_d.abs() < 1e-9 && ang.norm() < 1e-12, "{acc_d} {ang}");
    }
}
