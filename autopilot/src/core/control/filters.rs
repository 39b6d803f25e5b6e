//! Second-order Butterworth low-pass filters for the LMS identification (spec A.1 item 7, A.4 steps
//! 2-3: 8 Hz on the translation channels, 15 Hz on the rotation channels).
//!
//! In: one sample per call at the fixed rate `sample_hz` (the inner loop rate), any unit. Out: the
//! filtered sample, same unit. Discretisation: bilinear (Tustin) transform with the cutoff prewarped,
//! `K = tan(pi fc / fs)`, which is what `scipy.signal.butter(2, fc, fs=fs)` produces; the gain at `fc` is
//! exactly -3 dB and the DC gain exactly 1. Realisation: transposed direct form II (as `scipy.signal.
//! lfilter`), and `reset_to(x)` sets the steady state for a constant input `x` (as `lfilter_zi * x`).
//! `retune(fc, fs)` changes the cutoff while running: the filter keeps its last two inputs and outputs
//! and rebuilds its state from them with the new coefficients, so the output does not jump.

use nalgebra::Vector3;

/// Highest cutoff accepted, as a fraction of the sample rate: the prewarped design needs fc < fs/2, and
/// a cutoff above this is clamped to it so the filter stays stable and finite whatever it is given.
const MAX_CUTOFF_FRACTION: f64 = 0.45;

/// 2nd-order Butterworth low-pass, one channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass2 {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
    z1: f64,
    z2: f64,
    last_output: f64,
    /// The last input `x[n]`, the one before it `x[n-1]` and the output before the last `y[n-1]`: the
    /// history [`LowPass2::retune`] rebuilds the state from.
    last_input: f64,
    input_before: f64,
    output_before: f64,
}

impl LowPass2 {
    /// A filter with cutoff `cutoff_hz` sampled at `sample_hz`, at rest at zero.
    ///
    /// A cutoff outside `(0, 0.45 sample_hz]` is clamped into it (config validation reports it first;
    /// this keeps the control path free of panics and NaN).
    #[must_use]
    pub fn new(cutoff_hz: f64, sample_hz: f64) -> Self {
        let ([b0, b1, b2], [_, a1, a2]) = Self::design(cutoff_hz, sample_hz);
        Self {
            b0,
            b1,
            b2,
            a1,
            a2,
            z1: 0.0,
            z2: 0.0,
            last_output: 0.0,
            last_input: 0.0,
            input_before: 0.0,
            output_before: 0.0,
        }
    }

    /// The coefficients `([b0, b1, b2], [1, a1, a2])` for `cutoff_hz` at `sample_hz` (clamped as in
    /// [`LowPass2::new`]).
    fn design(cutoff_hz: f64, sample_hz: f64) -> ([f64; 3], [f64; 3]) {
        let fs = if sample_hz.is_finite() && sample_hz > 0.0 { sample_hz } else { 1.0 };
        let fc = if cutoff_hz.is_finite() { cutoff_hz } else { MAX_CUTOFF_FRACTION * fs };
        let fc = fc.clamp(1e-9 * fs, MAX_CUTOFF_FRACTION * fs);
        let k = (std::f64::consts::PI * fc / fs).tan();
        let k2 = k * k;
        let sqrt2 = std::f64::consts::SQRT_2;
        let norm = 1.0 / (1.0 + sqrt2 * k + k2);
        let b0 = k2 * norm;
        ([b0, 2.0 * b0, b0], [1.0, 2.0 * (k2 - 1.0) * norm, (1.0 - sqrt2 * k + k2) * norm])
    }

    /// Change the cutoff to `cutoff_hz` (at `sample_hz`, clamped as in [`LowPass2::new`]) without
    /// restarting: the state is rebuilt from the last two inputs and outputs, as if the new filter had
    /// produced them, so the next output continues from the last one. From the next [`LowPass2::update`].
    pub fn retune(&mut self, cutoff_hz: f64, sample_hz: f64) {
        let ([b0, b1, b2], [_, a1, a2]) = Self::design(cutoff_hz, sample_hz);
        (self.b0, self.b1, self.b2, self.a1, self.a2) = (b0, b1, b2, a1, a2);
        let (x, y) = (self.last_input, self.last_output);
        self.z2 = b2 * x - a2 * y;
        self.z1 = b1 * x - a1 * y + (b2 * self.input_before - a2 * self.output_before);
    }

    /// Put the filter in the steady state of a constant input `value` (its output is then `value`).
    pub fn reset_to(&mut self, value: f64) {
        self.z1 = value * (1.0 - self.b0);
        self.z2 = value * (self.b2 - self.a2);
        self.last_output = value;
        self.last_input = value;
        self.input_before = value;
        self.output_before = value;
    }

    /// Filter one sample.
    pub fn update(&mut self, x: f64) -> f64 {
        let y = self.b0 * x + self.z1;
        self.z1 = self.b1 * x - self.a1 * y + self.z2;
        self.z2 = self.b2 * x - self.a2 * y;
        self.input_before = self.last_input;
        self.last_input = x;
        self.output_before = self.last_output;
        self.last_output = y;
        y
    }

    /// The last output (the reset value before any update).
    #[must_use]
    pub fn output(&self) -> f64 {
        self.last_output
    }

    /// Numerator and denominator `([b0, b1, b2], [1, a1, a2])` of the discrete transfer function.
    #[must_use]
    pub fn coefficients(&self) -> ([f64; 3], [f64; 3]) {
        ([self.b0, self.b1, self.b2], [1.0, self.a1, self.a2])
    }
}

/// Three independent [`LowPass2`] channels with the same design, for a vector signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass2Vec3 {
    axes: [LowPass2; 3],
}

impl LowPass2Vec3 {
    /// Three channels with cutoff `cutoff_hz` sampled at `sample_hz`, at rest at zero.
    #[must_use]
    pub fn new(cutoff_hz: f64, sample_hz: f64) -> Self {
        Self { axes: [LowPass2::new(cutoff_hz, sample_hz); 3] }
    }

    /// Steady state of a constant input `value`.
    pub fn reset_to(&mut self, value: &Vector3<f64>) {
        for (axis, v) in self.axes.iter_mut().zip(value.iter()) {
            axis.reset_to(*v);
        }
    }

    /// Change the cutoff of every channel without restarting (see [`LowPass2::retune`]).
    pub fn retune(&mut self, cutoff_hz: f64, sample_hz: f64) {
        for axis in &mut self.axes {
            axis.retune(cutoff_hz, sample_hz);
        }
    }

    /// Filter one vector sample.
    pub fn update(&mut self, x: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(self.axes[0].update(x.x), self.axes[1].update(x.y), self.axes[2].update(x.z))
    }

    /// The last output.
    #[must_use]
    pub fn output(&self) -> Vector3<f64> {
        Vector3::new(self.axes[0].output(), self.axes[1].output(), self.axes[2].output())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steady-state amplitude of the filter's response to a unit sine at `freq_hz`.
    fn sine_gain(cutoff_hz: f64, sample_hz: f64, freq_hz: f64) -> f64 {
        let mut f = LowPass2::new(cutoff_hz, sample_hz);
        let n = (sample_hz * 20.0) as usize;
        let mut peak: f64 = 0.0;
        for k in 0..n {
            let t = k as f64 / sample_hz;
            let y = f.update((2.0 * std::f64::consts::PI * freq_hz * t).sin());
            if k > n / 2 {
                peak = peak.max(y.abs());
            }
        }
        peak
    }

    #[test]
    fn given_constant_input_when_filtered_long_then_output_equals_input_dc_gain_one() {
        let mut f = LowPass2::new(8.0, 500.0);
        let mut y = 0.0;
        for _ in 0..2000 {
            y = f.update(3.5);
        }
        assert!((y - 3.5).abs() < 1e-12, "y = {y}");
        let (b, a) = f.coefficients();
        let dc = b.iter().sum::<f64>() / a.iter().sum::<f64>();
        assert!((dc - 1.0).abs() < 1e-12, "dc = {dc}");
    }

    #[test]
    fn given_sine_at_cutoff_when_filtered_then_gain_is_minus_3_db() {
        for (fc, fs) in [(8.0, 500.0), (15.0, 500.0), (15.0, 250.0), (8.0, 1000.0)] {
            let g = sine_gain(fc, fs, fc);
            assert!((g - std::f64::consts::FRAC_1_SQRT_2).abs() < 2e-3, "fc {fc} fs {fs}: gain {g}");
        }
    }

    #[test]
    fn given_sine_well_above_cutoff_when_filtered_then_attenuated_40_db_per_decade() {
        let g = sine_gain(8.0, 500.0, 80.0);
        assert!(g < 0.012 && g > 0.005, "gain at 10 fc = {g}");
    }

    #[test]
    fn given_reset_to_value_when_fed_that_value_then_output_stays_there() {
        let mut f = LowPass2::new(15.0, 500.0);
        f.reset_to(-9.81);
        assert_eq!(f.output(), -9.81);
        for _ in 0..10 {
            let y = f.update(-9.81);
            assert!((y + 9.81).abs() < 1e-12, "y = {y}");
        }
    }

    #[test]
    fn given_vector_filter_when_reset_and_stepped_then_each_axis_independent() {
        let mut f = LowPass2Vec3::new(8.0, 500.0);
        f.reset_to(&Vector3::new(0.0, 0.0, -9.81));
        let y = f.update(&Vector3::new(1.0, 0.0, -9.81));
        assert!(y.x > 0.0 && y.x < 0.01, "{y}");
        assert_eq!(y.y, 0.0);
        assert!((y.z + 9.81).abs() < 1e-12);
    }

    /// The response of `f` to a deterministic, wide-band input over `n` samples starting at sample `k0`.
    fn run(f: &mut LowPass2, k0: usize, n: usize) -> Vec<f64> {
        (k0..k0 + n).map(|k| f.update((0.37 * k as f64).sin() + 0.5 * (0.011 * k as f64).cos())).collect()
    }

    #[test]
    fn given_running_filter_when_retuned_to_its_own_cutoff_then_output_unchanged() {
        let mut plain = LowPass2::new(8.0, 500.0);
        run(&mut plain, 0, 300);
        let mut retuned = plain;
        retuned.retune(8.0, 500.0);
        let (a, b) = (run(&mut plain, 300, 300), run(&mut retuned, 300, 300));
        for (x, y) in a.iter().zip(b.iter()) {
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
    }

    #[test]
    fn given_steady_state_when_retuned_then_output_does_not_jump() {
        let mut f = LowPass2::new(8.0, 500.0);
        f.reset_to(-51.0);
        for _ in 0..10 {
            f.update(-51.0);
        }
        f.retune(15.0, 500.0);
        for _ in 0..10 {
            let y = f.update(-51.0);
            assert!((y + 51.0).abs() < 1e-9, "y = {y}");
        }
    }

    #[test]
    fn given_filter_retuned_from_8_to_15_hz_when_fed_history_then_behaves_as_a_15_hz_filter() {
        // The same input history through a filter built at 15 Hz and one retuned to 15 Hz: once the
        // retuned one has seen two samples of the new design, the two outputs coincide up to the decay
        // of the different pasts, which is at least as fast as the new filter's poles.
        let mut retuned = LowPass2::new(8.0, 500.0);
        let mut native = LowPass2::new(15.0, 500.0);
        run(&mut retuned, 0, 500);
        run(&mut native, 0, 500);
        retuned.retune(15.0, 500.0);
        let (a, b) = (run(&mut retuned, 500, 1000), run(&mut native, 500, 1000));
        let gap_start = (a[0] - b[0]).abs();
        let gap_end = (a[999] - b[999]).abs();
        assert!(gap_end < 1e-6 * (1.0 + gap_start), "{gap_start} -> {gap_end}");
        assert_eq!(retuned.coefficients(), native.coefficients());
        let mut f = LowPass2Vec3::new(8.0, 500.0);
        f.retune(15.0, 500.0);
        assert_eq!(f.axes[2].coefficients(), native.coefficients());
    }

    #[test]
    fn given_cutoff_above_nyquist_when_built_then_output_stays_finite() {
        let mut f = LowPass2::new(400.0, 500.0);
        for k in 0..1000 {
            assert!(f.update(f64::from(k % 2)).is_finite());
        }
    }
}
