//! The Widrow-Hoff LMS kernel of the paper's ACO (Eqs 11-18), one channel with an ADALINE bias.
//!
//! Model: `y = w phi + b` with regressor `x = [phi, 1]` (spec A.1). Per sample (Eqs 14-17):
//! `e = d - (w phi + b)`, `w <- Pi(w + 2 mu_w e phi)`, `b <- Pi(b + 2 mu_b e)`, where `Pi` is the
//! projection onto the bounds (spec A.1 item 5).
//!
//! In: the (normalised, dimensionless or in the target's unit) regressor `phi` and the measured target
//! `d`, once per tick at `sample_hz`. Out: the prediction error and the updated weights. The step sizes
//! are given as continuous-time rates `gamma` (1/s) and converted per tick as `mu = gamma / (2 f_s)`
//! (spec A.1 item 4), so the adaptation speed does not change with the loop rate. `reconfigure` changes
//! the rates and bounds of a running channel and keeps its weights (projected onto the new bounds).

/// Per-tick step size for a continuous-time adaptation rate: `mu = gamma / (2 f_s)` (spec A.1 item 4).
#[must_use]
pub fn step_size_per_tick(gamma_per_s: f64, sample_hz: f64) -> f64 {
    gamma_per_s / (2.0 * sample_hz)
}

/// Projection bounds of one LMS channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmsBounds {
    pub w_min: f64,
    pub w_max: f64,
    /// The bias is kept in `[-b_abs_max, b_abs_max]`.
    pub b_abs_max: f64,
}

/// One LMS channel: gain weight `w`, bias weight `b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmsChannel {
    w: f64,
    b: f64,
    mu_w: f64,
    mu_b: f64,
    bounds: LmsBounds,
    hit_bound: bool,
}

impl LmsChannel {
    /// A channel starting at `(w0, b0)` (clamped into the bounds), adapting at `gamma_w_per_s`,
    /// `gamma_b_per_s` (1/s) when updated `sample_hz` times a second.
    #[must_use]
    pub fn new(w0: f64, b0: f64, gamma_w_per_s: f64, gamma_b_per_s: f64, sample_hz: f64, bounds: LmsBounds) -> Self {
        Self {
            w: w0.clamp(bounds.w_min, bounds.w_max),
            b: b0.clamp(-bounds.b_abs_max, bounds.b_abs_max),
            mu_w: step_size_per_tick(gamma_w_per_s, sample_hz),
            mu_b: step_size_per_tick(gamma_b_per_s, sample_hz),
            bounds,
            hit_bound: false,
        }
    }

    /// New adaptation rates (1/s, at `sample_hz`) and bounds, keeping the weights: a weight outside the
    /// new bounds is projected onto them, which counts as a clip for [`LmsChannel::hit_bound`].
    pub fn reconfigure(&mut self, gamma_w_per_s: f64, gamma_b_per_s: f64, sample_hz: f64, bounds: LmsBounds) {
        self.mu_w = step_size_per_tick(gamma_w_per_s, sample_hz);
        self.mu_b = step_size_per_tick(gamma_b_per_s, sample_hz);
        self.bounds = bounds;
        // max/min rather than clamp: no panic even on inverted bounds (config validation reports them).
        let w = self.w.max(bounds.w_min).min(bounds.w_max);
        let b = self.b.max(-bounds.b_abs_max).min(bounds.b_abs_max);
        if w != self.w || b != self.b {
            self.hit_bound = true;
        }
        self.w = w;
        self.b = b;
    }

    /// Multiply the gain weight by `factor` (a change of the regressor's normalisation, so that `w phi`
    /// stays the same); no projection (follow with [`LmsChannel::reconfigure`]). A non-finite or
    /// non-positive factor is ignored.
    pub fn rescale_w(&mut self, factor: f64) {
        if factor.is_finite() && factor > 0.0 {
            self.w *= factor;
        }
    }

    /// The model's prediction `w phi + b` (Eq 13).
    #[must_use]
    pub fn predict(&self, phi: f64) -> f64 {
        self.w * phi + self.b
    }

    /// One LMS step on the sample `(phi, target)`; returns the a-priori error `e = target - (w phi + b)`
    /// (Eq 14). With `adapt == false` only the error is computed. A non-finite sample or error leaves the
    /// weights untouched (they can never become NaN).
    pub fn update(&mut self, phi: f64, target: f64, adapt: bool) -> f64 {
        let e = target - self.predict(phi);
        if !adapt || !e.is_finite() || !phi.is_finite() {
            return e;
        }
        let w_raw = self.w + 2.0 * self.mu_w * e * phi;
        let b_raw = self.b + 2.0 * self.mu_b * e;
        let w = w_raw.clamp(self.bounds.w_min, self.bounds.w_max);
        let b = b_raw.clamp(-self.bounds.b_abs_max, self.bounds.b_abs_max);
        if w != w_raw || b != b_raw {
            self.hit_bound = true;
        }
        self.w = w;
        self.b = b;
        e
    }

    /// Gain weight.
    #[must_use]
    pub fn w(&self) -> f64 {
        self.w
    }

    /// Bias weight.
    #[must_use]
    pub fn b(&self) -> f64 {
        self.b
    }

    /// Per-tick step sizes `(mu_w, mu_b)`.
    #[must_use]
    pub fn step_sizes(&self) -> (f64, f64) {
        (self.mu_w, self.mu_b)
    }

    /// True once any projection has clipped a weight (sticky).
    #[must_use]
    pub fn hit_bound(&self) -> bool {
        self.hit_bound
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WIDE: LmsBounds = LmsBounds { w_min: 0.1, w_max: 100.0, b_abs_max: 50.0 };

    /// Deterministic, persistently exciting regressor (no randomness in the core, not even in tests).
    fn phi_at(t_s: f64) -> f64 {
        -1.0 + 0.5 * (2.0 * std::f64::consts::PI * 0.7 * t_s).sin()
            + 0.4 * (2.0 * std::f64::consts::PI * 2.3 * t_s).cos()
    }

    #[test]
    fn given_synthetic_linear_data_when_adapting_then_weights_converge_to_truth() {
        let fs = 500.0;
        let mut ch = LmsChannel::new(9.81, 0.0, 10.0, 5.0, fs, WIDE);
        let (w_true, b_true) = (8.0, 1.5);
        for k in 0..(fs as usize * 60) {
            let phi = phi_at(k as f64 / fs);
            ch.update(phi, w_true * phi + b_true, true);
        }
        assert!((ch.w() - w_true).abs() < 1e-3, "w = {}", ch.w());
        assert!((ch.b() - b_true).abs() < 1e-3, "b = {}", ch.b());
        assert!(!ch.hit_bound());
    }

    #[test]
    fn given_truth_outside_bounds_when_adapting_then_weights_clipped_and_flag_sticky() {
        let fs = 500.0;
        let bounds = LmsBounds { w_min: 4.905, w_max: 19.62, b_abs_max: 4.0 };
        let mut ch = LmsChannel::new(9.81, 0.0, 10.0, 5.0, fs, bounds);
        let mut b_max = f64::NEG_INFINITY;
        for k in 0..(fs as usize * 30) {
            let phi = phi_at(k as f64 / fs);
            ch.update(phi, 9.81 * phi + 7.0, true);
            assert!(ch.b().abs() <= 4.0 && ch.w() >= 4.905 && ch.w() <= 19.62, "{ch:?}");
            b_max = b_max.max(ch.b());
        }
        assert_eq!(b_max, 4.0, "b should reach its bound");
        assert!(ch.hit_bound());
        // Sticky: consistent data afterwards does not clear it.
        for k in 0..1000 {
            let phi = phi_at(k as f64 / fs);
            ch.update(phi, ch.predict(phi), true);
        }
        assert!(ch.hit_bound());
    }

    #[test]
    fn given_adaptation_disabled_when_updating_then_weights_frozen_but_error_reported() {
        let mut ch = LmsChannel::new(9.81, 0.0, 10.0, 5.0, 500.0, WIDE);
        let e = ch.update(-1.0, -8.0, false);
        assert!((e - 1.81).abs() < 1e-12);
        assert_eq!((ch.w(), ch.b()), (9.81, 0.0));
    }

    #[test]
    fn given_non_finite_sample_when_updating_then_weights_not_poisoned() {
        let mut ch = LmsChannel::new(9.81, 0.0, 10.0, 5.0, 500.0, WIDE);
        ch.update(f64::NAN, 1.0, true);
        ch.update(1.0, f64::INFINITY, true);
        assert_eq!((ch.w(), ch.b()), (9.81, 0.0));
    }

    #[test]
    fn given_adapted_channel_when_reconfigured_then_weights_kept_rates_changed_and_tighter_bounds_project() {
        let mut ch = LmsChannel::new(9.81, 0.0, 10.0, 5.0, 500.0, WIDE);
        for k in 0..5000 {
            let phi = phi_at(f64::from(k) / 500.0);
            ch.update(phi, 8.0 * phi + 1.5, true);
        }
        let (w, b) = (ch.w(), ch.b());
        let mut same = ch;
        same.reconfigure(10.0, 5.0, 500.0, WIDE);
        assert_eq!(same, ch, "same settings: nothing changes");
        ch.reconfigure(20.0, 1.0, 500.0, WIDE);
        assert_eq!((ch.w(), ch.b()), (w, b));
        assert_eq!(ch.step_sizes(), (0.02, 0.001));
        assert!(!ch.hit_bound());
        ch.reconfigure(20.0, 1.0, 500.0, LmsBounds { w_min: 9.0, w_max: 20.0, b_abs_max: 1.0 });
        assert_eq!((ch.w(), ch.b()), (9.0, 1.0));
        assert!(ch.hit_bound());
        ch.rescale_w(2.0);
        assert_eq!(ch.w(), 18.0);
        ch.rescale_w(f64::NAN);
        assert_eq!(ch.w(), 18.0);
    }

    #[test]
    fn given_rates_in_per_second_when_converted_then_500_hz_gives_spec_mu() {
        assert!((step_size_per_tick(10.0, 500.0) - 0.01).abs() < 1e-15);
        assert!((step_size_per_tick(5.0, 500.0) - 0.005).abs() < 1e-15);
        assert!((step_size_per_tick(20.0, 500.0) - 0.02).abs() < 1e-15);
        assert!((step_size_per_tick(20.0, 1000.0) - 0.01).abs() < 1e-15);
    }

    /// Time (s) for the bias weight to absorb half of a step in the target, at loop rate `fs`.
    fn bias_half_time_s(fs: f64) -> f64 {
        let mut ch = LmsChannel::new(9.81, 0.0, 10.0, 5.0, fs, WIDE);
        let mut k = 0usize;
        loop {
            let t = k as f64 / fs;
            let phi = phi_at(t);
            ch.update(phi, 9.81 * phi + 2.0, true);
            k += 1;
            if ch.b() >= 1.0 || t > 10.0 {
                return t;
            }
        }
    }

    #[test]
    fn given_same_gamma_when_run_at_250_500_1000_hz_then_adaptation_time_is_rate_invariant() {
        let t500 = bias_half_time_s(500.0);
        for fs in [250.0, 1000.0] {
            let t = bias_half_time_s(fs);
            assert!((t - t500).abs() < 0.02 * t500 + 2.0 / fs, "fs {fs}: {t} s vs {t500} s at 500 Hz");
        }
        // The per-tick steps scale inversely with the rate so that 2 mu f_s stays gamma.
        let m250 = LmsChannel::new(9.81, 0.0, 10.0, 5.0, 250.0, WIDE).step_sizes();
        let m1000 = LmsChannel::new(9.81, 0.0, 10.0, 5.0, 1000.0, WIDE).step_sizes();
        assert!((2.0 * m250.0 * 250.0 - 10.0).abs() < 1e-12 && (2.0 * m1000.1 * 1000.0 - 5.0).abs() < 1e-12);
    }
}
