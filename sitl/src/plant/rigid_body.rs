//! Newton-Euler equations of motion and their RK4 integrator (spec (b); paper Eq 7 for the rotation):
//! in, the state (p, v NED in m, m/s; q body FRD -> NED; ω FRD in rad/s; rotor lifts F1..F4 in N), the
//! commanded rotor lifts and the wind (m/s NED), both held over the step (zero-order hold); out, the state
//! derivative and the state one RK4 substep later (default 1 ms), with q renormalised.
//!
//! - ṗ = v
//! - v̇ = g e3 - (T/m) R e3 - (ρ CdA / 2m) |v - w| (v - w), m the airframe's mass plus any payload
//! - q̇ = ½ q ⊗ (0, ω)
//! - I ω̇ = M + τ_dist - ω × Iω (Eq 7), M from the Eq 27 mixer; with a payload ([`super::payload`]) I is
//!   the full inertia with it and its weight adds r × Rᵀ(m_p g e3) to the torque
//! - Ḟ_i = (k_F h_i F10(PWM_i) - F_i)/τ_m

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::airframe::Airframe;
use super::rotor;

/// The integrated state of the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBodyState {
    /// Position of the centre of mass in NED (m).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity in NED (m/s).
    pub vel_ned_mps: Vector3<f64>,
    /// Attitude, Hamilton quaternion rotating FRD vectors into NED. Unit after every completed substep;
    /// RK4 stages in between may be slightly off unit length, which is why it is a plain `Quaternion`.
    pub q_ned_frd: Quaternion<f64>,
    /// Body rates in FRD (rad/s).
    pub rate_frd_radps: Vector3<f64>,
    /// Current lift of each rotor (N), paper numbering (index i = rotor i+1).
    pub rotor_lift_n: [f64; 4],
}

impl RigidBodyState {
    /// The attitude as a unit quaternion (normalising whatever small drift a stage state carries).
    #[must_use]
    pub fn attitude(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::new_normalize(self.q_ned_frd)
    }

    /// True when every component is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.pos_ned_m.iter().all(|x| x.is_finite())
            && self.vel_ned_mps.iter().all(|x| x.is_finite())
            && self.q_ned_frd.coords.iter().all(|x| x.is_finite())
            && self.rate_frd_radps.iter().all(|x| x.is_finite())
            && self.rotor_lift_n.iter().all(|x| x.is_finite())
    }

    fn add_scaled(&self, d: &StateDerivative, h: f64) -> Self {
        Self {
            pos_ned_m: self.pos_ned_m + d.vel_ned_mps * h,
            vel_ned_mps: self.vel_ned_mps + d.acc_ned_mps2 * h,
            q_ned_frd: self.q_ned_frd + d.q_dot * h,
            rate_frd_radps: self.rate_frd_radps + d.ang_acc_frd_radps2 * h,
            rotor_lift_n: std::array::from_fn(|i| self.rotor_lift_n[i] + d.lift_rate_nps[i] * h),
        }
    }
}

/// Time derivative of [`RigidBodyState`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateDerivative {
    /// ṗ = v (m/s, NED).
    pub vel_ned_mps: Vector3<f64>,
    /// v̇ (m/s², NED).
    pub acc_ned_mps2: Vector3<f64>,
    /// q̇ = ½ q ⊗ (0, ω) (1/s).
    pub q_dot: Quaternion<f64>,
    /// ω̇ (rad/s², FRD).
    pub ang_acc_frd_radps2: Vector3<f64>,
    /// Ḟ_i (N/s).
    pub lift_rate_nps: [f64; 4],
}

impl StateDerivative {
    fn weighted_sum(k: [&Self; 4], w: [f64; 4]) -> Self {
        Self {
            vel_ned_mps: k[0].vel_ned_mps * w[0]
                + k[1].vel_ned_mps * w[1]
                + k[2].vel_ned_mps * w[2]
                + k[3].vel_ned_mps * w[3],
            acc_ned_mps2: k[0].acc_ned_mps2 * w[0]
                + k[1].acc_ned_mps2 * w[1]
                + k[2].acc_ned_mps2 * w[2]
                + k[3].acc_ned_mps2 * w[3],
            q_dot: k[0].q_dot * w[0] + k[1].q_dot * w[1] + k[2].q_dot * w[2] + k[3].q_dot * w[3],
            ang_acc_frd_radps2: k[0].ang_acc_frd_radps2 * w[0]
                + k[1].ang_acc_frd_radps2 * w[1]
                + k[2].ang_acc_frd_radps2 * w[2]
                + k[3].ang_acc_frd_radps2 * w[3],
            lift_rate_nps: std::array::from_fn(|i| {
                k[0].lift_rate_nps[i] * w[0]
                    + k[1].lift_rate_nps[i] * w[1]
                    + k[2].lift_rate_nps[i] * w[2]
                    + k[3].lift_rate_nps[i] * w[3]
            }),
        }
    }
}

/// What is held constant over a plant step (zero-order hold): the lift each rotor is driven towards and
/// the wind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldInputs {
    /// k_F·h_i·F10(PWM_i) (N), see [`rotor::commanded_lift_n`].
    pub lift_cmd_n: [f64; 4],
    /// Wind velocity (m/s, NED) the air moves with.
    pub wind_ned_mps: Vector3<f64>,
}

/// The equations of motion (module docs) evaluated at `state`.
#[must_use]
pub fn derivative(state: &RigidBodyState, inputs: &HeldInputs, airframe: &Airframe) -> StateDerivative {
    let wrench = rotor::mix(&state.rotor_lift_n, airframe.arm_m, airframe.yaw_moment_m);
    let acc_ned_mps2 = acceleration_ned_mps2(state, wrench.thrust_n, &inputs.wind_ned_mps, airframe);

    // Rotation, Eq 7 with a diagonal inertia (with a payload, its full inertia and its weight's torque).
    let omega = state.rate_frd_radps;
    let ang_acc_frd_radps2 = if airframe.payload.is_carried() {
        let payload = &airframe.payload;
        let inertia = payload.inertia_with_kgm2(&airframe.inertia_kgm2);
        let h_frd = inertia * omega;
        let torque_frd_nm = wrench.moment_frd_nm
            + airframe.disturbance_torque_frd_nm
            + payload.gravity_torque_frd_nm(&state.attitude(), airframe.gravity_mps2)
            - omega.cross(&h_frd);
        // A rigid body's inertia is positive definite (validated principal inertias plus a point mass).
        inertia.cholesky().map_or_else(Vector3::zeros, |c| c.solve(&torque_frd_nm))
    } else {
        let inertia = airframe.inertia_kgm2;
        let h_frd = inertia.component_mul(&omega);
        let torque_frd_nm = wrench.moment_frd_nm + airframe.disturbance_torque_frd_nm - omega.cross(&h_frd);
        torque_frd_nm.component_div(&inertia)
    };

    let q_dot = state.q_ned_frd * Quaternion::from_imag(omega) * 0.5;

    StateDerivative {
        vel_ned_mps: state.vel_ned_mps,
        acc_ned_mps2,
        q_dot,
        ang_acc_frd_radps2,
        lift_rate_nps: rotor::lift_rate_nps(&state.rotor_lift_n, &inputs.lift_cmd_n, airframe.motor_tau_s),
    }
}

/// The translational part of [`derivative`], v̇ (m/s², NED), for a total rotor thrust `thrust_n` (N) and
/// the air moving at `wind_ned_mps`: all the plant's true state needs between steps.
#[must_use]
pub fn acceleration_ned_mps2(
    state: &RigidBodyState,
    thrust_n: f64,
    wind_ned_mps: &Vector3<f64>,
    airframe: &Airframe,
) -> Vector3<f64> {
    // Gravity, thrust along -z_FRD, quadratic drag on the air-relative velocity.
    let thrust_dir_ned = state.attitude().transform_vector(&Vector3::z());
    let air_rel_ned_mps = state.vel_ned_mps - wind_ned_mps;
    let mass_kg = airframe.total_mass_kg();
    let drag_per_speed = airframe.air_density_kgpm3 * airframe.drag_cda_m2 / (2.0 * mass_kg) * air_rel_ned_mps.norm();
    Vector3::new(0.0, 0.0, airframe.gravity_mps2)
        - thrust_dir_ned * (thrust_n / mass_kg)
        - air_rel_ned_mps * drag_per_speed
}

/// One classical 4th-order Runge-Kutta step of length `h_s` (s), inputs held, q renormalised at the end.
#[must_use]
pub fn rk4_step(state: &RigidBodyState, inputs: &HeldInputs, airframe: &Airframe, h_s: f64) -> RigidBodyState {
    let k1 = derivative(state, inputs, airframe);
    let k2 = derivative(&state.add_scaled(&k1, 0.5 * h_s), inputs, airframe);
    let k3 = derivative(&state.add_scaled(&k2, 0.5 * h_s), inputs, airframe);
    let k4 = derivative(&state.add_scaled(&k3, h_s), inputs, airframe);
    let sixth = h_s / 6.0;
    let increment = StateDerivative::weighted_sum([&k1, &k2, &k3, &k4], [sixth, 2.0 * sixth, 2.0 * sixth, sixth]);
    let mut next = state.add_scaled(&increment, 1.0);
    next.q_ned_frd = next.attitude().into_inner();
    next
}

/// ZYX Euler angles (φ roll, θ pitch, ψ yaw; rad) of a body -> NED attitude, R = Rz(ψ) Ry(θ) Rx(φ).
#[must_use]
pub fn euler_rad(q_ned_frd: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (roll, pitch, yaw) = q_ned_frd.euler_angles();
    Vector3::new(roll, pitch, yaw)
}

/// The attitude with ZYX Euler angles `euler_rad` = (φ, θ, ψ) (rad), R = Rz(ψ) Ry(θ) Rx(φ).
#[must_use]
pub fn attitude_from_euler(euler_rad: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(euler_rad.x, euler_rad.y, euler_rad.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3};

    fn hover_state(airframe: &Airframe) -> RigidBodyState {
        RigidBodyState {
            pos_ned_m: Vector3::new(0.0, 0.0, -10.0),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: Quaternion::identity(),
            rate_frd_radps: Vector3::zeros(),
            rotor_lift_n: [airframe.hover_lift_n(); 4],
        }
    }

    #[test]
    fn given_zyx_euler_angles_when_building_the_attitude_then_r_is_rz_ry_rx() {
        let (phi, theta, psi) = (0.4_f64, -0.5_f64, -0.4_f64);
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, phi.cos(), -phi.sin(), 0.0, phi.sin(), phi.cos());
        let ry = Matrix3::new(theta.cos(), 0.0, theta.sin(), 0.0, 1.0, 0.0, -theta.sin(), 0.0, theta.cos());
        let rz = Matrix3::new(psi.cos(), -psi.sin(), 0.0, psi.sin(), psi.cos(), 0.0, 0.0, 0.0, 1.0);
        let q = attitude_from_euler(&Vector3::new(phi, theta, psi));
        let r: Rotation3<f64> = q.to_rotation_matrix();
        assert!((r.matrix() - rz * ry * rx).norm() < 1e-14);
        assert!((euler_rad(&q) - Vector3::new(phi, theta, psi)).norm() < 1e-14);
    }

    #[test]
    fn given_hover_lifts_when_evaluating_the_derivative_then_everything_is_at_rest() {
        let airframe = Airframe::nominal();
        let state = hover_state(&airframe);
        let inputs = HeldInputs { lift_cmd_n: [airframe.hover_lift_n(); 4], wind_ned_mps: Vector3::zeros() };
        let d = derivative(&state, &inputs, &airframe);
        assert!(d.acc_ned_mps2.norm() < 1e-14);
        assert_eq!(d.ang_acc_frd_radps2, Vector3::zeros());
        assert_eq!(d.lift_rate_nps, [0.0; 4]);
    }

    #[test]
    fn given_wind_when_evaluating_the_derivative_then_drag_pushes_with_the_air() {
        let airframe = Airframe::nominal();
        let state = hover_state(&airframe);
        let inputs = HeldInputs { lift_cmd_n: [airframe.hover_lift_n(); 4], wind_ned_mps: Vector3::new(0.0, 6.7, 0.0) };
        let d = derivative(&state, &inputs, &airframe);
        // ρ CdA / 2m · 6.7² = 1.225·0.1/10.4·44.89 = 0.528751... m/s² toward +E.
        let expected = 1.225 * 0.1 / (2.0 * 5.2) * 6.7 * 6.7;
        assert!((d.acc_ned_mps2.y - expected).abs() < 1e-12);
        assert!(d.acc_ned_mps2.x.abs() < 1e-15);
    }

    #[test]
    fn given_a_tilted_vehicle_when_stepping_then_the_quaternion_stays_unit() {
        let airframe = Airframe::nominal();
        let mut state = hover_state(&airframe);
        state.q_ned_frd = attitude_from_euler(&Vector3::new(0.4, -0.5, -0.4)).into_inner();
        state.rate_frd_radps = Vector3::new(3.0, -2.0, 1.0);
        let inputs = HeldInputs { lift_cmd_n: [12.0, 13.0, 14.0, 11.5], wind_ned_mps: Vector3::zeros() };
        for _ in 0..2000 {
            state = rk4_step(&state, &inputs, &airframe, 0.001);
            assert!((state.q_ned_frd.norm() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn given_a_payload_then_the_hover_lift_carries_it_and_its_offset_pitches_by_the_full_inertia() {
        use crate::plant::payload::Payload;
        // 0.5 kg at the origin: m g/4 of the 5.7 kg hovers, nothing turns.
        let centred = Airframe { payload: Payload { mass_kg: 0.5, ..Payload::default() }, ..Airframe::nominal() };
        assert!((centred.hover_lift_n() - 5.7 * 9.81 / 4.0).abs() < 1e-12);
        let state = hover_state(&centred);
        let inputs = HeldInputs { lift_cmd_n: [centred.hover_lift_n(); 4], wind_ned_mps: Vector3::zeros() };
        let d = derivative(&state, &inputs, &centred);
        assert!(d.acc_ned_mps2.norm() < 1e-12 && d.ang_acc_frd_radps2.norm() < 1e-15, "{d:?}");
        // The same lifts with the airframe's own 5.2 kg only: it climbs at (5.7/5.2 - 1) g.
        let light = derivative(&state, &inputs, &Airframe::nominal());
        assert!((light.acc_ned_mps2.z + (5.7 / 5.2 - 1.0) * 9.81).abs() < 1e-12, "{light:?}");
        // 0.5 kg 0.1 m forward, 0.04 m right: τ = (0.1962, -0.4905, 0) N·m on the full inertia
        // [[0.0808, -0.002, 0], [-0.002, 0.085, 0], [0, 0, 0.1258]]; solved by hand (Cramer's rule):
        // det = 0.0808·0.085 - 0.002² = 0.006864; ω̇x = (0.1962·0.085 - 0.002·0.4905)/det,
        // ω̇y = (-0.4905·0.0808 + 0.002·0.1962)/det.
        let offset = Airframe {
            payload: Payload { mass_kg: 0.5, offset_frd_m: Vector3::new(0.1, 0.04, 0.0) },
            ..Airframe::nominal()
        };
        let d = derivative(&state, &inputs, &offset);
        let det = 0.0808 * 0.085 - 0.002 * 0.002;
        let expected =
            Vector3::new((0.1962 * 0.085 - 0.002 * 0.4905) / det, (-0.4905 * 0.0808 + 0.002 * 0.1962) / det, 0.0);
        assert!((d.ang_acc_frd_radps2 - expected).norm() < 1e-12, "{} vs {expected}", d.ang_acc_frd_radps2);
        assert!(d.ang_acc_frd_radps2.y < 0.0, "weight ahead pitches the nose down");
        // Without a payload the path is the diagonal one, bit for bit: m + 0 is m.
        let none = Airframe::nominal();
        assert_eq!(none.total_mass_kg().to_bits(), none.mass_kg.to_bits());
    }
}
