//! The health of the plant link (the ARM board's serial line, or UDP to the SITL plant) as the vehicle
//! sees it: which sensor samples went missing, which came late, the drop rate over the last second, and
//! the byte counts the shell measures on the link.
//!
//! In, once per vehicle step: the step's `now_us` (the `time_usec` of the plant's HIL_SENSOR) and,
//! from a shell that counts them, the link's [`PlantLinkCounters`] (totals since it opened: bytes read
//! and written, frames the decoder dropped). The plant sends one sample every period `P` = 1e6 /
//! `LOOP_INNER_HZ` µs, so:
//! - a gap `g` between consecutive sample times larger than 1.5 P means `round(g / P) - 1` samples
//!   missing (smaller ones are jitter, none missing);
//! - a sample whose time is not after the last one (a resend of the same sample, an out-of-order one)
//!   is late: counted, and nothing else (it is no new sample, so no slot of the window);
//! - the window is the last second of samples: the last `N` = round(1e6 / P) sample slots (each received
//!   or missing), which on the plant's regular clock is the last second of vehicle time. Its missing
//!   share is the drop rate, in MAVLink's centi-percent (0..=10000) for SYS_STATUS `drop_rate_comm`;
//! - the byte rates are the counters' growth over the last whole second of vehicle time.
//!
//! Out: a [`PlantLinkStatus`] (totals, the window, the byte counts and rates) and, from a step, at most
//! one [`PlantLinkEvent`] for the vehicle to say: [`PlantLinkEvent::Missing`] (WARNING, with the window's
//! counts) at a step that finds samples missing before it, at most once per [`WARNING_INTERVAL_US`] of
//! vehicle time (so while the loss lasts, one every 5 s, and none for a loss that has ended but still
//! fills the window); and [`PlantLinkEvent::Complete`] (INFO) once after a warning, when a full window
//! has passed without a missing sample. Like the estimator's source events, the texts announce changes; the repeat every 5 s
//! says how bad it still is.
//!
//! The monitor is the vehicle's: a vehicle rebuilt (a plant restart, a reboot) starts counting afresh.
//! Pure: no clock but `now_us`, no I/O.

use std::collections::VecDeque;

/// The window of the drop rate and the texts (µs of vehicle time): one second.
pub const WINDOW_US: u64 = 1_000_000;
/// Vehicle time between two WARNINGs while samples keep going missing (µs).
pub const WARNING_INTERVAL_US: u64 = 5_000_000;
/// Vehicle time the byte rates are measured over (µs).
pub const RATE_INTERVAL_US: u64 = 1_000_000;
/// MAVLink's full scale of `drop_rate_comm` (centi-percent): every sample missing.
pub const DROP_RATE_FULL_CPCT: u16 = 10_000;
/// Said (INFO) once a full second passes without a missing sample after a WARNING.
pub const COMPLETE_TEXT: &str = "Plant link: samples complete again";

/// What the shell counts on the plant link, totals since the link opened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PlantLinkCounters {
    /// Bytes read from the link (datagrams, or serial bytes).
    pub rx_bytes: u64,
    /// Bytes written to the link.
    pub tx_bytes: u64,
    /// Malformed frames the link's decoder dropped (a bad CRC, a truncated frame; garbage bytes are not
    /// frames).
    pub bad_frames: u64,
}

/// The plant link's health after the last step (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantLinkStatus {
    /// Samples that arrived in time (one vehicle step each).
    pub received_samples: u64,
    /// Samples inferred missing from gaps in the sample times.
    pub missing_samples: u64,
    /// Samples whose time was not after the last one.
    pub late_samples: u64,
    /// The window's sample slots so far (N once a second of samples has passed) and the missing among them.
    pub window_expected_samples: u32,
    pub window_missing_samples: u32,
    /// The shell's counts (zero from a host that does not count).
    pub counters: PlantLinkCounters,
    /// Bytes per second read and written over the last whole second of vehicle time.
    pub rx_bytes_per_s: f64,
    pub tx_bytes_per_s: f64,
}

impl PlantLinkStatus {
    /// The window's missing share in centi-percent (0..=10000, rounded; 0 before any sample).
    #[must_use]
    pub fn drop_rate_cpct(&self) -> u16 {
        let expected = u64::from(self.window_expected_samples);
        if expected == 0 {
            return 0;
        }
        let missing = u64::from(self.window_missing_samples).min(expected);
        let cpct = (missing * u64::from(DROP_RATE_FULL_CPCT) + expected / 2) / expected;
        u16::try_from(cpct).unwrap_or(DROP_RATE_FULL_CPCT)
    }

    /// The window's missing share in percent (0..=100).
    #[must_use]
    pub fn drop_rate_pct(&self) -> f64 {
        let expected = self.window_expected_samples;
        if expected == 0 { 0.0 } else { f64::from(self.window_missing_samples) * 100.0 / f64::from(expected) }
    }
}

/// What the vehicle says of the plant link (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlantLinkEvent {
    /// `missing` of the last second's `expected` samples are missing (WARNING).
    Missing { missing: u32, expected: u32 },
    /// A full second without a missing sample after a warning (INFO).
    Complete,
}

impl PlantLinkEvent {
    /// The announcement, at most 40 bytes (counts up to 2000, LOOP_INNER_HZ's maximum):
    /// "Plant link: 100 of 500 samples missing", [`COMPLETE_TEXT`].
    #[must_use]
    pub fn text(&self) -> String {
        match *self {
            PlantLinkEvent::Missing { missing, expected } => {
                format!("Plant link: {missing} of {expected} samples missing")
            }
            PlantLinkEvent::Complete => COMPLETE_TEXT.to_owned(),
        }
    }
}

/// Samples missing in a gap of `gap_us` between consecutive samples `period_us` apart: none up to 1.5
/// periods, else `round(gap / period) - 1` (halves up).
#[must_use]
pub fn missing_in_gap(gap_us: u64, period_us: u64) -> u64 {
    let (gap, period) = (u128::from(gap_us), u128::from(period_us.max(1)));
    if 2 * gap <= 3 * period {
        return 0;
    }
    u64::try_from((2 * gap + period) / (2 * period) - 1).unwrap_or(u64::MAX)
}

/// The plant link's monitor: see the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantHealth {
    period_us: u64,
    /// N: the sample slots of one window.
    window_slots: u64,
    /// The newest sample time seen.
    last_us: Option<u64>,
    /// Sample slots so far (received and missing), numbered from 1.
    slots: u64,
    /// The numbers of the missing slots among the last `window_slots`, oldest first.
    missing_slots: VecDeque<u64>,
    status: PlantLinkStatus,
    /// Where the current byte-rate interval began: its vehicle time and the counters then.
    rate_from: Option<(u64, PlantLinkCounters)>,
    /// A WARNING was said and its INFO not yet.
    warned: bool,
    last_warning_us: Option<u64>,
}

impl PlantHealth {
    /// A monitor of samples `period_us` apart (0 taken as 1).
    #[must_use]
    pub fn new(period_us: u64) -> Self {
        let period_us = period_us.max(1);
        let window_slots = ((WINDOW_US + period_us / 2) / period_us).max(1);
        Self {
            period_us,
            window_slots,
            last_us: None,
            slots: 0,
            missing_slots: VecDeque::new(),
            status: PlantLinkStatus::default(),
            rate_from: None,
            warned: false,
            last_warning_us: None,
        }
    }

    /// A monitor of a plant sampling at `rate_hz` (the vehicle's LOOP_INNER_HZ; 0 taken as 1).
    #[must_use]
    pub fn at_rate_hz(rate_hz: u32) -> Self {
        let hz = u64::from(rate_hz.max(1));
        Self::new((1_000_000 + hz / 2) / hz)
    }

    /// The sample period (µs).
    #[must_use]
    pub fn period_us(&self) -> u64 {
        self.period_us
    }

    /// The state after the last step.
    #[must_use]
    pub fn status(&self) -> PlantLinkStatus {
        self.status
    }

    /// One vehicle step at `now_us`, with the shell's counters when it has them (`None`: the last ones
    /// hold); the event to say, if any.
    pub fn step(&mut self, now_us: u64, counters: Option<PlantLinkCounters>) -> Option<PlantLinkEvent> {
        if let Some(counters) = counters {
            self.status.counters = counters;
        }
        self.measure_rates(now_us);
        let mut missing = 0;
        if let Some(last_us) = self.last_us {
            if now_us <= last_us {
                self.status.late_samples += 1;
                return None;
            }
            missing = missing_in_gap(now_us - last_us, self.period_us);
            self.record_missing(missing);
        }
        self.last_us = Some(now_us);
        self.slots += 1;
        self.status.received_samples += 1;
        let oldest = self.slots.saturating_sub(self.window_slots);
        while self.missing_slots.front().is_some_and(|&s| s <= oldest) {
            self.missing_slots.pop_front();
        }
        self.status.window_expected_samples = u32::try_from(self.slots.min(self.window_slots)).unwrap_or(u32::MAX);
        self.status.window_missing_samples = u32::try_from(self.missing_slots.len()).unwrap_or(u32::MAX);
        self.event(now_us, missing > 0)
    }

    /// `count` slots missing before the next sample; the window keeps at most its own length of them.
    fn record_missing(&mut self, count: u64) {
        if count == 0 {
            return;
        }
        self.status.missing_samples += count;
        let kept = count.min(self.window_slots);
        let first = self.slots + count - kept + 1;
        if kept == self.window_slots {
            self.missing_slots.clear();
        }
        self.missing_slots.extend(first..=self.slots + count);
        self.slots += count;
    }

    /// The byte rates over the last whole [`RATE_INTERVAL_US`] of vehicle time.
    fn measure_rates(&mut self, now_us: u64) {
        let counters = self.status.counters;
        match self.rate_from {
            Some((from_us, from)) if now_us >= from_us.saturating_add(RATE_INTERVAL_US) => {
                let span_s = (now_us - from_us) as f64 * 1e-6;
                self.status.rx_bytes_per_s = counters.rx_bytes.saturating_sub(from.rx_bytes) as f64 / span_s;
                self.status.tx_bytes_per_s = counters.tx_bytes.saturating_sub(from.tx_bytes) as f64 / span_s;
                self.rate_from = Some((now_us, counters));
            }
            Some(_) => {}
            None => self.rate_from = Some((now_us, counters)),
        }
    }

    /// The event of a step at `now_us` that found samples missing before it (`fresh`) or not.
    fn event(&mut self, now_us: u64, fresh: bool) -> Option<PlantLinkEvent> {
        let (missing, expected) = (self.status.window_missing_samples, self.status.window_expected_samples);
        if missing > 0 {
            // Only a fresh loss is warned of: the window still holds a loss for a second after it ended.
            let due = self.last_warning_us.is_none_or(|at| now_us.saturating_sub(at) >= WARNING_INTERVAL_US);
            if !fresh || !due {
                return None;
            }
            self.last_warning_us = Some(now_us);
            self.warned = true;
            return Some(PlantLinkEvent::Missing { missing, expected });
        }
        if self.warned {
            self.warned = false;
            return Some(PlantLinkEvent::Complete);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    const P: u64 = 2_000;

    /// Steps `h` at each of `times_us`; the events with their times.
    fn run(h: &mut PlantHealth, times_us: impl IntoIterator<Item = u64>) -> Vec<(u64, PlantLinkEvent)> {
        times_us.into_iter().filter_map(|t| h.step(t, None).map(|e| (t, e))).collect()
    }

    #[test]
    fn a_gap_over_one_and_a_half_periods_counts_its_rounded_periods_less_one_as_missing() {
        assert_eq!(missing_in_gap(P, P), 0);
        assert_eq!(missing_in_gap(3 * P / 2, P), 0, "1.5 periods is jitter");
        assert_eq!(missing_in_gap(3 * P / 2 + 1, P), 1);
        assert_eq!(missing_in_gap(2 * P, P), 1);
        assert_eq!(missing_in_gap(5 * P / 2, P), 2, "2.5 periods rounds up");
        assert_eq!(missing_in_gap(10 * P + 300, P), 9);
        assert_eq!(missing_in_gap(0, P), 0);
        assert_eq!(missing_in_gap(u64::MAX, 1), u64::MAX - 1);
        assert_eq!(PlantHealth::at_rate_hz(500).period_us(), 2_000);
        assert_eq!(PlantHealth::at_rate_hz(300).period_us(), 3_333);
    }

    #[test]
    fn a_regular_clock_has_nothing_missing_nothing_late_and_says_nothing() {
        let mut h = PlantHealth::at_rate_hz(500);
        // Jitter of up to a quarter period either way is no loss.
        let said = run(&mut h, (0..2_000_u64).map(|k| k * P + [0, 400, 0, 500][(k % 4) as usize]));
        assert!(said.is_empty(), "{said:?}");
        let s = h.status();
        assert_eq!((s.received_samples, s.missing_samples, s.late_samples), (2_000, 0, 0));
        assert_eq!((s.window_expected_samples, s.window_missing_samples, s.drop_rate_cpct()), (500, 0, 0));
    }

    #[test]
    fn the_window_fills_over_the_first_second_and_then_holds_the_last_second_of_slots() {
        let mut h = PlantHealth::at_rate_hz(500);
        run(&mut h, (0..100_u64).map(|k| k * P));
        assert_eq!(h.status().window_expected_samples, 100);
        // Every fifth sample lost for two seconds: 20 %.
        run(&mut h, (100..1_100_u64).filter(|k| k % 5 != 0).map(|k| k * P));
        let s = h.status();
        assert_eq!((s.window_expected_samples, s.window_missing_samples), (500, 100));
        assert_eq!(s.drop_rate_cpct(), 2_000);
        assert!((s.drop_rate_pct() - 20.0).abs() < 1e-9);
        assert_eq!(s.missing_samples, 200);
        // Half a second clean: the older half of the window still holds its losses.
        run(&mut h, (1_100..1_350_u64).map(|k| k * P));
        assert_eq!(h.status().window_missing_samples, 50);
        assert_eq!(h.status().drop_rate_cpct(), 1_000);
    }

    #[test]
    fn a_resent_or_out_of_order_sample_is_late_and_changes_nothing_else() {
        let mut h = PlantHealth::at_rate_hz(500);
        run(&mut h, [0, P, 2 * P, 2 * P, P, 3 * P]);
        let s = h.status();
        assert_eq!((s.received_samples, s.missing_samples, s.late_samples), (4, 0, 2));
        assert_eq!((s.window_expected_samples, s.window_missing_samples), (4, 0));
    }

    #[test]
    fn a_gap_longer_than_the_window_fills_it_with_missing_slots_and_counts_every_one() {
        let mut h = PlantHealth::at_rate_hz(500);
        run(&mut h, (0..600_u64).map(|k| k * P));
        // Three seconds of silence (a board that stopped sending), then one sample.
        let said = run(&mut h, [3_000_000 + 599 * P]);
        let s = h.status();
        assert_eq!(s.missing_samples, 1_499);
        assert_eq!((s.window_expected_samples, s.window_missing_samples), (500, 499));
        assert_eq!(s.drop_rate_cpct(), 9_980);
        assert_eq!(said, [(3_000_000 + 599 * P, PlantLinkEvent::Missing { missing: 499, expected: 500 })]);
    }

    #[test]
    fn samples_going_missing_are_warned_at_once_and_every_5_s_while_it_lasts_and_the_end_once_after_a_clean_second() {
        let mut h = PlantHealth::at_rate_hz(500);
        run(&mut h, (0..1_000_u64).map(|k| k * P));
        // From 2 s: every tenth sample lost, for 12 s.
        let lossy = (1_000..7_000_u64).filter(|k| k % 10 != 5).map(|k| k * P);
        let said = run(&mut h, lossy);
        let first = 1_006 * P;
        assert_eq!(said[0], (first, PlantLinkEvent::Missing { missing: 1, expected: 500 }));
        let times: Vec<u64> = said.iter().map(|(t, _)| *t).collect();
        assert_eq!(times, [first, first + 5_000_000, first + 10_000_000], "one per 5 s");
        // The repeats count the settled loss: 50 of the last second's 500.
        assert!(said[1..].iter().all(|(_, e)| *e == PlantLinkEvent::Missing { missing: 50, expected: 500 }));
        // Clean again: the INFO once the last loss (sample 6995, at 13.99 s) has left the window.
        let said = run(&mut h, (7_000..9_000_u64).map(|k| k * P));
        assert_eq!(said, [((6_995 + 500) * P, PlantLinkEvent::Complete)]);
        let texts: Vec<String> =
            [PlantLinkEvent::Missing { missing: 2_000, expected: 2_000 }, PlantLinkEvent::Complete]
                .iter()
                .map(PlantLinkEvent::text)
                .collect();
        assert_eq!(texts, ["Plant link: 2000 of 2000 samples missing", "Plant link: samples complete again"]);
        assert!(texts.iter().all(|t| t.len() <= 50));
    }

    #[test]
    fn a_loss_that_ended_is_not_warned_again_though_the_window_still_holds_it() {
        let mut h = PlantHealth::at_rate_hz(500);
        run(&mut h, (0..500_u64).map(|k| k * P));
        // Sample 500 (1.0 s) lost: warned at 1.002 s, complete at 2.0 s. Sample 2995 (5.99 s) lost: found
        // at 5.992 s, within 5 s of the warning (not said); at 6.002 s the 5 s have passed and the window
        // still holds it, but it has ended: nothing is said, and no INFO follows what was not warned.
        let said = run(&mut h, (501..4_000_u64).filter(|&k| k != 2_995).map(|k| k * P));
        assert_eq!(
            said,
            [(501 * P, PlantLinkEvent::Missing { missing: 1, expected: 500 }), (1_000 * P, PlantLinkEvent::Complete)]
        );
        assert_eq!(h.status().missing_samples, 2);
    }

    #[test]
    fn a_new_loss_within_5_s_of_the_last_warning_waits_for_its_interval() {
        let mut h = PlantHealth::at_rate_hz(500);
        run(&mut h, (0..500_u64).map(|k| k * P));
        // One sample lost at 1.0 s: warned; clean for 1.5 s: complete; lost again at 3.0 s and on.
        let said = run(&mut h, (501..1_500_u64).map(|k| k * P));
        assert_eq!(said.len(), 2, "{said:?}");
        let said = run(&mut h, (1_500..4_000_u64).filter(|k| k % 4 != 0).map(|k| k * P));
        let at: Vec<u64> = said.iter().map(|(t, _)| *t).collect();
        assert_eq!(at, [501 * P + 5_000_000], "not before 5 s after the first warning");
    }

    #[test]
    fn the_byte_rates_are_the_counters_growth_over_each_whole_second_of_vehicle_time() {
        let mut h = PlantHealth::at_rate_hz(500);
        for k in 0..=1_000_u64 {
            let c = PlantLinkCounters { rx_bytes: 150 * k, tx_bytes: 40 * k, bad_frames: k / 100 };
            h.step(k * P, Some(c));
        }
        let s = h.status();
        assert_eq!(s.counters, PlantLinkCounters { rx_bytes: 150_000, tx_bytes: 40_000, bad_frames: 10 });
        assert!((s.rx_bytes_per_s - 75_000.0).abs() < 1e-6 && (s.tx_bytes_per_s - 20_000.0).abs() < 1e-6, "{s:?}");
        // Without counters (an in-process host) the last ones hold.
        h.step(1_001 * P, None);
        assert_eq!(h.status().counters.rx_bytes, 150_000);
    }

    /// Strictly increasing sample times on the grid of `P` (gaps of 1 to 40 periods, a few long ones),
    /// each followed by 0 to 2 late copies (a resend, or an older time).
    fn sequence() -> impl Strategy<Value = (u64, Vec<(u64, Vec<u64>)>)> {
        let gap = prop_oneof![8 => Just(1_u64), 3 => 2_u64..6, 1 => 6_u64..800];
        (0_u64..1_000, prop::collection::vec((gap, prop::collection::vec(0_u64..3, 0..3)), 1..400))
    }

    proptest! {
        #[test]
        fn over_any_sequence_missing_and_received_make_the_regular_count_and_the_window_is_the_last_n_slots(
            (start, steps) in sequence(),
            jitter in prop::collection::vec(0_u64..P / 4, 400),
        ) {
            let mut h = PlantHealth::at_rate_hz(500);
            let n = 500_usize;
            let mut k = start;
            let mut slots: Vec<bool> = Vec::new(); // true: missing
            let mut late = 0_u64;
            let mut first = None;
            for (i, (gap, lates)) in steps.iter().enumerate() {
                if first.is_some() {
                    k += gap;
                    slots.extend(std::iter::repeat_n(true, usize::try_from(gap - 1).unwrap_or(0)));
                }
                let t = k * P + jitter[i];
                first.get_or_insert(k);
                slots.push(false);
                h.step(t, None);
                for back in lates {
                    h.step(t.saturating_sub(back * P), None);
                    late += 1;
                }
                let s = h.status();
                // Missing and received: the samples a regular sequence had over the span, never more.
                prop_assert_eq!(s.missing_samples + s.received_samples, k - first.unwrap_or(k) + 1);
                prop_assert_eq!(s.late_samples, late);
                let window = &slots[slots.len().saturating_sub(n)..];
                prop_assert_eq!(s.window_expected_samples as usize, window.len());
                prop_assert_eq!(s.window_missing_samples as usize, window.iter().filter(|m| **m).count());
                prop_assert!(s.window_missing_samples < s.window_expected_samples, "the sample itself arrived");
                prop_assert!(s.drop_rate_cpct() <= DROP_RATE_FULL_CPCT);
                prop_assert!((0.0..=100.0).contains(&s.drop_rate_pct()));
            }
        }
    }
}
