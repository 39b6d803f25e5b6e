//! The 16-state error-state Kalman filter (ESKF) behind the fused estimator: the mathematics only, no
//! sensor policy. In: bias-uncorrected IMU samples (specific force m/s², rates rad/s, FRD) with their
//! interval `dt` (s) at the IMU rate, and scalar observations `(H, residual, variance)` built by the
//! caller at each sensor's rate. Out: the nominal state (NED position m, NED velocity m/s, attitude
//! `q_ned_frd`, accelerometer bias m/s² FRD, gyro bias rad/s FRD, barometer offset m) and its covariance.
//!
//! Nominal propagation (per IMU sample, the sample held over the interval ending at it):
//! `q <- q exp((w - b_g) dt)`, `a_ned = R_mid (f - b_a) + g e3`, `p <- p + v dt + a dt²/2`, `v <- v + a dt`,
//! with `R_mid` the attitude at the middle of the interval.
//!
//! Error state `dx = [dp, dv, dtheta, db_a, db_g, db_baro]`, the attitude error in the NED frame
//! (`q_true = exp(dtheta) q`), so that a yaw error is exactly `dtheta_z` and resets of one axis are clean:
//!
//! ```text
//! dp'      = dv
//! dv'      = -[R (f - b_a)]x dtheta - R db_a + n_a
//! dtheta'  = -R db_g + n_g
//! db_a'    = n_ba,   db_g' = n_bg,   db_baro' = n_baro       (random walks)
//! ```
//!
//! discretised as `F = I + A dt`, `P <- F P Fᵀ + Q`. Observations are fused one scalar at a time
//! (independent noises, so this equals the vector update), after a gate on every component's normalised
//! innovation against the prior covariance (all components pass or the whole measurement is rejected).
//! The correction is injected into the nominal state at the end of each measurement and the error state
//! returns to zero; the reset Jacobian is taken as identity (the usual first-order ESKF choice).

use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};

/// Standard gravity (m/s²), `g e3` in NED.
pub const GRAVITY_MPS2: f64 = 9.806_65;

/// Number of error states.
pub const NX: usize = 16;
/// Error-state covariance.
pub type Cov = SMatrix<f64, NX, NX>;
/// An error-state vector (or an observation row `H`).
pub type ErrVec = SVector<f64, NX>;

/// Index of the first component of each error-state block.
pub mod idx {
    /// NED position (m), 3.
    pub const POS: usize = 0;
    /// NED velocity (m/s), 3.
    pub const VEL: usize = 3;
    /// Attitude error about the NED axes (rad), 3.
    pub const ATT: usize = 6;
    /// Accelerometer bias (m/s², FRD), 3.
    pub const ACC_BIAS: usize = 9;
    /// Gyro bias (rad/s, FRD), 3.
    pub const GYRO_BIAS: usize = 12;
    /// Barometer offset (m): `baro_alt = -pos_d + offset`.
    pub const BARO: usize = 15;
}

/// Smallest variance kept on the diagonal after an update (guards against round-off going negative).
const MIN_VARIANCE: f64 = 1e-12;

/// The nominal (full) state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nominal {
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    pub q_ned_frd: UnitQuaternion<f64>,
    pub accel_bias_frd_mps2: Vector3<f64>,
    pub gyro_bias_frd_radps: Vector3<f64>,
    /// Barometric altitude of the local `D = 0` level (m): `pressure_alt_m = -pos_d + baro_offset_m`.
    pub baro_offset_m: f64,
}

/// Process noise. The IMU noises are the standard deviation of one sample at the IMU rate (as PX4's
/// `EKF2_ACC_NOISE`/`EKF2_GYR_NOISE`); the random walks are densities per square-root second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProcessNoise {
    pub accel_mps2: f64,
    pub gyro_radps: f64,
    pub accel_bias_walk: f64,
    pub gyro_bias_walk: f64,
    pub baro_offset_walk: f64,
}

/// One scalar observation: `residual = z - h(x) ≈ h · dx + noise`, noise variance `variance`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalarObs {
    pub h: ErrVec,
    pub residual: f64,
    pub variance: f64,
}

impl ScalarObs {
    /// An observation of a single error-state component `index` (`h` = unit vector).
    #[must_use]
    pub fn direct(index: usize, residual: f64, variance: f64) -> Self {
        let mut h = ErrVec::zeros();
        h[index] = 1.0;
        Self { h, residual, variance }
    }
}

/// What a measurement update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// Fused: the error-state correction that was injected, and the largest normalised innovation
    /// squared `residual² / (h P hᵀ + r)` over the components (expected about 1 when consistent).
    Fused { correction: ErrVec, nis_max: f64 },
    /// Rejected by the gate: the largest normalised innovation squared.
    Rejected { nis_max: f64 },
}

/// `[v]x`, the cross-product matrix.
#[must_use]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `F P Fᵀ` for the transition `F = I + G` of [`Eskf::predict`], whose only non-zero blocks of `G` are
/// `G[POS, VEL] = I dt`, `G[VEL, ATT] = b_va`, `G[VEL, ACC_BIAS] = b_r` and `G[ATT, GYRO_BIAS] = b_r`.
/// Done block-wise (`A = P + G P`, then `A + A Gᵀ`): about 1/6 of the multiply-adds of the dense 16x16
/// products, which were most of a vehicle step.
#[must_use]
pub fn propagate(p: &Cov, dt_s: f64, b_va: &Matrix3<f64>, b_r: &Matrix3<f64>) -> Cov {
    use idx::{ACC_BIAS, ATT, GYRO_BIAS, POS, VEL};
    // A = F P: only the POS, VEL and ATT rows change, each from the original rows of P.
    let mut a = *p;
    for c in 0..NX {
        for k in 0..3 {
            let mut vel = p[(VEL + k, c)];
            let mut att = p[(ATT + k, c)];
            for m in 0..3 {
                vel += b_va[(k, m)] * p[(ATT + m, c)] + b_r[(k, m)] * p[(ACC_BIAS + m, c)];
                att += b_r[(k, m)] * p[(GYRO_BIAS + m, c)];
            }
            a[(POS + k, c)] = p[(POS + k, c)] + dt_s * p[(VEL + k, c)];
            a[(VEL + k, c)] = vel;
            a[(ATT + k, c)] = att;
        }
    }
    // A Fᵀ: only the POS, VEL and ATT columns change, each from the original columns of A.
    let mut out = a;
    for r in 0..NX {
        for k in 0..3 {
            let mut vel = a[(r, VEL + k)];
            let mut att = a[(r, ATT + k)];
            for m in 0..3 {
                vel += a[(r, ATT + m)] * b_va[(k, m)] + a[(r, ACC_BIAS + m)] * b_r[(k, m)];
                att += a[(r, GYRO_BIAS + m)] * b_r[(k, m)];
            }
            out[(r, POS + k)] = a[(r, POS + k)] + dt_s * a[(r, VEL + k)];
            out[(r, VEL + k)] = vel;
            out[(r, ATT + k)] = att;
        }
    }
    out
}

/// The filter: nominal state and error covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct Eskf {
    pub x: Nominal,
    pub p: Cov,
}

impl Eskf {
    /// A filter at `x` with a diagonal covariance of the given variances.
    #[must_use]
    pub fn new(x: Nominal, variances: &ErrVec) -> Self {
        Self { x, p: Cov::from_diagonal(variances) }
    }

    /// Propagates over `dt_s` with the raw IMU sample (biases are removed here).
    pub fn predict(
        &mut self,
        dt_s: f64,
        gyro_frd_radps: &Vector3<f64>,
        accel_frd_mps2: &Vector3<f64>,
        noise: &ProcessNoise,
    ) {
        let rate_frd_radps = gyro_frd_radps - self.x.gyro_bias_frd_radps;
        let force_frd_mps2 = accel_frd_mps2 - self.x.accel_bias_frd_mps2;
        let half_step = UnitQuaternion::from_scaled_axis(rate_frd_radps * (0.5 * dt_s));
        let q_mid = self.x.q_ned_frd * half_step;
        let force_ned_mps2 = q_mid * force_frd_mps2;
        let accel_ned_mps2 = force_ned_mps2 + Vector3::new(0.0, 0.0, GRAVITY_MPS2);

        self.x.pos_ned_m += self.x.vel_ned_mps * dt_s + accel_ned_mps2 * (0.5 * dt_s * dt_s);
        self.x.vel_ned_mps += accel_ned_mps2 * dt_s;
        let mut q = (q_mid * half_step).into_inner();
        q.normalize_mut();
        self.x.q_ned_frd = UnitQuaternion::new_unchecked(q);

        let r_ned_frd = q_mid.to_rotation_matrix().into_inner();
        self.p = propagate(&self.p, dt_s, &(-skew(&force_ned_mps2) * dt_s), &(-r_ned_frd * dt_s));

        let vel_var = (noise.accel_mps2 * dt_s).powi(2);
        let att_var = (noise.gyro_radps * dt_s).powi(2);
        let acc_bias_var = noise.accel_bias_walk.powi(2) * dt_s;
        let gyro_bias_var = noise.gyro_bias_walk.powi(2) * dt_s;
        for i in 0..3 {
            self.p[(idx::VEL + i, idx::VEL + i)] += vel_var;
            self.p[(idx::ATT + i, idx::ATT + i)] += att_var;
            self.p[(idx::ACC_BIAS + i, idx::ACC_BIAS + i)] += acc_bias_var;
            self.p[(idx::GYRO_BIAS + i, idx::GYRO_BIAS + i)] += gyro_bias_var;
        }
        self.p[(idx::BARO, idx::BARO)] += noise.baro_offset_walk.powi(2) * dt_s;
        self.symmetrise();
    }

    /// Gates, then fuses the scalar observations in turn and injects the correction. `gate_sigma` is the
    /// largest accepted innovation in standard deviations (`f64::INFINITY` fuses unconditionally).
    pub fn fuse(&mut self, observations: &[ScalarObs], gate_sigma: f64) -> Outcome {
        let mut nis_max: f64 = 0.0;
        for obs in observations {
            let s = obs.h.dot(&(self.p * obs.h)) + obs.variance;
            nis_max = nis_max.max(obs.residual * obs.residual / s);
        }
        if nis_max.is_nan() || nis_max > gate_sigma * gate_sigma {
            return Outcome::Rejected { nis_max };
        }
        let mut correction = ErrVec::zeros();
        for obs in observations {
            let ph = self.p * obs.h;
            let s = obs.h.dot(&ph) + obs.variance;
            if s.is_nan() || s <= 0.0 {
                continue;
            }
            let gain = ph / s;
            let innovation = obs.residual - obs.h.dot(&correction);
            correction += gain * innovation;
            self.p -= gain * ph.transpose();
        }
        self.symmetrise();
        self.inject(&correction);
        Outcome::Fused { correction, nis_max }
    }

    /// Adds an error-state correction to the nominal state.
    pub fn inject(&mut self, dx: &ErrVec) {
        self.x.pos_ned_m += dx.fixed_rows::<3>(idx::POS);
        self.x.vel_ned_mps += dx.fixed_rows::<3>(idx::VEL);
        let dtheta = Vector3::from(dx.fixed_rows::<3>(idx::ATT));
        let mut q = (UnitQuaternion::from_scaled_axis(dtheta) * self.x.q_ned_frd).into_inner();
        q.normalize_mut();
        self.x.q_ned_frd = UnitQuaternion::new_unchecked(q);
        self.x.accel_bias_frd_mps2 += dx.fixed_rows::<3>(idx::ACC_BIAS);
        self.x.gyro_bias_frd_radps += dx.fixed_rows::<3>(idx::GYRO_BIAS);
        self.x.baro_offset_m += dx[idx::BARO];
    }

    /// Forgets every correlation of component `i` and sets its variance (after a state reset to an
    /// independent measurement).
    pub fn reset_component(&mut self, i: usize, variance: f64) {
        self.p.row_mut(i).fill(0.0);
        self.p.column_mut(i).fill(0.0);
        self.p[(i, i)] = variance;
    }

    /// Caps the variance of component `i` at `max_variance`, scaling its row and column so the matrix
    /// stays positive semi-definite (`D P D` with `D` diagonal and positive).
    pub fn cap_variance(&mut self, i: usize, max_variance: f64) {
        let var = self.p[(i, i)];
        if var > max_variance {
            let scale = (max_variance / var).sqrt();
            self.p.row_mut(i).scale_mut(scale);
            self.p.column_mut(i).scale_mut(scale);
        }
    }

    /// Standard deviation of component `i`.
    #[must_use]
    pub fn std(&self, i: usize) -> f64 {
        self.p[(i, i)].max(0.0).sqrt()
    }

    fn symmetrise(&mut self) {
        for i in 0..NX {
            for j in (i + 1)..NX {
                let mean = 0.5 * (self.p[(i, j)] + self.p[(j, i)]);
                self.p[(i, j)] = mean;
                self.p[(j, i)] = mean;
            }
        }
        for i in 0..NX {
            if self.p[(i, i)].is_nan() || self.p[(i, i)] < MIN_VARIANCE {
                self.p[(i, i)] = MIN_VARIANCE;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn level_at_rest() -> Eskf {
        let x = Nominal {
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: UnitQuaternion::identity(),
            accel_bias_frd_mps2: Vector3::zeros(),
            gyro_bias_frd_radps: Vector3::zeros(),
            baro_offset_m: 0.0,
        };
        Eskf::new(x, &ErrVec::from_element(0.01))
    }

    proptest::proptest! {
        /// The Euler angles used throughout the estimator are nalgebra's `euler_angles` /
        /// `from_euler_angles`: the spec's ZYX convention (A.2, `R = Rz(psi) Ry(theta) Rx(phi)`, Hamilton,
        /// FRD -> NED), checked on random attitudes against the controllers' own `R(eta)`.
        #[test]
        fn given_random_quaternions_when_converted_to_euler_then_the_spec_zyx_rotation_comes_back(
            w in -1.0f64..1.0, x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0
        ) {
            let raw = nalgebra::Quaternion::new(w, x, y, z);
            proptest::prop_assume!(raw.norm() > 1e-3);
            let q = UnitQuaternion::new_normalize(raw);
            let (roll, pitch, yaw) = q.euler_angles();
            proptest::prop_assert!(pitch.abs() <= std::f64::consts::FRAC_PI_2);
            let spec_r = crate::core::control::frames::rotation_ned_frd(&Vector3::new(roll, pitch, yaw));
            let worst = (spec_r - q.to_rotation_matrix().into_inner()).abs().max();
            proptest::prop_assert!(worst < 1e-7, "{worst:e}");
            let back = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
            proptest::prop_assert!(back.angle_to(&q) < 1e-7, "{} rad", back.angle_to(&q));
        }
    }

    #[test]
    fn given_any_covariance_when_propagated_blockwise_then_it_equals_the_dense_f_p_ft() {
        // A symmetric positive-definite P with every entry non-zero, and non-trivial blocks.
        let m = Cov::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.01 - 0.05);
        let p = m * m.transpose() + Cov::identity() * 0.1;
        let dt = 0.002;
        let b_va = -skew(&Vector3::new(0.3, -0.2, -9.8)) * dt;
        let r = UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7).to_rotation_matrix().into_inner();
        let b_r = -r * dt;
        let mut f = Cov::identity();
        f.fixed_view_mut::<3, 3>(idx::POS, idx::VEL).copy_from(&(Matrix3::identity() * dt));
        f.fixed_view_mut::<3, 3>(idx::VEL, idx::ATT).copy_from(&b_va);
        f.fixed_view_mut::<3, 3>(idx::VEL, idx::ACC_BIAS).copy_from(&b_r);
        f.fixed_view_mut::<3, 3>(idx::ATT, idx::GYRO_BIAS).copy_from(&b_r);
        let dense = f * p * f.transpose();
        let blockwise = propagate(&p, dt, &b_va, &b_r);
        let worst = (dense - blockwise).abs().max();
        assert!(worst < 1e-15, "largest difference {worst:e}");
    }

    const QUIET: ProcessNoise = ProcessNoise {
        accel_mps2: 0.1,
        gyro_radps: 0.01,
        accel_bias_walk: 0.0,
        gyro_bias_walk: 0.0,
        baro_offset_walk: 0.0,
    };

    #[test]
    fn given_a_constant_rate_and_force_when_predicted_then_the_nominal_state_follows_the_kinematics() {
        let mut f = level_at_rest();
        let rate = Vector3::new(0.0, 0.0, 0.5);
        // Level, accelerating 1 m/s² north in a yawing body: the body-frame force rotates against the yaw.
        for k in 0..1000 {
            let t_mid = (f64::from(k) + 0.5) * 0.001;
            let psi = 0.5 * t_mid;
            let force_frd = Vector3::new(psi.cos(), -psi.sin(), -GRAVITY_MPS2);
            f.predict(0.001, &rate, &force_frd, &QUIET);
        }
        let (_, _, yaw) = f.x.q_ned_frd.euler_angles();
        assert!((yaw - 0.5).abs() < 1e-12, "yaw {yaw}");
        assert!((f.x.vel_ned_mps - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-6, "{}", f.x.vel_ned_mps);
        assert!((f.x.pos_ned_m - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-6, "{}", f.x.pos_ned_m);
    }

    #[test]
    fn given_an_accelerometer_bias_when_hovering_then_velocity_variance_grows_and_couples_to_the_bias() {
        let mut f = level_at_rest();
        for _ in 0..100 {
            f.predict(0.01, &Vector3::zeros(), &Vector3::new(0.0, 0.0, -GRAVITY_MPS2), &QUIET);
        }
        assert!(f.p[(idx::VEL, idx::VEL)] > 0.01);
        // dv_n' = -db_a,n (level): negative correlation between north velocity and the x bias.
        assert!(f.p[(idx::VEL, idx::ACC_BIAS)] < 0.0);
        // dv_n' = -g dtheta_e (a positive rotation about east tilts the thrust south): negative correlation.
        assert!(f.p[(idx::VEL, idx::ATT + 1)] < 0.0);
    }

    #[test]
    fn given_a_direct_observation_when_fused_then_the_state_moves_by_the_kalman_fraction() {
        let mut f = level_at_rest();
        let outcome = f.fuse(&[ScalarObs::direct(idx::POS, 0.1, 0.01)], 5.0);
        assert!(matches!(outcome, Outcome::Fused { nis_max, .. } if (nis_max - 0.5).abs() < 1e-12));
        assert!((f.x.pos_ned_m.x - 0.05).abs() < 1e-12);
        assert!((f.p[(0, 0)] - 0.005).abs() < 1e-12);
    }

    #[test]
    fn given_an_outlier_when_fused_then_the_gate_rejects_it_and_nothing_changes() {
        let mut f = level_at_rest();
        let before = f.clone();
        // sigma = sqrt(0.02) = 0.14: a 1 m residual is 7 sigma.
        let outcome = f.fuse(&[ScalarObs::direct(idx::POS, 0.1, 0.01), ScalarObs::direct(idx::VEL, 1.0, 0.01)], 5.0);
        assert!(matches!(outcome, Outcome::Rejected { nis_max } if (nis_max - 50.0).abs() < 1e-9));
        assert_eq!(f, before);
    }

    #[test]
    fn given_an_attitude_correction_when_injected_then_it_rotates_about_the_ned_axes() {
        let mut f = level_at_rest();
        f.x.q_ned_frd = UnitQuaternion::from_euler_angles(0.0, 0.3, 0.0);
        let mut dx = ErrVec::zeros();
        dx[idx::ATT + 2] = 0.2;
        f.inject(&dx);
        let (roll, pitch, yaw) = f.x.q_ned_frd.euler_angles();
        assert!((Vector3::new(roll, pitch, yaw) - Vector3::new(0.0, 0.3, 0.2)).norm() < 1e-12, "{roll} {pitch} {yaw}");
    }

    #[test]
    fn given_a_large_variance_when_capped_then_it_is_limited_and_correlations_scale_with_it() {
        let mut f = level_at_rest();
        f.p[(0, 3)] = 0.005;
        f.p[(3, 0)] = 0.005;
        f.p[(0, 0)] = 4.0;
        f.cap_variance(0, 1.0);
        assert!((f.p[(0, 0)] - 1.0).abs() < 1e-12);
        assert!((f.p[(0, 3)] - 0.0025).abs() < 1e-12);
        assert!((f.p[(3, 0)] - 0.0025).abs() < 1e-12);
    }
}
