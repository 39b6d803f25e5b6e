//! Per-source health of the fused estimator's inputs (GPS, barometer, magnetometer, IMU), judged from the
//! data only: lost (no sample for the source's timeout), stuck (bit-identical samples for a time while an
//! independent sensor showed motion), rejected (the innovation gate or the sanitiser refusing it
//! persistently); where the height comes from; and the events that announce a change. The policy (what is
//! fused while a source is faulted) is `fusion`'s; this module holds the types and the stuck detector.

use serde::{Deserialize, Serialize};

/// A stuck GPS, barometer or magnetometer repeats its sample at least this many times (and for
/// `stuck_time_s`).
pub const STUCK_MIN_REPEATS: u32 = 4;
/// A stuck IMU repeats its sample at least this many times (and for `imu_stuck_time_s`).
pub const IMU_STUCK_MIN_REPEATS: u32 = 50;
/// Motion of the IMU that a GPS, barometer or magnetometer must see: a change of a specific-force axis
/// (m/s², FRD) or a rate axis (rad/s, FRD) since a run of identical samples began. Twice the modest SITL
/// noise's sigma (0.05 m/s², 0.005 rad/s), so a noisy IMU moves them within a few samples, and far
/// above what a noise-free vehicle holding still jitters.
pub const IMU_MOTION: [f64; 6] = [0.1, 0.1, 0.1, 0.01, 0.01, 0.01];
/// Motion the IMU must show for the magnetometer: a rotation only (rad/s, FRD). The field in the body frame
/// changes only when the body turns; a specific force that changes (a spool-up, a touchdown, a climb) with
/// the attitude held is no witness, and a noise-free hover at rest reads the same field bit for bit.
pub const IMU_ROTATION: [f64; 6] = [f64::INFINITY, f64::INFINITY, f64::INFINITY, 0.01, 0.01, 0.01];
/// Motion the IMU must see, from the magnetometer (gauss per axis: 0.005 G is 0.6 deg of the 0.48 G
/// field): a rotation, which turns both the rates and gravity in the body frame. The barometer (the last
/// value) is no witness: a noise-free vertical climb changes the height while the gyro reads 0 bit for bit.
pub const AIDING_MOTION: [f64; 4] = [0.005, 0.005, 0.005, f64::INFINITY];
/// The IMU is rejected when more than this share of its recent samples (an average over about
/// [`IMU_REFUSED_WINDOW`] samples) was refused by the sanitiser (garbage: values beyond 16 g or 35 rad/s,
/// non-finite, or time not increasing), and healthy again below [`IMU_REFUSED_CLEAR`].
pub const IMU_REFUSED_FLAG: f64 = 0.5;
pub const IMU_REFUSED_CLEAR: f64 = 0.1;
pub const IMU_REFUSED_WINDOW: f64 = 50.0;
/// Events kept until drained (the oldest dropped beyond).
pub const MAX_PENDING_EVENTS: usize = 32;

/// Why a source is not fused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceFault {
    /// No usable sample for the source's timeout.
    Lost,
    /// Bit-identical samples for `stuck_time_s` while an independent sensor showed motion.
    Stuck,
    /// Samples arrive but are refused (innovation gate, or the sanitiser for the IMU) for `reject_time_s`.
    Rejected,
}

impl std::fmt::Display for SourceFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SourceFault::Lost => "lost",
            SourceFault::Stuck => "stuck",
            SourceFault::Rejected => "rejected",
        })
    }
}

/// The fault of each source; `None` is healthy (or not yet heard from: a source is only judged after its
/// first sample).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash, Serialize, Deserialize)]
pub struct SourceHealth {
    pub gps: Option<SourceFault>,
    pub baro: Option<SourceFault>,
    pub mag: Option<SourceFault>,
    pub imu: Option<SourceFault>,
}

impl SourceHealth {
    /// The fault of `source`.
    #[must_use]
    pub fn of(&self, source: Source) -> Option<SourceFault> {
        match source {
            Source::Gps => self.gps,
            Source::Baro => self.baro,
            Source::Mag => self.mag,
            Source::Imu => self.imu,
        }
    }

    /// No source faulted.
    #[must_use]
    pub fn all_healthy(&self) -> bool {
        *self == Self::default()
    }
}

/// What the height is aided by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeightSource {
    /// The barometer (with its offset calibrated by GPS height, which is fused too).
    Baro,
    /// GPS altitude alone: the barometer is faulted.
    Gps,
    /// Nothing: the height dead-reckons on the IMU (or the filter is not running).
    #[default]
    None,
}

impl std::fmt::Display for HeightSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            HeightSource::Baro => "baro",
            HeightSource::Gps => "gps",
            HeightSource::None => "none",
        })
    }
}

/// One of the estimator's sources.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    Gps,
    Baro,
    Mag,
    Imu,
}

impl Source {
    /// Every source, in the order events are raised.
    pub const ALL: [Source; 4] = [Source::Imu, Source::Gps, Source::Baro, Source::Mag];
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Source::Gps => "GPS",
            Source::Baro => "Baro",
            Source::Mag => "Mag",
            Source::Imu => "IMU",
        })
    }
}

/// How loud an event is (the vehicle maps it onto STATUSTEXT severities).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum EventSeverity {
    /// A source is back.
    Info,
    /// A source is lost; the estimate falls back.
    Warning,
    /// The IMU is faulted: nothing to fall back to.
    Critical,
}

/// A change in a source's health, drained with [`super::Estimator::take_events`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EstimatorEvent {
    /// `source` is no longer fused because of `fault` (or its fault changed); `height_source` is where the
    /// height comes from afterwards.
    Fault { source: Source, fault: SourceFault, height_source: HeightSource },
    /// `source` is fused again.
    Regained { source: Source },
}

impl EstimatorEvent {
    /// The announcement: "GPS lost: dead reckoning", "Baro stuck: height from GPS", "GPS regained".
    #[must_use]
    pub fn text(&self) -> String {
        match *self {
            EstimatorEvent::Fault { source: Source::Gps, fault: SourceFault::Rejected, .. } => {
                "GPS rejected: position jump".to_owned()
            }
            EstimatorEvent::Fault { source: Source::Gps, fault, .. } => format!("GPS {fault}: dead reckoning"),
            EstimatorEvent::Fault { source: Source::Baro, fault, height_source: HeightSource::Gps } => {
                format!("Baro {fault}: height from GPS")
            }
            EstimatorEvent::Fault { source: Source::Baro, fault, .. } => format!("Baro {fault}: no height aiding"),
            EstimatorEvent::Fault { source: Source::Mag, fault, .. } => format!("Mag {fault}: heading on gyro"),
            EstimatorEvent::Fault { source: Source::Imu, fault: SourceFault::Lost, .. } => {
                "IMU lost: coasting".to_owned()
            }
            EstimatorEvent::Fault { source: Source::Imu, fault, .. } => format!("IMU {fault}: attitude unreliable"),
            EstimatorEvent::Regained { source } => format!("{source} regained"),
        }
    }

    /// Warning for a lost aiding source, critical for the IMU, info when regained.
    #[must_use]
    pub fn severity(&self) -> EventSeverity {
        match self {
            EstimatorEvent::Fault { source: Source::Imu, .. } => EventSeverity::Critical,
            EstimatorEvent::Fault { .. } => EventSeverity::Warning,
            EstimatorEvent::Regained { .. } => EventSeverity::Info,
        }
    }
}

/// Bit-identical sample detection, as PX4's sensor `DataValidator` stale check, made safe for noise-free
/// simulation: a run of samples whose `N` values are bit-identical counts as stuck only once it has lasted
/// `min_repeats` repeats and a time, AND an independent witness (`W` values, e.g. the IMU's readings for
/// the GPS) moved by more than its per-value threshold since the run began. A still vehicle with
/// noise-free sensors reads identical values everywhere (the witness too) and is never flagged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StuckDetector<const N: usize, const W: usize> {
    last: Option<[u64; N]>,
    run_start_us: u64,
    repeats: u32,
    /// The witness's values when the run began (None: unknown then).
    witness_ref: Option<[f64; W]>,
    witness_moved: bool,
    stuck: bool,
}

impl<const N: usize, const W: usize> Default for StuckDetector<N, W> {
    fn default() -> Self {
        Self { last: None, run_start_us: 0, repeats: 0, witness_ref: None, witness_moved: false, stuck: false }
    }
}

impl<const N: usize, const W: usize> StuckDetector<N, W> {
    /// A sample at `now_us` with the witness's latest values (NaN: unknown); whether the source is stuck
    /// after it.
    pub fn observe(
        &mut self,
        values: [f64; N],
        now_us: u64,
        witness: [f64; W],
        min_repeats: u32,
        min_time_us: u64,
    ) -> bool {
        let bits = values.map(f64::to_bits);
        if self.last == Some(bits) {
            self.repeats = self.repeats.saturating_add(1);
        } else {
            *self = Self {
                last: Some(bits),
                run_start_us: now_us,
                repeats: 0,
                witness_ref: witness.iter().all(|w| w.is_finite()).then_some(witness),
                witness_moved: false,
                stuck: false,
            };
        }
        if self.repeats >= min_repeats && now_us.saturating_sub(self.run_start_us) >= min_time_us && self.witness_moved
        {
            self.stuck = true;
        }
        self.stuck
    }

    /// The witness's latest values: notes whether any moved beyond its threshold since the run began
    /// (NaN, unknown, never counts as motion).
    pub fn witness(&mut self, witness: [f64; W], thresholds: &[f64; W]) {
        if self.last.is_none() || self.witness_moved {
            return;
        }
        let Some(reference) = self.witness_ref else {
            // The witness was unknown when the run began: its first complete values are the reference.
            self.witness_ref = witness.iter().all(|w| w.is_finite()).then_some(witness);
            return;
        };
        self.witness_moved = witness.iter().zip(&reference).zip(thresholds).any(|((w, r), t)| (w - r).abs() > *t);
    }

    /// Whether the last run was judged stuck (until a different sample arrives).
    #[must_use]
    pub fn stuck(&self) -> bool {
        self.stuck
    }

    /// Forgets the run (the source was lost: its next sample starts afresh).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: [f64; 1] = [0.1];

    #[test]
    fn given_identical_samples_when_the_witness_is_still_then_never_stuck_and_when_it_moves_then_stuck() {
        let mut d = StuckDetector::<2, 1>::default();
        for k in 0..1000_u64 {
            assert!(!d.observe([1.0, 2.0], k * 10_000, [5.0], 4, 1_000_000));
            d.witness([5.0 + 0.099 * (k % 2) as f64], &T);
        }
        d.witness([5.2], &T);
        assert!(d.observe([1.0, 2.0], 10_010_000, [5.2], 4, 1_000_000));
        // A different sample ends the run at once.
        assert!(!d.observe([1.0, 2.000_000_1], 10_020_000, [5.2], 4, 1_000_000));
    }

    #[test]
    fn given_a_moving_witness_when_the_run_is_short_in_time_or_count_then_not_stuck() {
        let mut d = StuckDetector::<1, 1>::default();
        d.observe([3.0], 0, [0.0], 4, 1_000_000);
        d.witness([1.0], &T);
        // Four repeats but only 0.9 s.
        for k in 1..=4 {
            assert!(!d.observe([3.0], k * 225_000, [1.0], 4, 1_000_000));
        }
        // 1 s but the fifth sample only now: stuck.
        assert!(d.observe([3.0], 1_000_000, [1.0], 4, 1_000_000));
        let mut d = StuckDetector::<1, 1>::default();
        d.observe([3.0], 0, [0.0], 4, 1_000_000);
        d.witness([1.0], &T);
        // Long enough but only 3 repeats.
        for k in 1..=3 {
            assert!(!d.observe([3.0], k * 1_000_000, [1.0], 4, 1_000_000));
        }
    }

    #[test]
    fn given_each_event_when_announced_then_the_texts_and_severities_are_the_designs() {
        let fault = |source, fault, height_source| EstimatorEvent::Fault { source, fault, height_source };
        let cases = [
            (fault(Source::Gps, SourceFault::Lost, HeightSource::Baro), "GPS lost: dead reckoning"),
            (fault(Source::Gps, SourceFault::Rejected, HeightSource::Baro), "GPS rejected: position jump"),
            (fault(Source::Baro, SourceFault::Stuck, HeightSource::Gps), "Baro stuck: height from GPS"),
            (fault(Source::Baro, SourceFault::Lost, HeightSource::None), "Baro lost: no height aiding"),
            (fault(Source::Mag, SourceFault::Stuck, HeightSource::Baro), "Mag stuck: heading on gyro"),
            (fault(Source::Imu, SourceFault::Stuck, HeightSource::Baro), "IMU stuck: attitude unreliable"),
            (EstimatorEvent::Regained { source: Source::Gps }, "GPS regained"),
        ];
        for (event, text) in cases {
            assert_eq!(event.text(), text);
        }
        assert_eq!(cases[0].0.severity(), EventSeverity::Warning);
        assert_eq!(cases[5].0.severity(), EventSeverity::Critical);
        assert_eq!(cases[6].0.severity(), EventSeverity::Info);
        assert_eq!(SourceFault::Rejected.to_string(), "rejected");
    }
}
