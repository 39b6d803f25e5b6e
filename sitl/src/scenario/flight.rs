//! The metrics of the paper's real flights (its Section 6), on the plant's truth: the figure-8's turning
//! points (`corners`: the overshoot past each and the time back onto the "8") and a hover's recovery after
//! each crosswind pulse (`pulses`). Definitions (also in docs/scenarios.md):
//!
//! - A track's turning points are its waypoints after the first, every lap. The reference **reaches** one
//!   at the first sample whose prefiltered progress is within [`CORNER_REACHED_TOL_M`] of the point's arc
//!   length (the prefilter approaches the track's end only asymptotically).
//! - **overshoot** at a turning point c, with unit incoming direction u_in: over the samples from when the
//!   reference is halfway along the incoming segment until it reaches the next turning point (the run's
//!   end for the last), the largest distance from the vehicle to the outgoing line (through c along the
//!   next segment) while the vehicle is beyond c ((p - c)·u_in > 0); where the track ends at c, the
//!   distance beyond c along u_in. At a right-angle corner both are the distance travelled past c along the
//!   incoming direction. 0 if the vehicle never goes beyond c.
//! - **return** at a turning point: the time from when the reference reaches it until the cross-track
//!   error to the path is within [`CORNER_RETURN_BAND_M`] and stays there until the reference reaches the
//!   next turning point (the run's end for the last); 0 if it never leaves the band, `None` (never) if it
//!   is outside at the window's last sample.
//! - **pulse recovery**: from a pulse's end until the horizontal error stays below
//!   [`super::metrics::RECOVERY_BAND_M`] for the rest of the gap before the next pulse's start (the run's
//!   end after the last); 0 if it never leaves the band, `None` (never) if outside at the gap's last
//!   sample. Pulses that end after the run are not judged.

use nalgebra::Vector2;
use serde::Serialize;

use super::metrics::{RECOVERY_BAND_M, time_to_stay_within};
use crate::plant::Pulse;

/// The band on the cross-track error a vehicle returns to after a turning point (m).
pub const CORNER_RETURN_BAND_M: f64 = 0.05;
/// The reference reaches a turning point when its progress is within this of the point's arc length (m).
pub const CORNER_REACHED_TOL_M: f64 = 1e-3;

/// One turning point of a track.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Corner {
    /// The point (m, N and E).
    pub n_m: f64,
    pub e_m: f64,
    /// The turn between the incoming and the outgoing segment (degrees; 0 straight on); `None` where the
    /// track ends.
    pub turn_deg: Option<f64>,
    /// When the reference reached it (s; `None`: not within the run).
    pub reached_s: Option<f64>,
    /// How far beyond the point the vehicle went (m; see the module doc).
    pub overshoot_m: f64,
    /// The time back within [`CORNER_RETURN_BAND_M`] of the path (s; `None`: never).
    pub return_s: Option<f64>,
}

/// The `corners` metric: every turning point, and the largest and mean over them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CornerMetrics {
    pub corners: Vec<Corner>,
    pub max_overshoot_m: f64,
    pub mean_overshoot_m: f64,
    /// The longest return (s); `None` if any corner never returned.
    pub max_return_s: Option<f64>,
    /// The mean return over the corners that returned (s); `None` if none did.
    pub mean_return_s: Option<f64>,
    /// How many corners never returned.
    pub never: usize,
}

/// The first sample index whose progress reaches arc length `s_m` (within the tolerance); `len` if none.
fn reached(progress_m: &[f64], s_m: f64) -> usize {
    progress_m.iter().position(|&p| p >= s_m - CORNER_REACHED_TOL_M).unwrap_or(progress_m.len())
}

/// The corners of the track through `waypoints_ne_m` flown `laps` times (closed when the last of at least
/// four repeats the first), from the truth `pos_n_m`, `pos_e_m`, the reference's progress `progress_m` (m)
/// and the cross-track error `cross_m` (m, non-finite where not measured), all sampled at `t` (s).
#[must_use]
pub fn corner_metrics(
    t: &[f64],
    pos_n_m: &[f64],
    pos_e_m: &[f64],
    progress_m: &[f64],
    cross_m: &[f64],
    waypoints_ne_m: &[[f64; 2]],
    laps: u32,
) -> CornerMetrics {
    let points: Vec<Vector2<f64>> = waypoints_ne_m.iter().map(|w| Vector2::new(w[0], w[1])).collect();
    let lengths: Vec<f64> = points.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
    let dirs: Vec<Vector2<f64>> = points.windows(2).zip(&lengths).map(|(w, l)| (w[1] - w[0]) / *l).collect();
    let lap_m: f64 = lengths.iter().sum();
    let closed = points.len() >= 4 && points.first() == points.last();
    // (point, arc length, incoming direction, outgoing direction, incoming length) per turning point.
    let mut turns = Vec::new();
    for lap in 0..laps {
        let mut s = f64::from(lap) * lap_m;
        for j in 1..points.len() {
            s += lengths[j - 1];
            let out = if j < dirs.len() {
                Some(dirs[j])
            } else if closed && lap + 1 < laps {
                Some(dirs[0])
            } else {
                None
            };
            turns.push((points[j], s, dirs[j - 1], out, lengths[j - 1]));
        }
    }
    let n = t.len();
    let mut corners = Vec::with_capacity(turns.len());
    for (i, &(c, s_c, u_in, u_out, len_in)) in turns.iter().enumerate() {
        let k_mid = reached(progress_m, s_c - len_in / 2.0);
        let k_at = reached(progress_m, s_c);
        let k_next = turns.get(i + 1).map_or(n, |next| reached(progress_m, next.1));
        let mut overshoot_m: f64 = 0.0;
        for k in k_mid..k_next {
            let d = Vector2::new(pos_n_m[k], pos_e_m[k]) - c;
            let beyond = d.dot(&u_in);
            if beyond > 0.0 {
                let dist = u_out.map_or(beyond, |u| (d.x * u.y - d.y * u.x).abs());
                overshoot_m = overshoot_m.max(dist);
            }
        }
        let return_s = (k_at < k_next)
            .then(|| time_to_stay_within(&t[k_at..k_next], &cross_m[k_at..k_next], t[k_at], CORNER_RETURN_BAND_M))
            .flatten();
        corners.push(Corner {
            n_m: c.x,
            e_m: c.y,
            turn_deg: u_out.map(|u| u_in.dot(&u).clamp(-1.0, 1.0).acos().to_degrees()),
            reached_s: (k_at < n).then(|| t[k_at]),
            overshoot_m,
            return_s,
        });
    }
    let count = corners.len().max(1) as f64;
    let returns: Vec<f64> = corners.iter().filter_map(|c| c.return_s).collect();
    let never = corners.len() - returns.len();
    CornerMetrics {
        max_overshoot_m: corners.iter().map(|c| c.overshoot_m).fold(0.0, f64::max),
        mean_overshoot_m: corners.iter().map(|c| c.overshoot_m).sum::<f64>() / count,
        max_return_s: (never == 0).then(|| returns.iter().copied().fold(0.0, f64::max)),
        mean_return_s: (!returns.is_empty()).then(|| returns.iter().sum::<f64>() / returns.len() as f64),
        never,
        corners,
    }
}

/// One pulse and the recovery after it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PulseRecovery {
    pub start_s: f64,
    pub end_s: f64,
    pub amplitude_mps: f64,
    /// The largest horizontal error from the pulse's start to the next pulse's start (m).
    pub peak_m: f64,
    /// From the pulse's end until back to balance (s; `None`: never; see the module doc).
    pub recovery_s: Option<f64>,
}

/// The `pulses` metric: each pulse's recovery and their distribution.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PulseMetrics {
    pub pulses: Vec<PulseRecovery>,
    /// The median recovery, a never counting as longer than any time (s; `None` if half or more never).
    pub median_recovery_s: Option<f64>,
    /// The longest recovery (s; `None` if any never).
    pub max_recovery_s: Option<f64>,
    /// How many pulses the vehicle never recovered from.
    pub never: usize,
    /// The largest peak over the pulses (m).
    pub max_peak_m: f64,
}

/// The `pulses` metric of a hover: `err_xy_m` is the horizontal distance to the reference at `t` (s),
/// `pulses` the train's pulses in time order.
#[must_use]
pub fn pulse_metrics(t: &[f64], err_xy_m: &[f64], pulses: &[Pulse]) -> PulseMetrics {
    let last_s = t.last().copied().unwrap_or(0.0);
    let index = |time_s: f64| t.partition_point(|&x| x < time_s - 1e-9);
    let mut out = Vec::new();
    for (i, p) in pulses.iter().enumerate() {
        if p.end_s() > last_s {
            break;
        }
        let next = pulses.get(i + 1).map_or(t.len(), |q| index(q.start_s));
        let (from, at_end) = (index(p.start_s), index(p.end_s()));
        let recovery_s = (at_end < next)
            .then(|| time_to_stay_within(&t[at_end..next], &err_xy_m[at_end..next], p.end_s(), RECOVERY_BAND_M))
            .flatten();
        out.push(PulseRecovery {
            start_s: p.start_s,
            end_s: p.end_s(),
            amplitude_mps: p.amplitude_mps,
            peak_m: err_xy_m[from..next.max(from)].iter().copied().fold(0.0, f64::max),
            recovery_s,
        });
    }
    let mut sorted: Vec<f64> = out.iter().map(|p| p.recovery_s.unwrap_or(f64::INFINITY)).collect();
    sorted.sort_by(f64::total_cmp);
    let m = sorted.len();
    let median = match m {
        0 => f64::INFINITY,
        _ if m % 2 == 1 => sorted[m / 2],
        _ => 0.5 * (sorted[m / 2 - 1] + sorted[m / 2]),
    };
    let never = sorted.iter().filter(|x| x.is_infinite()).count();
    PulseMetrics {
        median_recovery_s: median.is_finite().then_some(median),
        max_recovery_s: (m > 0 && never == 0).then(|| sorted[m - 1]),
        never,
        max_peak_m: out.iter().map(|p| p.peak_m).fold(0.0, f64::max),
        pulses: out,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn times(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * dt).collect()
    }

    #[test]
    fn given_a_right_angle_corner_overshot_by_8_cm_then_overshoot_and_return_are_the_known_ones() {
        // An L: (0, 0) -> (1, 0) -> (1, 1), open. The reference moves at 0.5 m/s from t = 0 (progress = 0.5 t);
        // it reaches the corner at 2 s and the end at 4 s. The vehicle follows the reference exactly, but
        // from 2 s to 3 s it runs on along N to 1.08 m and back (a triangle, peak at 2.5 s), 0.08 m beyond
        // the corner and as far from the outgoing line N = 1; the cross-track error is its |N - 1| then,
        // 0 elsewhere. Back within 0.05 m when N - 1 < 0.05 again: at 2.5 + 0.5 * (0.03 / 0.08) = 2.6875 s.
        let t = times(601, 0.01);
        let progress: Vec<f64> = t.iter().map(|&x| (0.5 * x).min(2.0)).collect();
        let (mut n, mut e, mut cross) = (vec![0.0; t.len()], vec![0.0; t.len()], vec![0.0; t.len()]);
        for k in 0..t.len() {
            let s = progress[k];
            (n[k], e[k]) = if s < 1.0 { (s, 0.0) } else { (1.0, s - 1.0) };
            if (2.0..3.0).contains(&t[k]) {
                let past = 0.08 * (1.0 - (t[k] - 2.5).abs() / 0.5);
                n[k] = 1.0 + past;
                cross[k] = past;
            }
        }
        let m = corner_metrics(&t, &n, &e, &progress, &cross, &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], 1);
        assert_eq!(m.corners.len(), 2);
        let c = &m.corners[0];
        assert_eq!((c.n_m, c.e_m), (1.0, 0.0));
        assert!((c.turn_deg.unwrap() - 90.0).abs() < 1e-9, "{c:?}");
        assert!((c.reached_s.unwrap() - 2.0).abs() < 1e-9, "{c:?}");
        assert!((c.overshoot_m - 0.08).abs() < 1e-12, "{c:?}");
        // Sampled at 10 ms: the first sample back within 0.05 m is 2.69 s (2.68 s is 0.0512 m out).
        assert!((c.return_s.unwrap() - 0.69).abs() < 1e-9, "{c:?}");
        // The end: reached at 4 s, never beyond (the vehicle stops on it), never out of the band.
        let end = &m.corners[1];
        assert_eq!((end.turn_deg, end.overshoot_m, end.return_s), (None, 0.0, Some(0.0)));
        assert!((m.max_overshoot_m - 0.08).abs() < 1e-12 && (m.mean_overshoot_m - 0.04).abs() < 1e-12);
        assert_eq!((m.max_return_s, m.never), (Some(c.return_s.unwrap()), 0));

        // Still 0.06 m off the path at the run's end: the last corner never returns, and beyond the end by
        // 0.06 m along the incoming direction (E).
        let k_end = t.len() - 1;
        (e[k_end], cross[k_end]) = (1.06, 0.06);
        let m = corner_metrics(&t, &n, &e, &progress, &cross, &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], 1);
        assert_eq!((m.corners[1].return_s, m.never, m.max_return_s), (None, 1, None));
        assert!((m.corners[1].overshoot_m - 0.06).abs() < 1e-12);
        assert!((m.mean_return_s.unwrap() - 0.69).abs() < 1e-9);
    }

    #[test]
    fn given_pulses_then_recovery_is_counted_from_each_end_and_a_never_is_none() {
        // Pulses at 10-12 s and 30-32 s. After the first the error is 0.3 m until 15 s, then 0.02 m: back
        // in 3 s. After the second it is 0.15 m to the run's end (50 s): never.
        let t = times(5001, 0.01);
        let err: Vec<f64> = t
            .iter()
            .map(|&x| match x {
                x if (10.0..15.0).contains(&x) => 0.3,
                x if x >= 30.0 => 0.15,
                _ => 0.02,
            })
            .collect();
        let pulses = [
            Pulse { start_s: 10.0, width_s: 2.0, amplitude_mps: 6.0 },
            Pulse { start_s: 30.0, width_s: 2.0, amplitude_mps: 7.0 },
            Pulse { start_s: 49.5, width_s: 2.0, amplitude_mps: 7.0 },
        ];
        let m = pulse_metrics(&t, &err, &pulses);
        assert_eq!(m.pulses.len(), 2, "the pulse past the run's end is not judged");
        assert!((m.pulses[0].recovery_s.unwrap() - 3.0).abs() < 1e-9, "{m:?}");
        assert_eq!((m.pulses[0].peak_m, m.pulses[1].peak_m), (0.3, 0.15));
        assert_eq!((m.pulses[1].recovery_s, m.never, m.max_recovery_s, m.median_recovery_s), (None, 1, None, None));
        // Without the never: median and max are the one recovery.
        let m = pulse_metrics(&t[..2500], &err[..2500], &pulses);
        assert_eq!(m.pulses.len(), 1);
        assert!((m.median_recovery_s.unwrap() - 3.0).abs() < 1e-9 && m.max_recovery_s == m.median_recovery_s);
    }
}
