//! The airframe's radio receiver, as the ARM board reads it: what the pilot's radio says now (an
//! [`RcFrame`], or nothing when the receiver has no output), from a stick schedule on plant time
//! ([`RcSchedule`], a scenario's `[[rc]]`), from the last good frame of the plant's RC input port
//! (the plant link's, `link::rc`), and silenced while SIM_RC_FAIL = 1 (a SIM_ parameter). The plant link sends
//! what [`Radio::output`] gives as `RC_CHANNELS` at 50 Hz of plant time; it touches nothing the
//! physics or the sensors use, so a plant without a radio runs bit for bit as before.
//!
//! Precedence: the schedule wins from its first entry on (before it, the port's frame, if any).

use autopilot::core::manual::RcFrame;

/// Channels a schedule's frames carry (1..=16, as a 16-channel receiver).
pub const SCHEDULE_CHANNELS: usize = 16;
/// Lowest PWM (µs) a schedule or the RC input port accepts (wider than a radio's usual 1000..2000 end
/// points, so a trimmed or extended radio fits).
pub const RC_PWM_MIN_US: u16 = 800;
/// Highest PWM (µs) a schedule or the RC input port accepts.
pub const RC_PWM_MAX_US: u16 = 2200;
/// Every schedule channel's value before the first entry sets it (µs): centred, ...
pub const SCHEDULE_CENTRE_US: u16 = 1500;
/// ... except channel 3, the throttle (AETR), which starts low (µs).
pub const SCHEDULE_THROTTLE_START_US: u16 = 1000;

/// A stick schedule: from each time on (µs of plant time, in order) the receiver outputs the frame, or
/// nothing (`None`: the receiver lost the radio).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RcSchedule {
    entries: Vec<(u64, Option<RcFrame>)>,
}

impl RcSchedule {
    /// A schedule of `entries` (plant time µs, output from then on).
    ///
    /// # Errors
    /// A message naming the first entry whose time is earlier than the one before it.
    pub fn new(entries: Vec<(u64, Option<RcFrame>)>) -> Result<Self, String> {
        for (i, pair) in entries.windows(2).enumerate() {
            if pair[1].0 < pair[0].0 {
                return Err(format!(
                    "rc[{}] at {} us is earlier than rc[{i}] at {} us: entries must be in time order",
                    i + 1,
                    pair[1].0,
                    pair[0].0
                ));
            }
        }
        Ok(Self { entries })
    }

    /// The entries (plant time µs, output).
    #[must_use]
    pub fn entries(&self) -> &[(u64, Option<RcFrame>)] {
        &self.entries
    }

    /// What the schedule says at plant time `t_us`: `None` before its first entry, else the output of the
    /// last entry at or before `t_us`.
    #[must_use]
    pub fn at(&self, t_us: u64) -> Option<Option<RcFrame>> {
        let n = self.entries.partition_point(|(at, _)| *at <= t_us);
        n.checked_sub(1).map(|i| self.entries[i].1)
    }
}

/// The receiver: the schedule, the RC input port's last good frame, and the SIM_RC_FAIL switch.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Radio {
    schedule: RcSchedule,
    port_frame: Option<RcFrame>,
    failed: bool,
}

impl Radio {
    /// Fly `schedule` (replacing any earlier one).
    pub fn set_schedule(&mut self, schedule: RcSchedule) {
        self.schedule = schedule;
    }

    /// The RC input port's last good frame (held until the next).
    pub fn set_port_frame(&mut self, frame: RcFrame) {
        self.port_frame = Some(frame);
    }

    /// SIM_RC_FAIL: while `failed`, the receiver has no output.
    pub fn set_failed(&mut self, failed: bool) {
        self.failed = failed;
    }

    /// Whether SIM_RC_FAIL silences the receiver.
    #[must_use]
    pub fn failed(&self) -> bool {
        self.failed
    }

    /// The receiver's output at plant time `t_us`: nothing while failed; the schedule's from its first
    /// entry on; before that the port's last good frame; else nothing.
    #[must_use]
    pub fn output(&self, t_us: u64) -> Option<RcFrame> {
        if self.failed {
            return None;
        }
        self.schedule.at(t_us).unwrap_or(self.port_frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(v: u16) -> RcFrame {
        RcFrame::of(&[v; SCHEDULE_CHANNELS])
    }

    #[test]
    fn given_a_schedule_then_each_entry_holds_from_its_time_until_the_next() {
        let s =
            RcSchedule::new(vec![(1_000_000, Some(frame(1100))), (2_000_000, None), (3_000_000, Some(frame(1900)))])
                .unwrap();
        assert_eq!(s.at(0), None, "before the first entry the schedule says nothing");
        assert_eq!(s.at(999_999), None);
        assert_eq!(s.at(1_000_000), Some(Some(frame(1100))));
        assert_eq!(s.at(1_999_999), Some(Some(frame(1100))));
        assert_eq!(s.at(2_000_000), Some(None), "lost: no output");
        assert_eq!(s.at(3_500_000), Some(Some(frame(1900))));
        assert_eq!(s.at(u64::MAX), Some(Some(frame(1900))));
    }

    #[test]
    fn given_entries_out_of_time_order_then_the_error_names_the_entry() {
        let e = RcSchedule::new(vec![(0, None), (2, None), (1, None)]).unwrap_err();
        assert!(e.contains("rc[2]") && e.contains("time order"), "{e}");
    }

    #[test]
    fn given_a_schedule_and_a_port_frame_then_the_schedule_wins_from_its_first_entry_and_sim_rc_fail_silences_both() {
        let mut radio = Radio::default();
        assert_eq!(radio.output(0), None, "a new receiver has no output");
        radio.set_port_frame(frame(1200));
        assert_eq!(radio.output(0), Some(frame(1200)));
        radio.set_schedule(RcSchedule::new(vec![(500_000, Some(frame(1700))), (900_000, None)]).unwrap());
        assert_eq!(radio.output(499_999), Some(frame(1200)), "the port's frame before the schedule begins");
        assert_eq!(radio.output(500_000), Some(frame(1700)));
        assert_eq!(radio.output(900_000), None, "the schedule's loss, though the port has a frame");
        radio.set_failed(true);
        assert_eq!(radio.output(0), None);
        assert_eq!(radio.output(500_000), None);
        radio.set_failed(false);
        assert_eq!(radio.output(500_000), Some(frame(1700)));
    }
}
