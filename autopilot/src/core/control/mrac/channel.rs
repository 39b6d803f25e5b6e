//! One SISO MRAC channel of the CA baseline (spec (c)): the reference model, the control law
//! `v = k1 x1 + k2 x2 + kr r + theta`, the Lyapunov-weighted error `s = p12 e1 + p22 e2`, the gradient
//! laws with projection and the saturation freeze. The competent-CA extension of the channel (integral,
//! e-modification, hedging) is in `competent`.

/// One SISO MRAC channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MracChannel {
    /// `[k1, k2, kr]`.
    pub(super) gains: [f64; 3],
    pub(super) theta: f64,
    pub(super) gain_bounds: [[f64; 2]; 3],
    pub(super) theta_max: f64,
    pub(super) wn: f64,
    pub(super) zeta: f64,
    pub(super) p12: f64,
    pub(super) p22: f64,
    pub(super) gamma_k: f64,
    pub(super) gamma_theta: f64,
    pub(super) xm: f64,
    pub(super) xm_dot: f64,
    pub(super) active: bool,
    pub(super) hit_bound: bool,
    /// Competent CA: the integral pole ωi (rad/s; 0: the paper's channel).
    pub(super) wi: f64,
    /// `[kI, kP, kD]` of the model-following error feedback (zero when `wi = 0`).
    pub(super) err_gains: [f64; 3],
    /// `[pI, p1, p2]`: `s = pI ∫e1 + p1 e1 + p2 e2` (the last column of the third-order Lyapunov matrix).
    pub(super) s_weights: [f64; 3],
    /// e-modification σ (0: off).
    pub(super) sigma_e: f64,
    /// `∫e1 dt`, the integral of the model-following error.
    pub(super) e_int: f64,
    /// The pseudo-control the actuators did not give at the last output (hedging; 0 when off).
    pub(super) hedge: f64,
}

impl MracChannel {
    /// A channel with reference model `(wn, zeta)`, at the nominal matching gains
    /// `k1 = -wn², k2 = -2 zeta wn, kr = wn², theta = 0`.
    #[must_use]
    pub fn new(wn: f64, zeta: f64, gamma_k: f64, gamma_theta: f64, theta_max: f64, projection: [f64; 2]) -> Self {
        let gains = Self::nominal_gains(wn, zeta);
        let (gain_bounds, p12, p22) = Self::design(wn, zeta, projection);
        Self {
            gains,
            theta: 0.0,
            gain_bounds,
            theta_max,
            wn,
            zeta,
            p12,
            p22,
            gamma_k,
            gamma_theta,
            xm: 0.0,
            xm_dot: 0.0,
            active: false,
            hit_bound: false,
            wi: 0.0,
            err_gains: [0.0; 3],
            s_weights: [0.0; 3],
            sigma_e: 0.0,
            e_int: 0.0,
            hedge: 0.0,
        }
    }

    /// The matching gains of the reference model `(wn, zeta)`: `[k1, k2, kr] = [-wn², -2 zeta wn, wn²]`.
    pub(super) fn nominal_gains(wn: f64, zeta: f64) -> [f64; 3] {
        [-wn * wn, -2.0 * zeta * wn, wn * wn]
    }

    /// The gain bounds (`projection` times the matching gains) and the Lyapunov weights `(p12, p22)`.
    fn design(wn: f64, zeta: f64, projection: [f64; 2]) -> ([[f64; 2]; 3], f64, f64) {
        let bound = |g0: f64| {
            let (a, b) = (projection[0] * g0, projection[1] * g0);
            [a.min(b), a.max(b)]
        };
        let [k1, k2, kr] = Self::nominal_gains(wn, zeta);
        let p12 = 1.0 / (2.0 * wn * wn);
        ([bound(k1), bound(k2), bound(kr)], p12, (p12 + 0.5) / (2.0 * zeta * wn))
    }

    /// New reference model, adaptation rates and bounds, keeping the adapted `[k1, k2, kr, theta]` and the
    /// reference-model state: the gain bounds follow the new matching gains, and a parameter outside the
    /// new bounds is projected onto them (which counts as a clip for [`MracChannel::hit_bound`]).
    pub fn reconfigure(
        &mut self,
        wn: f64,
        zeta: f64,
        gamma_k: f64,
        gamma_theta: f64,
        theta_max: f64,
        projection: [f64; 2],
    ) {
        let (gain_bounds, p12, p22) = Self::design(wn, zeta, projection);
        (self.wn, self.zeta, self.p12, self.p22) = (wn, zeta, p12, p22);
        (self.gamma_k, self.gamma_theta, self.gain_bounds, self.theta_max) =
            (gamma_k, gamma_theta, gain_bounds, theta_max);
        for (gain, [lo, hi]) in self.gains.iter_mut().zip(gain_bounds) {
            // max/min rather than clamp: no panic on a non-finite bound.
            let projected = gain.max(lo).min(hi);
            self.hit_bound |= projected != *gain;
            *gain = projected;
        }
        let theta = self.theta.max(-theta_max).min(theta_max);
        self.hit_bound |= theta != self.theta;
        self.theta = theta;
        if self.wi != 0.0 {
            // The error feedback and the weights of s follow the new reference model.
            self.set_robustness(self.wi, self.sigma_e);
        }
    }

    /// `(p12, p22)` of the Lyapunov matrix.
    #[must_use]
    pub fn lyapunov_weights(&self) -> (f64, f64) {
        (self.p12, self.p22)
    }

    /// `[k1, k2, kr, theta]`.
    #[must_use]
    pub fn parameters(&self) -> [f64; 4] {
        [self.gains[0], self.gains[1], self.gains[2], self.theta]
    }

    /// The reference model state `(x_m, x_m')`.
    #[must_use]
    pub fn reference_state(&self) -> (f64, f64) {
        (self.xm, self.xm_dot)
    }

    /// True once a projection has clipped a parameter (sticky).
    #[must_use]
    pub fn hit_bound(&self) -> bool {
        self.hit_bound
    }

    /// Switch the channel off; the next [`MracChannel::step`] restarts the reference model at the state.
    pub fn deactivate(&mut self) {
        self.active = false;
        self.hedge = 0.0;
    }

    /// One step of period `dt_s` with state `(x1, x2)` and reference `r`: returns the control
    /// `v = k1 x1 + k2 x2 + kr r + theta` computed with the current parameters, then adapts (unless
    /// `frozen`) and advances the reference model.
    pub fn step(&mut self, x1: f64, x2: f64, r: f64, dt_s: f64, frozen: bool) -> f64 {
        if !self.active {
            self.xm = x1;
            self.xm_dot = x2;
            self.e_int = 0.0;
            self.active = true;
        }
        if self.wi != 0.0 || self.sigma_e != 0.0 || self.hedge != 0.0 {
            return self.step_competent(x1, x2, r, dt_s, frozen);
        }
        let e1 = x1 - self.xm;
        let e2 = x2 - self.xm_dot;
        let s = self.p12 * e1 + self.p22 * e2;
        let [k1, k2, kr] = self.gains;
        let v = k1 * x1 + k2 * x2 + kr * r + self.theta;
        if !frozen {
            let raw = [
                k1 - self.gamma_k * x1 * s * dt_s,
                k2 - self.gamma_k * x2 * s * dt_s,
                kr - self.gamma_k * r * s * dt_s,
            ];
            for (i, value) in raw.iter().enumerate() {
                let [lo, hi] = self.gain_bounds[i];
                let clipped = value.clamp(lo, hi);
                self.hit_bound |= clipped != *value;
                self.gains[i] = clipped;
            }
            let theta_raw = self.theta - self.gamma_theta * s * dt_s;
            self.theta = theta_raw.clamp(-self.theta_max, self.theta_max);
            self.hit_bound |= self.theta != theta_raw;
        }
        let xm_ddot = self.wn * self.wn * (r - self.xm) - 2.0 * self.zeta * self.wn * self.xm_dot;
        self.xm_dot += dt_s * xm_ddot;
        self.xm += dt_s * self.xm_dot;
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_adapted_channel_when_reconfigured_with_tighter_bounds_then_projected_and_flagged() {
        let mut ch = MracChannel::new(1.2, 0.9, 0.3, 1.0, 4.0, [0.2, 5.0]);
        ch.step(0.0, 0.0, 0.0, 0.01, false);
        for _ in 0..200 {
            ch.step(0.5, 0.2, 1.0, 0.01, false);
        }
        let [_, _, _, theta] = ch.parameters();
        assert!(theta.abs() > 0.01 && !ch.hit_bound(), "{theta}");
        let mut same = ch;
        same.reconfigure(1.2, 0.9, 0.3, 1.0, 4.0, [0.2, 5.0]);
        assert_eq!(same, ch);
        ch.reconfigure(1.2, 0.9, 0.3, 1.0, 0.005, [0.2, 5.0]);
        assert_eq!(ch.parameters()[3].abs(), 0.005);
        assert!(ch.hit_bound());
        let mut moved = MracChannel::new(5.0, 0.9, 1000.0, 1000.0, 8.0, [0.2, 5.0]);
        moved.reconfigure(2.0, 0.9, 1000.0, 1000.0, 8.0, [0.2, 5.0]);
        assert_eq!(
            moved.lyapunov_weights(),
            MracChannel::new(2.0, 0.9, 1000.0, 1000.0, 8.0, [0.2, 5.0]).lyapunov_weights()
        );
        // The kept k1 = -25 lies outside the new bounds [-20, -0.8] and is projected.
        assert_eq!(moved.parameters()[0], -20.0);
    }

    #[test]
    fn given_first_step_when_channel_starts_then_reference_model_starts_at_state_and_nothing_adapts() {
        let mut ch = MracChannel::new(5.0, 0.9, 1000.0, 1000.0, 8.0, [0.2, 5.0]);
        let p0 = ch.parameters();
        let v = ch.step(0.3, 0.1, 0.0, 0.002, false);
        assert_eq!(ch.parameters(), p0, "e = 0 at the first step, so s = 0");
        assert!((v - (-25.0 * 0.3 - 9.0 * 0.1)).abs() < 1e-12);
        let (xm, xm_dot) = ch.reference_state();
        let xm_ddot = 25.0 * (0.0 - 0.3) - 9.0 * 0.1;
        assert!((xm_dot - (0.1 + 0.002 * xm_ddot)).abs() < 1e-12);
        assert!((xm - (0.3 + 0.002 * xm_dot)).abs() < 1e-12, "semi-implicit Euler");
    }

    #[test]
    fn given_frozen_channel_when_stepped_then_parameters_hold_while_reference_model_runs() {
        let mut ch = MracChannel::new(5.0, 0.9, 1000.0, 1000.0, 8.0, [0.2, 5.0]);
        ch.step(0.0, 0.0, 0.0, 0.002, false);
        let p0 = ch.parameters();
        let xm0 = ch.reference_state();
        for _ in 0..50 {
            ch.step(0.2, 0.5, 0.3, 0.002, true);
        }
        assert_eq!(ch.parameters(), p0);
        assert_ne!(ch.reference_state(), xm0);
        ch.step(0.2, 0.5, 0.3, 0.002, false);
        assert_ne!(ch.parameters(), p0);
    }

    #[test]
    fn given_huge_errors_when_adapting_then_projection_holds_bounds_and_flag_is_sticky() {
        let mut ch = MracChannel::new(1.2, 0.9, 0.3, 1.0, 4.0, [0.2, 5.0]);
        ch.step(0.0, 0.0, 0.0, 0.01, false);
        for _ in 0..20_000 {
            ch.step(50.0, 20.0, -50.0, 0.01, false);
        }
        let [k1, k2, kr, theta] = ch.parameters();
        let (k10, k20, kr0) = (-1.44, -2.16, 1.44);
        assert!(k1 <= 0.2 * k10 + 1e-12 && k1 >= 5.0 * k10 - 1e-12, "k1 {k1}");
        assert!(k2 <= 0.2 * k20 + 1e-12 && k2 >= 5.0 * k20 - 1e-12, "k2 {k2}");
        assert!(kr >= 0.2 * kr0 - 1e-12 && kr <= 5.0 * kr0 + 1e-12, "kr {kr}");
        assert!(theta.abs() <= 4.0);
        assert!(ch.hit_bound());
    }
}
