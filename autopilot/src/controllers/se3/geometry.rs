//! The geometry of the SE(3) law: the hat and vee maps, the desired frame `Rd` from a thrust direction and
//! a heading (Lee, Leok and McClamroch, CDC 2010, Section IV: `b3d`, `b2d = b3d × b1d / ‖·‖`,
//! `Rd = [b2d × b3d, b2d, b3d]`), its angular velocity `Ωd` from the derivative of the thrust vector, and
//! the attitude and rate errors `eR`, `eΩ` (Eqs 10-11). In: NED vectors and body FRD rates, SI units.
//! Out: matrices and vectors; nothing is stored. Pure functions, called every tick.

use nalgebra::{Matrix3, Vector3};

/// The hat map `x̂`: the skew matrix with `x̂ y = x × y`.
#[must_use]
pub fn hat(x: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -x.z, x.y, x.z, 0.0, -x.x, -x.y, x.x, 0.0)
}

/// The vee map, the inverse of [`hat`] on skew matrices; on any matrix it reads the skew part's vector.
#[must_use]
pub fn vee(m: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) * 0.5
}

/// The attitude error `eR = ½ (Rdᵀ R - Rᵀ Rd)^∨` (Eq 10).
#[must_use]
pub fn attitude_error(r: &Matrix3<f64>, rd: &Matrix3<f64>) -> Vector3<f64> {
    let m = rd.transpose() * r - r.transpose() * rd;
    vee(&m) * 0.5
}

/// The rate error `eΩ = Ω - Rᵀ Rd Ωd` (Eq 11).
#[must_use]
pub fn rate_error(r: &Matrix3<f64>, rd: &Matrix3<f64>, omega: &Vector3<f64>, omega_d: &Vector3<f64>) -> Vector3<f64> {
    omega - r.transpose() * rd * omega_d
}

/// The desired frame and its angular velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DesiredFrame {
    /// `Rd = [b1d, b2d, b3d]`, body FRD -> NED.
    pub rd: Matrix3<f64>,
    /// `Ωd` (rad/s, desired body FRD axes), from `ḃ3d`.
    pub omega_d_radps: Vector3<f64>,
}

/// `Rd` and `Ωd` from the thrust-force vector `u` (N, NED; the thrust points along it, so `b3d = -u/‖u‖`,
/// the body z axis down) and its time derivative `u_dot` (N/s), with the heading `b1c = (cos ψ, sin ψ, 0)`
/// held (ψ̇ = 0): `b2d = b3d × b1c / ‖·‖`, `b1d = b2d × b3d`, `Ω̂d = Rdᵀ Ṙd`. A thrust vector along the
/// heading (a 90° tilt towards it) has no `b2d`; `e2` rotated by ψ is taken then. None when `u` is not a
/// usable direction (zero or not finite).
#[must_use]
pub fn desired_frame(u_ned_n: &Vector3<f64>, u_dot_ned_nps: &Vector3<f64>, yaw_rad: f64) -> Option<DesiredFrame> {
    let n = u_ned_n.norm();
    if !(n.is_finite() && n > 1e-9) {
        return None;
    }
    let b3 = -u_ned_n / n;
    // ḃ3d = -(I - b3 b3ᵀ) u̇ / ‖u‖ (the derivative of -u/‖u‖).
    let b3_dot = -(u_dot_ned_nps - b3 * b3.dot(u_dot_ned_nps)) / n;
    let (s, c) = yaw_rad.sin_cos();
    let b1c = Vector3::new(c, s, 0.0);
    let cross = b3.cross(&b1c);
    let cn = cross.norm();
    let (b2, b2_dot) = if cn > 1e-6 {
        let b2 = cross / cn;
        let cross_dot = b3_dot.cross(&b1c);
        (b2, (cross_dot - b2 * b2.dot(&cross_dot)) / cn)
    } else {
        (Vector3::new(-s, c, 0.0), Vector3::zeros())
    };
    let b1 = b2.cross(&b3);
    let b1_dot = b2_dot.cross(&b3) + b2.cross(&b3_dot);
    let rd = Matrix3::from_columns(&[b1, b2, b3]);
    let rd_dot = Matrix3::from_columns(&[b1_dot, b2_dot, b3_dot]);
    Some(DesiredFrame { rd, omega_d_radps: vee(&(rd.transpose() * rd_dot)) })
}

/// ZYX Euler angles (φ, θ, ψ) of a rotation body FRD -> NED (`R = Rz(ψ) Ry(θ) Rx(φ)`).
#[must_use]
pub fn euler_of(r: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(r[(2, 1)].atan2(r[(2, 2)]), -r[(2, 0)].clamp(-1.0, 1.0).asin(), r[(1, 0)].atan2(r[(0, 0)]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::frames::rotation_ned_frd;

    const EULERS: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [0.3, -0.2, 1.0], [-0.5, 0.4, -2.5], [0.1, 0.05, 3.0]];

    #[test]
    fn given_vectors_when_hatted_and_veed_then_cross_product_and_inverse() {
        let (x, y) = (Vector3::new(0.3, -1.2, 2.0), Vector3::new(-0.7, 0.4, 1.1));
        assert!((hat(&x) * y - x.cross(&y)).norm() < 1e-15);
        assert_eq!(vee(&hat(&x)), x);
        assert!((hat(&x) + hat(&x).transpose()).norm() < 1e-15, "skew");
    }

    #[test]
    fn given_rd_equal_to_r_when_compared_then_zero_attitude_and_rate_errors() {
        for e in EULERS {
            let r = rotation_ned_frd(&Vector3::from(e));
            assert!(attitude_error(&r, &r).norm() < 1e-15);
            let w = Vector3::new(0.2, -0.1, 0.4);
            assert!(rate_error(&r, &r, &w, &w).norm() < 1e-15);
            assert!((euler_of(&r) - Vector3::from(e)).norm() < 1e-12, "{e:?}");
        }
    }

    #[test]
    fn given_a_small_rotation_when_compared_then_attitude_error_is_its_angle_vector() {
        // R = Rd exp(ε̂): eR ≈ ε for a small ε (body axes).
        let rd = rotation_ned_frd(&Vector3::new(0.2, 0.1, -0.7));
        let eps = Vector3::new(1e-3, -2e-3, 0.5e-3);
        let r = rd * nalgebra::Rotation3::from_scaled_axis(eps).into_inner();
        assert!((attitude_error(&r, &rd) - eps).norm() < 1e-8);
    }

    #[test]
    fn given_a_thrust_vector_when_the_frame_is_built_then_b3_along_thrust_and_heading_kept() {
        let u = Vector3::new(3.0, -2.0, -50.0);
        let f = desired_frame(&u, &Vector3::zeros(), 0.8).expect("a direction");
        assert!((f.rd.column(2) + u.normalize()).norm() < 1e-12, "b3d = -u/|u|: thrust along -b3d");
        assert!((f.rd.transpose() * f.rd - Matrix3::identity()).norm() < 1e-12 && f.rd.determinant() > 0.0);
        assert!((euler_of(&f.rd).z - 0.8).abs() < 0.01, "the heading is the reference yaw");
        assert_eq!(f.omega_d_radps, Vector3::zeros());
        assert!(desired_frame(&Vector3::zeros(), &Vector3::zeros(), 0.0).is_none());
    }

    #[test]
    fn given_a_turning_thrust_vector_when_the_frame_is_built_then_omega_d_matches_finite_differences() {
        let u = |t: f64| Vector3::new(5.0 * (2.0 * t).sin(), 4.0 * (1.3 * t).cos(), -51.0 + t);
        let u_dot = |t: f64| Vector3::new(10.0 * (2.0 * t).cos(), -5.2 * (1.3 * t).sin(), 1.0);
        let (t, h) = (0.4, 1e-6);
        let f = desired_frame(&u(t), &u_dot(t), 0.3).expect("frame");
        let (a, b) = (
            desired_frame(&u(t - h), &u_dot(t), 0.3).expect("a"),
            desired_frame(&u(t + h), &u_dot(t), 0.3).expect("b"),
        );
        let numeric = vee(&(f.rd.transpose() * (b.rd - a.rd) / (2.0 * h)));
        assert!((numeric - f.omega_d_radps).norm() < 1e-6, "{numeric} vs {}", f.omega_d_radps);
    }
}
