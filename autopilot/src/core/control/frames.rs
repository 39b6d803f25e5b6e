//! Frame and attitude helpers shared by the controllers (spec A.2): NED earth, FRD body, ZYX Euler
//! angles `(phi roll, theta pitch, psi yaw)` in radians, `R = Rz(psi) Ry(theta) Rx(phi)` body -> NED.
//!
//! In: Euler angles (rad). Out: the rotation matrix, the kinematic maps `N` (`eta_dot = N omega`, the
//! paper's Eqs 23-25) and `E = N^-1` (`omega = E eta_dot`), angle wrapping and quaternions.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

/// `R(eta) = Rz(psi) Ry(theta) Rx(phi)`, body FRD -> NED.
#[must_use]
pub fn rotation_ned_frd(euler_rad: &Vector3<f64>) -> Matrix3<f64> {
    let (sp, cp) = euler_rad.x.sin_cos();
    let (st, ct) = euler_rad.y.sin_cos();
    let (ss, cs) = euler_rad.z.sin_cos();
    Matrix3::new(
        ct * cs,
        sp * st * cs - cp * ss,
        cp * st * cs + sp * ss,
        ct * ss,
        sp * st * ss + cp * cs,
        cp * st * ss - sp * cs,
        -st,
        sp * ct,
        cp * ct,
    )
}

/// Third column of `R(eta)`: the body z axis (down) expressed in NED, `R e3`.
#[must_use]
pub fn body_z_in_ned(euler_rad: &Vector3<f64>) -> Vector3<f64> {
    let (sp, cp) = euler_rad.x.sin_cos();
    let (st, ct) = euler_rad.y.sin_cos();
    let (ss, cs) = euler_rad.z.sin_cos();
    Vector3::new(cp * st * cs + sp * ss, cp * st * ss - sp * cs, cp * ct)
}

/// `E(eta)`: Euler-angle rates -> body rates, `omega = E eta_dot` (inverse of Eq 23's N).
#[must_use]
pub fn euler_rates_to_body(euler_rad: &Vector3<f64>) -> Matrix3<f64> {
    let (sp, cp) = euler_rad.x.sin_cos();
    let (st, ct) = euler_rad.y.sin_cos();
    Matrix3::new(1.0, 0.0, -st, 0.0, cp, sp * ct, 0.0, -sp, cp * ct)
}

/// `N(eta)`: body rates -> Euler-angle rates, `eta_dot = N omega` (Eqs 23-25). Singular at
/// `|theta| = pi/2`; `cos theta` is floored at 1e-6 in magnitude so the result stays finite.
#[must_use]
pub fn body_to_euler_rates(euler_rad: &Vector3<f64>) -> Matrix3<f64> {
    let (sp, cp) = euler_rad.x.sin_cos();
    let (st, ct) = euler_rad.y.sin_cos();
    let ct = if ct.abs() < 1e-6 { 1e-6_f64.copysign(ct) } else { ct };
    let tt = st / ct;
    Matrix3::new(1.0, sp * tt, cp * tt, 0.0, cp, -sp, 0.0, sp / ct, cp / ct)
}

/// Wrap an angle to `(-pi, pi]`: `-pi` (and every odd multiple of `pi`) maps to `+pi`. The one angle wrap
/// of the workspace (estimator, plant sensors and scenario metrics use it too), so that a heading at
/// exactly `+-pi` reads the same everywhere.
#[must_use]
pub fn wrap_pi(angle_rad: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut a = (angle_rad + std::f64::consts::PI).rem_euclid(two_pi) - std::f64::consts::PI;
    if a <= -std::f64::consts::PI {
        a += two_pi;
    }
    a
}

/// Hamilton quaternion body FRD -> NED from ZYX Euler angles.
#[must_use]
pub fn quaternion_from_euler(euler_rad: &Vector3<f64>) -> UnitQuaternion<f64> {
    let (sr, cr) = (0.5 * euler_rad.x).sin_cos();
    let (sp, cp) = (0.5 * euler_rad.y).sin_cos();
    let (sy, cy) = (0.5 * euler_rad.z).sin_cos();
    UnitQuaternion::new_normalize(Quaternion::new(
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_euler_angles_when_building_r_then_matches_nalgebra_zyx_and_e_inverts_n() {
        let eta = Vector3::new(0.4, -0.5, -0.4);
        let r = rotation_ned_frd(&eta);
        let reference = nalgebra::Rotation3::from_euler_angles(eta.x, eta.y, eta.z);
        assert!((r - reference.matrix()).abs().max() < 1e-14);
        assert!((body_z_in_ned(&eta) - r.column(2)).abs().max() < 1e-15);
        let q = quaternion_from_euler(&eta);
        assert!((q.to_rotation_matrix().matrix() - r).abs().max() < 1e-14);
        let prod = euler_rates_to_body(&eta) * body_to_euler_rates(&eta);
        assert!((prod - Matrix3::identity()).abs().max() < 1e-14);
    }

    #[test]
    fn given_angles_beyond_pi_when_wrapped_then_in_half_open_interval() {
        use std::f64::consts::PI;
        assert!((wrap_pi(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_pi(-3.0 * PI / 2.0) - PI / 2.0).abs() < 1e-12);
        assert!((wrap_pi(PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(-PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(0.3) - 0.3).abs() < 1e-15);
        assert_eq!(wrap_pi(-PI), PI, "exactly -pi maps to +pi, not to itself");
        assert_eq!(wrap_pi(3.0 * PI), PI);
        assert_eq!(wrap_pi(0.5), 0.5);
        assert!((wrap_pi(-0.1 - std::f64::consts::TAU) + 0.1).abs() < 1e-12);
        assert!(wrap_pi(f64::NAN).is_nan());
        for k in -40..=40 {
            let a = wrap_pi(0.37 * f64::from(k));
            assert!(a > -PI && a <= PI, "{k}: {a}");
        }
    }
}
