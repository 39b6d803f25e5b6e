//! A payload carried by the airframe (SIM_PAYLOAD_KG, SIM_CG_OFS_X/Y): an added point mass m_p (kg) at
//! r = (x, y, 0) (m, FRD) from the body origin. In, the airframe's inertia and the attitude; out, the
//! total mass, the inertia about the origin with the payload (parallel axis: I + m_p(|r|²E - r rᵀ), a full
//! 3×3 once r has two components) and the payload's gravity torque r × Rᵀ(m_p g e3) (N·m, FRD) of Eq 7.
//!
//! The model keeps the body origin (the rotor plane's centre) as the point the equations of motion
//! integrate: the rotors still push there, the payload's weight adds a torque about it, and its mass adds
//! to the translation and the inertia. What it leaves out is the offset mass's own acceleration as the body
//! rotates (ω̇ × r and ω × (ω × r) terms), small for the few centimetres and slow rates of a hover; a
//! payload at the origin (r = 0) is exact.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// An added point mass and where it sits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Payload {
    /// m_p (kg), >= 0; 0 = no payload.
    pub mass_kg: f64,
    /// r (m, FRD) from the body origin; z is kept 0 (SIM_CG_OFS_X, SIM_CG_OFS_Y).
    pub offset_frd_m: Vector3<f64>,
}

impl Default for Payload {
    /// No payload.
    fn default() -> Self {
        Self { mass_kg: 0.0, offset_frd_m: Vector3::zeros() }
    }
}

impl Payload {
    /// True when the payload has mass (else it changes nothing and the plant takes its diagonal path).
    #[must_use]
    pub fn is_carried(&self) -> bool {
        self.mass_kg > 0.0
    }

    /// The inertia (kg·m², about the body origin, FRD) of a body of principal inertia `inertia_kgm2` with
    /// this payload: diag(I) + m_p(|r|² E - r rᵀ).
    #[must_use]
    pub fn inertia_with_kgm2(&self, inertia_kgm2: &Vector3<f64>) -> Matrix3<f64> {
        let r = self.offset_frd_m;
        Matrix3::from_diagonal(inertia_kgm2)
            + (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * self.mass_kg
    }

    /// The torque (N·m, FRD) of the payload's weight about the body origin at attitude `q_ned_frd`:
    /// r × Rᵀ(m_p g e3).
    #[must_use]
    pub fn gravity_torque_frd_nm(&self, q_ned_frd: &UnitQuaternion<f64>, gravity_mps2: f64) -> Vector3<f64> {
        let weight_frd_n = q_ned_frd.inverse_transform_vector(&Vector3::new(0.0, 0.0, self.mass_kg * gravity_mps2));
        self.offset_frd_m.cross(&weight_frd_n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_a_payload_forward_and_right_when_level_then_its_torque_is_the_hand_computed_one() {
        // 0.5 kg at x = 0.1 m (forward), y = 0.04 m (right), level: weight (0, 0, 4.905) N in FRD;
        // r × F = (y·F, -x·F, 0) = (0.1962, -0.4905, 0) N·m: rolls right (+x moment) and pitches nose down.
        let p = Payload { mass_kg: 0.5, offset_frd_m: Vector3::new(0.1, 0.04, 0.0) };
        let tau = p.gravity_torque_frd_nm(&UnitQuaternion::identity(), 9.81);
        assert!((tau - Vector3::new(0.04 * 4.905, -0.1 * 4.905, 0.0)).norm() < 1e-12, "{tau}");
    }

    #[test]
    fn given_a_rolled_body_when_the_payload_sits_right_then_its_torque_shrinks_with_the_cosine() {
        // Rolled 60°: the weight in FRD is (0, m g sin φ, m g cos φ); r = (0, 0.1, 0): τx = 0.1·m g cos φ.
        let p = Payload { mass_kg: 1.0, offset_frd_m: Vector3::new(0.0, 0.1, 0.0) };
        let q = UnitQuaternion::from_euler_angles(60_f64.to_radians(), 0.0, 0.0);
        let tau = p.gravity_torque_frd_nm(&q, 9.81);
        assert!((tau.x - 0.1 * 9.81 * 0.5).abs() < 1e-12, "{tau}");
        assert!(tau.y.abs() < 1e-12 && tau.z.abs() < 1e-12, "{tau}");
    }

    #[test]
    fn given_an_offset_payload_then_the_inertia_is_the_parallel_axis_one_by_hand() {
        // 0.5 kg at (0.1, 0.04, 0): Ixx += m y² = 0.0008, Iyy += m x² = 0.005, Izz += m (x² + y²) = 0.0058,
        // Ixy = Iyx = -m x y = -0.002, the rest 0.
        let p = Payload { mass_kg: 0.5, offset_frd_m: Vector3::new(0.1, 0.04, 0.0) };
        let j = p.inertia_with_kgm2(&Vector3::new(0.08, 0.08, 0.12));
        let expected = Matrix3::new(0.0808, -0.002, 0.0, -0.002, 0.085, 0.0, 0.0, 0.0, 0.1258);
        assert!((j - expected).norm() < 1e-15, "{j}");
        // At the origin a point mass adds no inertia.
        let centred = Payload { mass_kg: 3.0, offset_frd_m: Vector3::zeros() };
        assert_eq!(
            centred.inertia_with_kgm2(&Vector3::new(0.08, 0.08, 0.12)),
            Matrix3::from_diagonal(&Vector3::new(0.08, 0.08, 0.12))
        );
        assert!(!Payload::default().is_carried() && centred.is_carried());
    }
}
