//! The competent-CA extension of an MRAC channel (docs/controller.md §4.3), off in the paper's CA: an
//! integral of the model-following error with error feedback placing its pole, e-modification of the
//! adaptive laws, and pseudo-control hedging of the reference model against saturation.

use super::MracChannel;

impl MracChannel {
    /// Hedging: the part `deficit` of the last output the actuators did not give; the next step's
    /// reference-model acceleration is reduced by it (a non-finite deficit counts as 0).
    pub fn set_hedge(&mut self, deficit: f64) {
        self.hedge = if deficit.is_finite() { deficit } else { 0.0 };
    }

    /// This channel with the competent-CA extension: integral pole `wi` (rad/s, 0: none) and
    /// e-modification `sigma_e` (0: none). Non-finite or negative values count as 0.
    #[must_use]
    pub fn with_robustness(mut self, wi: f64, sigma_e: f64) -> Self {
        self.set_robustness(wi, sigma_e);
        self
    }

    /// Set the integral pole and the e-modification, keeping the integral (reset when `wi` is 0).
    pub(super) fn set_robustness(&mut self, wi: f64, sigma_e: f64) {
        let usable = |x: f64| if x.is_finite() && x > 0.0 { x } else { 0.0 };
        (self.wi, self.sigma_e) = (usable(wi), usable(sigma_e));
        match Self::integral_design(self.wn, self.zeta, self.wi) {
            Some((err_gains, s_weights)) => (self.err_gains, self.s_weights) = (err_gains, s_weights),
            None => {
                (self.wi, self.err_gains, self.s_weights, self.e_int) = (0.0, [0.0; 3], [0.0; 3], 0.0);
            }
        }
    }

    /// The error feedback `[kI, kP, kD] = [ωi ωn², 2ζωn ωi, ωi]` that makes the model-following error
    /// dynamics `(s + ωi)(s² + 2ζωn s + ωn²)`, and the last column `[pI, p1, p2]` of the P solving
    /// `A_eᵀP + P A_e = -I` for that companion matrix `A_e` (state `(∫e1, e1, e2)`); `None` for
    /// `wi = 0` or a model that is not Hurwitz.
    fn integral_design(wn: f64, zeta: f64, wi: f64) -> Option<([f64; 3], [f64; 3])> {
        if !(wi > 0.0 && wn > 0.0 && zeta > 0.0) {
            return None;
        }
        let (a0, a1, a2) = (wi * wn * wn, wn * wn + 2.0 * zeta * wn * wi, 2.0 * zeta * wn + wi);
        let a = nalgebra::Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -a0, -a1, -a2);
        let p = lyapunov3(&a)?;
        Some(([a0, 2.0 * zeta * wn * wi, wi], [p[(0, 2)], p[(1, 2)], p[(2, 2)]]))
    }

    /// `∫e1 dt` of the competent channel (0 for the paper's).
    #[must_use]
    pub fn error_integral(&self) -> f64 {
        self.e_int
    }

    /// [`MracChannel::step`] of the competent channel: `v = k1 x1 + k2 x2 + kr r + θ - (kI ∫e1 + kP e1 +
    /// kD e2)`, `s = pI ∫e1 + p1 e1 + p2 e2` (or the paper's `p12 e1 + p22 e2` without an integral),
    /// each parameter `ĝ -= Γ Δ (φ s + σ |s| (ĝ - ĝ0))` with `ĝ0` its initial value (0 for θ) and
    /// projected as in the paper, and `∫e1` advanced unless frozen (conditional integration), its
    /// contribution `kI ∫e1` held within the channel's `|θ|` bound; the reference model's acceleration
    /// is reduced by the hedge set since the last step.
    pub(super) fn step_competent(&mut self, x1: f64, x2: f64, r: f64, dt_s: f64, frozen: bool) -> f64 {
        let e1 = x1 - self.xm;
        let e2 = x2 - self.xm_dot;
        let s = if self.wi != 0.0 {
            let [pi, p1, p2] = self.s_weights;
            pi * self.e_int + p1 * e1 + p2 * e2
        } else {
            self.p12 * e1 + self.p22 * e2
        };
        let [k1, k2, kr] = self.gains;
        let [ki, kp, kd] = self.err_gains;
        let v = k1 * x1 + k2 * x2 + kr * r + self.theta - (ki * self.e_int + kp * e1 + kd * e2);
        if !frozen {
            let leak = self.sigma_e * s.abs();
            let nominal = Self::nominal_gains(self.wn, self.zeta);
            for (i, regressor) in [x1, x2, r].into_iter().enumerate() {
                let g = self.gains[i];
                let raw = g - self.gamma_k * dt_s * (regressor * s + leak * (g - nominal[i]));
                let [lo, hi] = self.gain_bounds[i];
                let clipped = raw.clamp(lo, hi);
                self.hit_bound |= clipped != raw;
                self.gains[i] = clipped;
            }
            let theta_raw = self.theta - self.gamma_theta * dt_s * (s + leak * self.theta);
            self.theta = theta_raw.clamp(-self.theta_max, self.theta_max);
            self.hit_bound |= self.theta != theta_raw;
            if ki > 0.0 {
                let limit = self.theta_max / ki;
                self.e_int = (self.e_int + e1 * dt_s).max(-limit).min(limit);
            }
        }
        let xm_ddot = self.wn * self.wn * (r - self.xm)
            - 2.0 * self.zeta * self.wn * self.xm_dot
            - std::mem::take(&mut self.hedge);
        self.xm_dot += dt_s * xm_ddot;
        self.xm += dt_s * self.xm_dot;
        v
    }
}

/// The solution `P` of `Aᵀ P + P A = -I` for a 3×3 `A` (Kronecker form, LU), or `None` when singular.
fn lyapunov3(a: &nalgebra::Matrix3<f64>) -> Option<nalgebra::Matrix3<f64>> {
    let mut m = nalgebra::SMatrix::<f64, 9, 9>::zeros();
    // vec(AᵀP + PA) = (I ⊗ Aᵀ + Aᵀ ⊗ I) vec(P), column-major vec.
    for i in 0..3 {
        for j in 0..3 {
            let row = i + 3 * j;
            for k in 0..3 {
                m[(row, k + 3 * j)] += a[(k, i)];
                m[(row, i + 3 * k)] += a[(k, j)];
            }
        }
    }
    let rhs = -nalgebra::SVector::<f64, 9>::from_column_slice(nalgebra::Matrix3::<f64>::identity().as_slice());
    let x = m.lu().solve(&rhs)?;
    let p = nalgebra::Matrix3::from_column_slice(x.as_slice());
    p.iter().all(|v| v.is_finite()).then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::mrac::MracConfig;

    #[test]
    fn given_default_config_when_built_then_no_competent_option_is_on() {
        assert!(!MracConfig::default().is_competent());
        assert!(MracConfig::competent().is_competent());
        let ch = MracChannel::new(5.0, 0.9, 1000.0, 1000.0, 8.0, [0.2, 5.0]);
        assert_eq!(ch.with_robustness(0.0, 0.0), ch, "zero poles and sigma leave the paper's channel");
        assert_eq!(ch.with_robustness(f64::NAN, -1.0), ch, "unusable values count as off");
    }

    #[test]
    fn given_integral_pole_when_designed_then_error_dynamics_have_it_and_p_solves_lyapunov_to_1e_9() {
        let (wn, zeta, wi) = (5.0, 0.9, 2.0);
        let ([ki, kp, kd], [pi, p1, p2]) = MracChannel::integral_design(wn, zeta, wi).expect("Hurwitz");
        // (s + wi)(s² + 2ζωn s + ωn²) = s³ + (2ζωn + wi) s² + (ωn² + 2ζωn wi) s + wi ωn².
        assert!((ki - wi * wn * wn).abs() < 1e-12 && (kp - 2.0 * zeta * wn * wi).abs() < 1e-12 && kd == wi);
        let (a0, a1, a2) = (ki, wn * wn + kp, 2.0 * zeta * wn + kd);
        let a = nalgebra::Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -a0, -a1, -a2);
        let p = lyapunov3(&a).expect("solvable");
        let residual = a.transpose() * p + p * a + nalgebra::Matrix3::identity();
        assert!(residual.abs().max() < 1e-9, "{residual}");
        assert!(p.symmetric_eigen().eigenvalues.min() > 0.0, "P positive definite");
        assert_eq!([pi, p1, p2], [p[(0, 2)], p[(1, 2)], p[(2, 2)]]);
        assert!(MracChannel::integral_design(wn, zeta, 0.0).is_none());
    }
}
