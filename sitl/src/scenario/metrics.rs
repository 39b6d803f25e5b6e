//! Scenario metrics over recorded truth: step response (overshoot, 2 % settling, steady-state error, RMS,
//! IAE, ITAE), gust recovery and its integrals, cross-track error, and the control effort of every run.
//!
//! In: sample times (s) and truth series (m, rad). Out: serialisable metric records. Definitions, checked
//! against the reference prototype's 50 Hz golden traces (they give its ACO overshoots to the printed digit
//! and its settling times within one 20 ms sample; `tests/tests/paper_scenarios.rs`):
//! - overshoot: largest excursion past the target in the direction of the step, in % of the step;
//! - settling: time from the step until the error stays within 2 % of the step (`None`: never settles);
//! - sse: largest |error| over the last 0.5 s of the segment;
//! - rms: root mean square of the error against the active setpoint;
//! - gust recovery: time from onset (or release) until the horizontal error stays below 0.10 m;
//! - fault ([`FaultMetrics`], from the fault's onset to the end): peak 3-D position error, peak tilt and
//!   yaw error, IAE of the position error, the altitude drop (how far below its reference it sank), the
//!   recovery (time until the position error stays below 0.10 m), whether it stayed within 0.3 m, and
//!   whether control was lost (tilt past 60°, PX4's FD_FAIL_R, or 1 m away, or a non-finite state).
//!
//! Banded times (settling, recovery) jump when an error grazes the band: a run that peaks at 0.099 m
//! recovers in 0 s, one at 0.101 m in a second or more. So every run also has continuous metrics:
//! - IAE = ∫ |e| dt and ITAE = ∫ (t - t0) |e| dt over each step segment, over the gust's onset window
//!   `[onset, release)` and its release window `[release, end]`, and of the cross-track error over a track;
//! - the time the horizontal error spends within 0.05, 0.10 and 0.20 m from the gust's onset to the end;
//! - control effort ([`EffortMetrics`]): ∫ mean over rotors of (PWM - the plant's hover PWM)² dt, the mean
//!   |PWM rate| and the time any rotor sits at a PWM limit.
//!
//! Integrals are left Riemann sums over the samples (one per control tick): sample k weighs the time to
//! sample k + 1, the last one the period before it.
//!
//! The fixed windows (the sse window, the gust's steady-error window, and the whole run for the gust peak
//! and RMS) are a scenario's defaults; its `[metric_windows]` table ([`MetricWindows`]) may set others.

use serde::{Deserialize, Serialize};

use crate::plant::envelope::{Feasibility, HoverEnvelope};

/// Settling band as a fraction of the step.
pub const SETTLING_BAND: f64 = 0.02;
/// The window at a segment's end over which the steady-state error is taken (s).
pub const SSE_WINDOW_S: f64 = 0.5;
/// Gust recovery band on the horizontal error (m).
pub const RECOVERY_BAND_M: f64 = 0.10;
/// The window before release over which the steady error during a gust is averaged (s).
pub const GUST_STEADY_WINDOW_S: f64 = 3.0;

/// The windows a scenario's metrics are taken over (`[metric_windows]`); the defaults are this module's
/// constants and the whole run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MetricWindows {
    /// Steps: the sse is the largest |error| over the last `step_sse_s` (s) of each segment.
    pub step_sse_s: f64,
    /// Gust: the steady error is the mean horizontal error over the `gust_steady_s` (s) before release.
    pub gust_steady_s: f64,
    /// Gust: the peak horizontal error is taken over `[from, to)` (s of simulated time); `None`: the run.
    pub gust_peak_s: Option<[f64; 2]>,
    /// Gust: the horizontal and vertical RMS are taken over `[from, to)` (s); `None`: the whole run.
    pub gust_rms_s: Option<[f64; 2]>,
}

impl Default for MetricWindows {
    fn default() -> Self {
        Self { step_sse_s: SSE_WINDOW_S, gust_steady_s: GUST_STEADY_WINDOW_S, gust_peak_s: None, gust_rms_s: None }
    }
}

impl MetricWindows {
    /// Checks every window, naming the offending key.
    ///
    /// # Errors
    /// A message naming the field: a length not finite and > 0, or a `[from, to)` not finite with
    /// `0 <= from < to`.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [("step_sse_s", self.step_sse_s), ("gust_steady_s", self.gust_steady_s)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("metric_windows.{name} must be finite and > 0 s, got {v}"));
            }
        }
        for (name, w) in [("gust_peak_s", self.gust_peak_s), ("gust_rms_s", self.gust_rms_s)] {
            if let Some([from, to]) = w
                && !(from.is_finite() && to.is_finite() && from >= 0.0 && from < to)
            {
                return Err(format!(
                    "metric_windows.{name} must be [from, to] with 0 <= from < to (s), got [{from}, {to}]"
                ));
            }
        }
        Ok(())
    }
}

/// A step on one axis: from `start` to `target`, over `[t0_s, t1_s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct StepSegment {
    pub axis: &'static str,
    pub t0_s: f64,
    pub t1_s: f64,
    pub start: f64,
    pub target: f64,
    /// Angles about a full turn (yaw): errors are wrapped to (-pi, pi].
    pub wrap: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentMetrics {
    pub axis: &'static str,
    pub t0_s: f64,
    pub step: f64,
    pub overshoot_pct: f64,
    pub settling_s: Option<f64>,
    pub sse: f64,
    pub rms: f64,
    /// ∫ |e| dt over the segment (m·s or rad·s).
    pub iae: f64,
    /// ∫ (t - t0) |e| dt over the segment (m·s² or rad·s²).
    pub itae: f64,
}

/// The horizontal-error bands whose occupancy a gust run reports (m).
pub const GUST_BANDS_M: [f64; 3] = [0.05, 0.10, 0.20];

/// The workspace's one angle wrap, to (-pi, pi], re-exported: metric users (the golden-trace tests) name it
/// here.
pub use autopilot::core::control::frames::wrap_pi;

fn in_window(t: &[f64], t0: f64, t1: f64) -> std::ops::Range<usize> {
    // Sample times are tick multiples; 1e-9 s absorbs their rounding.
    let lo = t.partition_point(|&x| x < t0 - 1e-9);
    let hi = t.partition_point(|&x| x < t1 - 1e-9);
    lo..hi.max(lo)
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
}

/// The time each sample `k` of `t` stands for: `t[k+1] - t[k]`, the last one the period before it.
fn sample_weights_s(t: &[f64]) -> impl Iterator<Item = f64> + '_ {
    let last = if t.len() >= 2 { t[t.len() - 1] - t[t.len() - 2] } else { 0.0 };
    t.windows(2).map(|w| w[1] - w[0]).chain((!t.is_empty()).then_some(last))
}

/// IAE = ∫ |e| dt and ITAE = ∫ (t - t0) |e| dt of the samples `abs_err` at times `t` (left Riemann sums).
#[must_use]
pub fn iae_itae(t: &[f64], abs_err: &[f64], t0: f64) -> (f64, f64) {
    t.iter()
        .zip(abs_err)
        .zip(sample_weights_s(t))
        .fold((0.0, 0.0), |(iae, itae), ((&tk, &e), dt)| (iae + e * dt, itae + (tk - t0) * e * dt))
}

/// The time (s) the samples `abs_err` at times `t` spend within `band` (`|e| <= band`).
#[must_use]
pub fn time_within(t: &[f64], abs_err: &[f64], band: f64) -> f64 {
    abs_err.iter().zip(sample_weights_s(t)).filter(|(e, _)| **e <= band).map(|(_, dt)| dt).sum()
}

/// The time from `t0` until `|e|` stays within `band` for the rest of the window: `Some(0)` if it never
/// leaves, `None` if it is still outside at the window's last sample.
pub(crate) fn time_to_stay_within(t: &[f64], abs_err: &[f64], t0: f64, band: f64) -> Option<f64> {
    match abs_err.iter().rposition(|&e| e > band || !e.is_finite()) {
        None => Some(0.0),
        Some(last) if last + 1 < abs_err.len() => Some(t[last + 1] - t0),
        Some(_) => None,
    }
}

/// Metrics of one step. `t` and `y` are the whole run; the segment selects its window.
#[must_use]
pub fn step_metrics(t: &[f64], y: &[f64], seg: &StepSegment) -> SegmentMetrics {
    step_metrics_in(t, y, seg, SSE_WINDOW_S)
}

/// [`step_metrics`] with the sse over the last `sse_window_s` (s) of the segment.
#[must_use]
pub fn step_metrics_in(t: &[f64], y: &[f64], seg: &StepSegment, sse_window_s: f64) -> SegmentMetrics {
    let r = in_window(t, seg.t0_s, seg.t1_s);
    let err = |v: f64| if seg.wrap { wrap_pi(v - seg.target) } else { v - seg.target };
    let step = if seg.wrap { wrap_pi(seg.target - seg.start) } else { seg.target - seg.start };
    let (tt, yy) = (&t[r.clone()], &y[r]);
    let errors: Vec<f64> = yy.iter().map(|&v| err(v)).collect();
    let past = errors.iter().map(|e| e * step.signum()).fold(0.0_f64, f64::max);
    let abs_err: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
    let sse_from = in_window(tt, seg.t1_s - sse_window_s, seg.t1_s).start;
    let (iae, itae) = iae_itae(tt, &abs_err, seg.t0_s);
    SegmentMetrics {
        axis: seg.axis,
        t0_s: seg.t0_s,
        step,
        overshoot_pct: if step == 0.0 { 0.0 } else { 100.0 * past / step.abs() },
        settling_s: time_to_stay_within(tt, &abs_err, seg.t0_s, SETTLING_BAND * step.abs()),
        sse: abs_err[sse_from..].iter().copied().fold(0.0, f64::max),
        rms: rms(errors.into_iter()),
        iae,
        itae,
    }
}

/// RMS of `y - reference` over the whole run (wrapped for angles).
#[must_use]
pub fn tracking_rms(y: &[f64], reference: &[f64], wrap: bool) -> f64 {
    rms(y.iter().zip(reference).map(|(&v, &r)| if wrap { wrap_pi(v - r) } else { v - r }))
}

/// Gust-hover metrics (see the module doc).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GustMetrics {
    pub recovery_onset_s: Option<f64>,
    pub recovery_release_s: Option<f64>,
    pub peak_m: f64,
    pub rms_xy_m: f64,
    pub steady_err_m: f64,
    pub rms_z_m: f64,
    /// ∫ horizontal error dt over `[onset, release)` (m·s).
    pub iae_onset_m_s: f64,
    /// ∫ horizontal error dt over `[release, end]` (m·s).
    pub iae_release_m_s: f64,
    /// ∫ (t - onset) horizontal error dt over `[onset, release)` (m·s²).
    pub itae_onset_m_s2: f64,
    /// ∫ (t - release) horizontal error dt over `[release, end]` (m·s²).
    pub itae_release_m_s2: f64,
    /// Time within each of [`GUST_BANDS_M`] from the onset to the end (s).
    pub within_5cm_s: f64,
    pub within_10cm_s: f64,
    pub within_20cm_s: f64,
}

/// `err_xy_m` is the horizontal distance to the hover point, `err_z_m` the vertical error, both from
/// truth; the gust starts at `onset_s` and is released at `release_s`.
#[must_use]
pub fn gust_metrics(t: &[f64], err_xy_m: &[f64], err_z_m: &[f64], onset_s: f64, release_s: f64) -> GustMetrics {
    gust_metrics_in(t, err_xy_m, err_z_m, onset_s, release_s, &MetricWindows::default())
}

/// [`gust_metrics`] over `windows` (its gust keys).
#[must_use]
pub fn gust_metrics_in(
    t: &[f64],
    err_xy_m: &[f64],
    err_z_m: &[f64],
    onset_s: f64,
    release_s: f64,
    windows: &MetricWindows,
) -> GustMetrics {
    let end = t.last().copied().unwrap_or(0.0) + 1.0;
    let during = in_window(t, onset_s, release_s);
    let after = in_window(t, release_s, end);
    let steady = in_window(t, release_s - windows.gust_steady_s, release_s);
    let within = |w: Option<[f64; 2]>| w.map_or(0..t.len(), |[from, to]| in_window(t, from, to));
    let (peak, rms_r) = (within(windows.gust_peak_s), within(windows.gust_rms_s));
    let mean = |r: std::ops::Range<usize>| {
        let n = r.len();
        if n == 0 { 0.0 } else { err_xy_m[r].iter().sum::<f64>() / n as f64 }
    };
    let (iae_onset_m_s, itae_onset_m_s2) = iae_itae(&t[during.clone()], &err_xy_m[during.clone()], onset_s);
    let (iae_release_m_s, itae_release_m_s2) = iae_itae(&t[after.clone()], &err_xy_m[after.clone()], release_s);
    let disturbed = during.start..after.end.max(during.end);
    let within = |band: f64| time_within(&t[disturbed.clone()], &err_xy_m[disturbed.clone()], band);
    let [within_5cm_s, within_10cm_s, within_20cm_s] = GUST_BANDS_M.map(within);
    GustMetrics {
        recovery_onset_s: time_to_stay_within(&t[during.clone()], &err_xy_m[during], onset_s, RECOVERY_BAND_M),
        recovery_release_s: time_to_stay_within(&t[after.clone()], &err_xy_m[after], release_s, RECOVERY_BAND_M),
        peak_m: err_xy_m[peak].iter().copied().fold(0.0, f64::max),
        rms_xy_m: rms(err_xy_m[rms_r.clone()].iter().copied()),
        steady_err_m: mean(steady),
        rms_z_m: rms(err_z_m[rms_r].iter().copied()),
        iae_onset_m_s,
        iae_release_m_s,
        itae_onset_m_s2,
        itae_release_m_s2,
        within_5cm_s,
        within_10cm_s,
        within_20cm_s,
    }
}

/// [`gust_metrics_in`] of a hover: `pos_ned_m` and `ref_ned_m` are per-axis series (N, E, D in m) sampled
/// at `t`; the errors are the horizontal distance and the down error to the reference.
#[must_use]
pub fn hover_gust_metrics(
    t: &[f64],
    pos_ned_m: &[Vec<f64>; 3],
    ref_ned_m: &[Vec<f64>; 3],
    onset_s: f64,
    release_s: f64,
    windows: &MetricWindows,
) -> GustMetrics {
    let err_xy: Vec<f64> =
        (0..t.len()).map(|k| (pos_ned_m[0][k] - ref_ned_m[0][k]).hypot(pos_ned_m[1][k] - ref_ned_m[1][k])).collect();
    let err_z: Vec<f64> = (0..t.len()).map(|k| pos_ned_m[2][k] - ref_ned_m[2][k]).collect();
    gust_metrics_in(t, &err_xy, &err_z, onset_s, release_s, windows)
}

/// The position error a fault run must stay within to hold (m): the 0.3 m.
pub const FAULT_HOLD_BAND_M: f64 = 0.3;
/// Tilt beyond which a fault run has lost control (rad): PX4's FD_FAIL_R / FD_FAIL_P default, 60°.
pub const LOST_CONTROL_TILT_RAD: f64 = std::f64::consts::FRAC_PI_3;
/// Position error beyond which a fault run has lost control (m).
pub const LOST_CONTROL_ERROR_M: f64 = 1.0;

/// What a fault (a rotor's thrust lost, a payload added) did to a hover or a track, from its onset to
/// the end of the run, judged on the plant's truth against the reference.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FaultMetrics {
    /// When the fault struck (s): the scenario's first `[[event]]`, 0 for a fault from the start.
    pub onset_s: f64,
    /// Largest 3-D distance to the reference position (m).
    pub peak_position_error_m: f64,
    /// Largest tilt from level, acos(cos φ cos θ) (rad).
    pub peak_tilt_rad: f64,
    /// Largest |yaw - reference yaw|, wrapped to ±π (rad).
    pub peak_yaw_error_rad: f64,
    /// ∫ 3-D position error dt (m·s).
    pub iae_m_s: f64,
    /// Largest depth below the reference altitude, 0 if it never sank (m).
    pub altitude_drop_m: f64,
    /// Time from the onset until the position error stays below [`RECOVERY_BAND_M`] (s; `None`: never).
    pub recovery_s: Option<f64>,
    /// The position error stayed within [`FAULT_HOLD_BAND_M`] throughout.
    pub within_0_3_m: bool,
    /// Tilt beyond [`LOST_CONTROL_TILT_RAD`], error beyond [`LOST_CONTROL_ERROR_M`], or a non-finite state.
    pub lost_control: bool,
    /// The position error at the last sample (m).
    pub final_error_m: f64,
    /// What physics allows the airframe as the run ended (its rotors' health and payload), whatever the
    /// controller: `full`, `without-yaw` (roll and pitch only: it must spin) or `infeasible`.
    pub feasibility: Feasibility,
    /// The airframe's bounds before the fault ([`crate::plant::envelope`]).
    pub envelope: HoverEnvelope,
    /// The greatest payload the autopilot's thrust limiter lets a controller carry (kg).
    pub max_payload_within_limiter_kg: f64,
}

/// The airframe a fault run judges physics by: before the fault and as the run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultPhysics {
    pub envelope: HoverEnvelope,
    pub max_payload_within_limiter_kg: f64,
    pub feasibility: Feasibility,
}

/// [`FaultMetrics`] of the samples at times `t` (truth `pos_ned_m` and `euler_rad` against `ref_ned_m` and
/// `ref_euler_rad`, per-axis series) from `onset_s` on, with the airframe's `physics`.
#[must_use]
pub fn fault_metrics(
    t: &[f64],
    pos_ned_m: &[Vec<f64>; 3],
    ref_ned_m: &[Vec<f64>; 3],
    euler_rad: &[Vec<f64>; 3],
    ref_euler_rad: &[Vec<f64>; 3],
    onset_s: f64,
    physics: FaultPhysics,
) -> FaultMetrics {
    let r = in_window(t, onset_s, f64::INFINITY);
    let err = |k: usize| {
        let d = |i: usize| pos_ned_m[i][k] - ref_ned_m[i][k];
        (d(0) * d(0) + d(1) * d(1) + d(2) * d(2)).sqrt()
    };
    let abs_err: Vec<f64> = r.clone().map(err).collect();
    let tilt: Vec<f64> =
        r.clone().map(|k| (euler_rad[0][k].cos() * euler_rad[1][k].cos()).clamp(-1.0, 1.0).acos()).collect();
    let yaw_err: Vec<f64> = r.clone().map(|k| wrap_pi(euler_rad[2][k] - ref_euler_rad[2][k]).abs()).collect();
    let drop: Vec<f64> = r.clone().map(|k| pos_ned_m[2][k] - ref_ned_m[2][k]).collect();
    let tt = &t[r];
    // NaN-propagating maxima: a non-finite sample makes the peak non-finite, not silently skipped.
    let peak =
        |v: &[f64]| v.iter().copied().fold(0.0, |a: f64, b| if b.is_nan() || a.is_nan() { f64::NAN } else { a.max(b) });
    let peak_position_error_m = peak(&abs_err);
    let peak_tilt_rad = peak(&tilt);
    let finite = peak_position_error_m.is_finite() && peak_tilt_rad.is_finite();
    FaultMetrics {
        onset_s,
        peak_position_error_m,
        peak_tilt_rad,
        peak_yaw_error_rad: peak(&yaw_err),
        iae_m_s: iae_itae(tt, &abs_err, onset_s).0,
        altitude_drop_m: peak(&drop),
        recovery_s: time_to_stay_within(tt, &abs_err, onset_s, RECOVERY_BAND_M),
        within_0_3_m: finite && peak_position_error_m <= FAULT_HOLD_BAND_M,
        lost_control: !finite || peak_tilt_rad > LOST_CONTROL_TILT_RAD || peak_position_error_m > LOST_CONTROL_ERROR_M,
        final_error_m: abs_err.last().copied().unwrap_or(0.0),
        feasibility: physics.feasibility,
        envelope: physics.envelope,
        max_payload_within_limiter_kg: physics.max_payload_within_limiter_kg,
    }
}

/// Track-following metrics over the track's active window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackMetrics {
    pub cross_track_rms_m: f64,
    pub cross_track_max_m: f64,
    pub alt_rms_m: f64,
    /// ∫ cross-track error dt over the active window (m·s).
    pub cross_track_iae_m_s: f64,
}

/// `t`, `cross_track_m` and `alt_err_m` are per-sample times and errors already restricted to the active
/// window.
#[must_use]
pub fn track_metrics(t: &[f64], cross_track_m: &[f64], alt_err_m: &[f64]) -> TrackMetrics {
    TrackMetrics {
        cross_track_rms_m: rms(cross_track_m.iter().copied()),
        cross_track_max_m: cross_track_m.iter().copied().fold(0.0, f64::max),
        alt_rms_m: rms(alt_err_m.iter().copied()),
        cross_track_iae_m_s: iae_itae(t, cross_track_m, t.first().copied().unwrap_or(0.0)).0,
    }
}

/// What the controller asked of the rotors over a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EffortMetrics {
    /// ∫ mean over rotors of (PWM - the plant's hover PWM)² dt (µs²·s).
    pub pwm_dev_sq_us2_s: f64,
    /// Mean over ticks and rotors of |PWM change| per second (µs/s).
    pub pwm_rate_mean_us_per_s: f64,
    /// Time with any rotor at its least or greatest PWM (s).
    pub saturation_s: f64,
}

/// Accumulates [`EffortMetrics`] one control tick at a time, so a run need not keep its PWM history.
#[derive(Debug, Clone, Copy)]
pub struct EffortAccumulator {
    hover_pwm_us: f64,
    pwm_limits_us: [f64; 2],
    last_pwm_us: Option<[f64; 4]>,
    dev_sq_us2_s: f64,
    change_sum_us: f64,
    rate_sum_us_per_s: f64,
    changes: u64,
    saturation_s: f64,
}

impl EffortAccumulator {
    /// Deviations are taken from `hover_pwm_us`; a rotor at or beyond `pwm_limits_us` (least, greatest) is
    /// saturated.
    #[must_use]
    pub fn new(hover_pwm_us: f64, pwm_limits_us: [f64; 2]) -> Self {
        Self {
            hover_pwm_us,
            pwm_limits_us,
            last_pwm_us: None,
            dev_sq_us2_s: 0.0,
            change_sum_us: 0.0,
            rate_sum_us_per_s: 0.0,
            changes: 0,
            saturation_s: 0.0,
        }
    }

    /// One tick's command, held for `dt_s`.
    pub fn add(&mut self, pwm_us: &[f64; 4], dt_s: f64) {
        let dev_sq = pwm_us.iter().map(|p| (p - self.hover_pwm_us).powi(2)).sum::<f64>() / 4.0;
        self.dev_sq_us2_s += dev_sq * dt_s;
        let [lo, hi] = self.pwm_limits_us;
        if pwm_us.iter().any(|&p| p <= lo || p >= hi) {
            self.saturation_s += dt_s;
        }
        if let Some(prev) = self.last_pwm_us {
            let change_us = prev.iter().zip(pwm_us).map(|(a, b)| (a - b).abs()).sum::<f64>() / 4.0;
            self.change_sum_us += change_us;
            if dt_s > 0.0 {
                self.rate_sum_us_per_s += change_us / dt_s;
            }
            self.changes += 1;
        }
        self.last_pwm_us = Some(*pwm_us);
    }

    /// Mean over the ticks and rotors of |PWM change| per tick (µs): the runs' `pwm_activity_us`.
    #[must_use]
    pub fn pwm_activity_us(&self) -> f64 {
        self.change_sum_us / self.changes.max(1) as f64
    }

    /// The run's effort so far.
    #[must_use]
    pub fn metrics(&self) -> EffortMetrics {
        EffortMetrics {
            pwm_dev_sq_us2_s: self.dev_sq_us2_s,
            pwm_rate_mean_us_per_s: if self.changes == 0 { 0.0 } else { self.rate_sum_us_per_s / self.changes as f64 },
            saturation_s: self.saturation_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn times(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * dt).collect()
    }

    #[test]
    fn given_a_first_order_step_then_settling_is_four_time_constants_and_no_overshoot() {
        let t = times(10_001, 1e-3);
        let y: Vec<f64> = t.iter().map(|&x| 1.0 - (-x).exp()).collect();
        let m = step_metrics(
            &t,
            &y,
            &StepSegment { axis: "x", t0_s: 0.0, t1_s: 10.0, start: 0.0, target: 1.0, wrap: false },
        );
        assert_eq!(m.overshoot_pct, 0.0);
        // e^-t = 0.02 at t = ln 50 = 3.912 s.
        assert!((m.settling_s.unwrap() - 50f64.ln()).abs() < 2e-3, "{:?}", m.settling_s);
        assert!(m.sse < 1e-4);
    }

    #[test]
    fn given_an_underdamped_step_down_then_overshoot_is_measured_past_the_target() {
        let t = times(20_001, 1e-3);
        // From 3 to 2, overshooting by 10 % of the step (to 1.9) and ringing out.
        let y: Vec<f64> =
            t.iter().map(|&x| 2.0 + (-x * 2.0).exp() * (1.0 - 1.1 * (x * 3.0).sin().powi(2).min(1.0))).collect();
        let m = step_metrics(
            &t,
            &y,
            &StepSegment { axis: "z", t0_s: 0.0, t1_s: 20.0, start: 3.0, target: 2.0, wrap: false },
        );
        let lowest = y.iter().copied().fold(f64::INFINITY, f64::min);
        assert!((m.overshoot_pct - 100.0 * (2.0 - lowest)).abs() < 1e-9);
        assert!(m.overshoot_pct > 1.0);
    }

    #[test]
    fn given_a_response_that_never_settles_then_settling_is_none() {
        let t = times(1001, 1e-3);
        let y = vec![0.5; 1001];
        let m = step_metrics(
            &t,
            &y,
            &StepSegment { axis: "x", t0_s: 0.0, t1_s: 1.0, start: 0.0, target: 1.0, wrap: false },
        );
        assert_eq!(m.settling_s, None);
        assert!((m.rms - 0.5).abs() < 1e-12);
    }

    #[test]
    fn given_yaw_across_pi_then_errors_wrap() {
        let t = times(3, 1.0);
        let y = [3.1, -3.1, std::f64::consts::PI];
        let m = step_metrics(
            &t,
            &y,
            &StepSegment { axis: "yaw", t0_s: 0.0, t1_s: 3.0, start: 2.9, target: std::f64::consts::PI, wrap: true },
        );
        assert!(m.rms < 0.05, "{}", m.rms);
        assert!(m.overshoot_pct > 0.0);
    }

    #[test]
    fn given_a_gust_excursion_then_recovery_counts_from_onset_and_release() {
        let t = times(3001, 0.01);
        let err: Vec<f64> =
            t.iter().map(|&x| if (5.0..7.5).contains(&x) || (17.0..19.0).contains(&x) { 0.2 } else { 0.01 }).collect();
        let z = vec![0.0; t.len()];
        let g = gust_metrics(&t, &err, &z, 5.0, 17.0);
        assert!((g.recovery_onset_s.unwrap() - 2.5).abs() < 1e-9);
        assert!((g.recovery_release_s.unwrap() - 2.0).abs() < 1e-9);
        assert_eq!(g.peak_m, 0.2);
        assert!((g.steady_err_m - 0.01).abs() < 1e-12);
    }

    #[test]
    fn given_metric_windows_then_peak_rms_steady_and_sse_are_taken_over_them() {
        let t = times(3001, 0.01);
        // A start-up transient of 0.5 m over the first second, the gust's 0.2 m from 5 s to 7.5 s, and a
        // last second before release at 0.05 m.
        let err: Vec<f64> = t
            .iter()
            .map(|&x| match x {
                x if x < 1.0 => 0.5,
                x if (5.0..7.5).contains(&x) => 0.2,
                x if (16.0..17.0).contains(&x) => 0.05,
                _ => 0.01,
            })
            .collect();
        let z = vec![0.0; t.len()];
        let whole = gust_metrics(&t, &err, &z, 5.0, 17.0);
        assert_eq!(whole.peak_m, 0.5, "the default window is the whole run, transient included");
        let windows = MetricWindows {
            gust_peak_s: Some([5.0, 30.0]),
            gust_rms_s: Some([5.0, 7.5]),
            gust_steady_s: 1.0,
            ..MetricWindows::default()
        };
        let g = gust_metrics_in(&t, &err, &z, 5.0, 17.0, &windows);
        assert_eq!(g.peak_m, 0.2);
        assert!((g.rms_xy_m - 0.2).abs() < 1e-3, "{}", g.rms_xy_m);
        assert!((g.steady_err_m - 0.05).abs() < 1e-3, "{}", g.steady_err_m);
        assert!((whole.steady_err_m - (0.05 + 2.0 * 0.01) / 3.0).abs() < 1e-3, "{}", whole.steady_err_m);
        // The defaults are the module's constants: the same numbers as the plain functions.
        assert_eq!(gust_metrics_in(&t, &err, &z, 5.0, 17.0, &MetricWindows::default()), whole);

        // The sse of a step that is still 0.1 off at 9 s and on target from 9.3 s.
        let y: Vec<f64> = t.iter().map(|&x| if x < 9.3 { 0.9 } else { 1.0 }).collect();
        let seg = StepSegment { axis: "x", t0_s: 0.0, t1_s: 10.0, start: 0.0, target: 1.0, wrap: false };
        assert!(step_metrics(&t, &y, &seg).sse < 1e-12);
        assert!((step_metrics_in(&t, &y, &seg, 1.0).sse - 0.1).abs() < 1e-9);
    }

    #[test]
    fn given_bad_metric_windows_then_validate_names_the_key() {
        let bad = MetricWindows { step_sse_s: 0.0, ..MetricWindows::default() };
        assert!(bad.validate().unwrap_err().contains("metric_windows.step_sse_s"));
        let bad = MetricWindows { gust_peak_s: Some([5.0, 5.0]), ..MetricWindows::default() };
        assert!(bad.validate().unwrap_err().contains("metric_windows.gust_peak_s"));
        let bad = MetricWindows { gust_rms_s: Some([f64::NAN, 5.0]), ..MetricWindows::default() };
        assert!(bad.validate().unwrap_err().contains("metric_windows.gust_rms_s"));
        let bad = MetricWindows { gust_steady_s: f64::INFINITY, ..MetricWindows::default() };
        assert!(bad.validate().unwrap_err().contains("metric_windows.gust_steady_s"));
        assert!(MetricWindows::default().validate().is_ok());
    }

    #[test]
    fn given_a_constant_error_then_iae_is_error_times_duration_and_itae_half_that_times_duration() {
        let t = times(1001, 1e-3);
        let e = vec![0.2; t.len()];
        let (iae, itae) = iae_itae(&t, &e, 0.0);
        // 1001 samples of 1 ms each: 1.001 s of 0.2.
        assert!((iae - 0.2 * 1.001).abs() < 1e-12, "{iae}");
        assert!((itae - 0.2 * (0..1001).map(|k| k as f64 * 1e-3 * 1e-3).sum::<f64>()).abs() < 1e-12, "{itae}");
        assert!((itae - 0.2 * 0.5).abs() < 2e-3, "{itae}");
    }

    #[test]
    fn given_an_error_that_grazes_the_recovery_band_then_recovery_jumps_and_iae_does_not() {
        // Two gust responses peaking just under and just over 0.10 m: the banded recovery jumps from 0 s
        // to the time spent above the band, the IAE and the peak move by about 2 %.
        let t = times(2001, 0.01);
        let bump =
            |peak: f64| -> Vec<f64> {
                t.iter()
                    .map(|&x| {
                        if (5.0..7.0).contains(&x) {
                            peak * (std::f64::consts::PI * (x - 5.0) / 2.0).sin()
                        } else {
                            0.0
                        }
                    })
                    .collect()
            };
        let z = vec![0.0; t.len()];
        let (under, over) =
            (gust_metrics(&t, &bump(0.099), &z, 5.0, 15.0), gust_metrics(&t, &bump(0.101), &z, 5.0, 15.0));
        assert_eq!(under.recovery_onset_s, Some(0.0));
        assert!(over.recovery_onset_s.unwrap() > 1.0, "{over:?}");
        assert!((over.iae_onset_m_s / under.iae_onset_m_s - 0.101 / 0.099).abs() < 1e-9);
        assert!((over.iae_onset_m_s - 0.101 * 4.0 / std::f64::consts::PI).abs() < 1e-3, "{}", over.iae_onset_m_s);
        assert_eq!(under.iae_release_m_s, 0.0);
        // Within the bands from the onset (5 s) to the end (20 s): 15.01 s of samples in all.
        assert!((under.within_20cm_s - 15.01).abs() < 1e-9, "{}", under.within_20cm_s);
        assert!(under.within_5cm_s < under.within_10cm_s && under.within_10cm_s == under.within_20cm_s);
    }

    #[test]
    fn given_pwm_at_hover_then_no_effort_and_a_saturated_swing_counts_deviation_rate_and_time() {
        let mut quiet = EffortAccumulator::new(1500.0, [1000.0, 2000.0]);
        for _ in 0..100 {
            quiet.add(&[1500.0; 4], 0.002);
        }
        assert_eq!(
            quiet.metrics(),
            EffortMetrics { pwm_dev_sq_us2_s: 0.0, pwm_rate_mean_us_per_s: 0.0, saturation_s: 0.0 }
        );
        let mut busy = EffortAccumulator::new(1500.0, [1000.0, 2000.0]);
        for k in 0..100 {
            let p = if k % 2 == 0 { 2000.0 } else { 1400.0 };
            busy.add(&[p, 1500.0, 1500.0, 1500.0], 0.002);
        }
        let m = busy.metrics();
        // Half the ticks 500 us off on one rotor of four, half 100 us off: mean (500² + 100²)/2/4 over 0.2 s.
        assert!((m.pwm_dev_sq_us2_s - (500.0_f64.powi(2) + 100.0_f64.powi(2)) / 2.0 / 4.0 * 0.2).abs() < 1e-6, "{m:?}");
        // Every change is 600 us on one rotor in 2 ms: 75,000 us/s averaged over four rotors.
        assert!((m.pwm_rate_mean_us_per_s - 600.0 / 4.0 / 0.002).abs() < 1e-6, "{m:?}");
        assert!((m.saturation_s - 50.0 * 0.002).abs() < 1e-12, "{m:?}");
    }

    /// The physics of the nominal airframe, for fault metrics that do not depend on it.
    fn nominal_physics(feasibility: Feasibility) -> FaultPhysics {
        let a = crate::plant::Airframe::nominal();
        FaultPhysics {
            envelope: crate::plant::envelope::hover_envelope(&a),
            max_payload_within_limiter_kg: crate::plant::envelope::max_payload_within_limiter_kg(&a),
            feasibility,
        }
    }

    #[test]
    fn given_a_synthetic_fault_trace_then_every_fault_metric_is_the_hand_computed_one() {
        // 100 Hz for 10 s, hover reference (0, 0, -1.5) heading 0. Fault at 4 s. Before it the vehicle sits
        // 0.5 m off (must not count). From 4 s: it sinks 0.2 m and drifts 0.1 m east (error sqrt(0.05) =
        // 0.2236 m) until 6 s, then 0.05 m below until the end; tilt 0.1 rad roll, 0.2 rad pitch at 5 s only;
        // yaw 3.0 rad at 5.5 s against a reference of -3.0 (wrapped error 0.2832 rad).
        let t = times(1000, 0.01);
        let n = t.len();
        let mut pos: [Vec<f64>; 3] = [vec![0.0; n], vec![0.0; n], vec![-1.5; n]];
        let refs: [Vec<f64>; 3] = [vec![0.0; n], vec![0.0; n], vec![-1.5; n]];
        let mut euler: [Vec<f64>; 3] = [vec![0.0; n], vec![0.0; n], vec![-3.0; n]];
        let ref_euler: [Vec<f64>; 3] = [vec![0.0; n], vec![0.0; n], vec![-3.0; n]];
        for k in 0..n {
            if t[k] < 4.0 - 1e-9 {
                pos[0][k] = 0.5;
            } else if t[k] < 6.0 - 1e-9 {
                pos[1][k] = 0.1;
                pos[2][k] = -1.3;
            } else {
                pos[2][k] = -1.45;
            }
        }
        let k5 = 500;
        (euler[0][k5], euler[1][k5]) = (0.1, 0.2);
        euler[2][550] = 3.0;
        let m = fault_metrics(&t, &pos, &refs, &euler, &ref_euler, 4.0, nominal_physics(Feasibility::Full));
        let e1 = 0.05_f64.sqrt();
        assert_eq!(m.onset_s, 4.0);
        assert!((m.peak_position_error_m - e1).abs() < 1e-12, "{m:?}");
        assert!((m.peak_tilt_rad - (0.1_f64.cos() * 0.2_f64.cos()).acos()).abs() < 1e-12, "{m:?}");
        assert!((m.peak_yaw_error_rad - (2.0 * std::f64::consts::PI - 6.0)).abs() < 1e-12, "{m:?}");
        // IAE: 2 s at 0.2236 m, then 4 s at 0.05 m (left sums over 10 ms samples).
        assert!((m.iae_m_s - (2.0 * e1 + 4.0 * 0.05)).abs() < 1e-9, "{m:?}");
        assert!((m.altitude_drop_m - 0.2).abs() < 1e-12, "{m:?}");
        // Below 0.10 m from 6 s on: recovered 2 s after the onset.
        assert!((m.recovery_s.unwrap() - 2.0).abs() < 1e-9, "{m:?}");
        assert!(m.within_0_3_m && !m.lost_control, "{m:?}");
        assert!((m.final_error_m - 0.05).abs() < 1e-12, "{m:?}");
        assert_eq!(m.feasibility, Feasibility::Full);

        // 0.31 m off at one sample: no longer within 0.3 m; 1.2 m: control lost; never back: no recovery.
        pos[0][700] = 0.31;
        let off = fault_metrics(&t, &pos, &refs, &euler, &ref_euler, 4.0, nominal_physics(Feasibility::Full));
        assert!(!off.within_0_3_m && !off.lost_control && off.recovery_s.is_some(), "{off:?}");
        pos[0][n - 1] = 1.2;
        let lost = fault_metrics(&t, &pos, &refs, &euler, &ref_euler, 4.0, nominal_physics(Feasibility::Full));
        assert!(
            lost.lost_control && lost.recovery_s.is_none() && (lost.final_error_m - 1.2f64.hypot(0.05)).abs() < 1e-12
        );
        // Tilted past 60° with the position held: control lost too; a NaN sample: lost, never within.
        pos[0][n - 1] = 0.0;
        euler[0][800] = 1.1;
        assert!(
            fault_metrics(&t, &pos, &refs, &euler, &ref_euler, 4.0, nominal_physics(Feasibility::Full)).lost_control
        );
        euler[0][800] = 0.0;
        pos[2][900] = f64::NAN;
        let nan = fault_metrics(&t, &pos, &refs, &euler, &ref_euler, 4.0, nominal_physics(Feasibility::Full));
        assert!(nan.lost_control && !nan.within_0_3_m && nan.peak_position_error_m.is_nan(), "{nan:?}");
    }
}
