//! A scenario's stick schedule, `[[rc]]`: what the pilot's radio says from each plant time on, as the
//! airframe's receiver outputs it (sent to the autopilot as `RC_CHANNELS`, see [`crate::plant::Radio`]).
//!
//! ```toml
//! [[rc]]
//! at_s = 1.0                       # plant time (s) from which this entry holds
//! ch = { "3" = 1000, "4" = 2000 }  # 1-based channel -> PWM (µs, 800..2200); the others keep their value
//! [[rc]]
//! at_s = 2.5
//! ch = { "4" = 1500 }
//! [[rc]]
//! at_s = 8.0
//! lost = true                      # the receiver has no output until the next `ch` entry
//! ```
//!
//! The first `ch` entry starts from 16 channels at 1500 µs with channel 3 (throttle, AETR) at 1000 µs;
//! a `ch` entry after `lost = true` starts from the values before the loss. Entries are in time order
//! (equal times apply in file order), each has exactly one of `ch` and `lost = true`; an unknown key, a
//! channel outside 1..16, a PWM outside 800..2200, a time out of order or after the run's end is an error
//! naming the entry (`rc[2] (at_s = 3)`).

use std::collections::BTreeMap;

use autopilot::core::manual::RcFrame;
use serde::Deserialize;

use crate::plant::radio::{
    RC_PWM_MAX_US, RC_PWM_MIN_US, RcSchedule, SCHEDULE_CENTRE_US, SCHEDULE_CHANNELS, SCHEDULE_THROTTLE_START_US,
};

/// One `[[rc]]` entry as written.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RcEntry {
    /// Plant time (s) from which the entry holds.
    pub at_s: f64,
    /// Channels to set: 1-based channel number (a string key, as TOML tables have) -> PWM (µs).
    #[serde(default)]
    pub ch: Option<BTreeMap<String, i64>>,
    /// `true`: the receiver stops output.
    #[serde(default)]
    pub lost: Option<bool>,
}

/// The schedule `entries` describe, checked against a run of `duration_s`.
///
/// # Errors
/// A message naming the entry (`rc[i] (at_s = t)`) and what is wrong with it.
pub fn schedule(entries: &[RcEntry], duration_s: f64) -> Result<RcSchedule, String> {
    let mut channels_us = [SCHEDULE_CENTRE_US; SCHEDULE_CHANNELS];
    channels_us[2] = SCHEDULE_THROTTLE_START_US;
    let mut out = Vec::with_capacity(entries.len());
    let mut last_s = f64::NEG_INFINITY;
    for (i, e) in entries.iter().enumerate() {
        let name = format!("rc[{i}] (at_s = {})", e.at_s);
        if !(e.at_s.is_finite() && e.at_s >= 0.0) {
            return Err(format!("{name}: at_s must be a plant time >= 0 s"));
        }
        if e.at_s < last_s {
            return Err(format!(
                "{name}: earlier than the entry before it (at_s = {last_s}): entries are in time order"
            ));
        }
        if e.at_s > duration_s {
            return Err(format!("{name}: after the run's end (duration_s = {duration_s})"));
        }
        last_s = e.at_s;
        let output = match (&e.ch, e.lost) {
            (Some(_), Some(_)) => return Err(format!("{name}: either ch or lost = true, not both")),
            (None, None) => return Err(format!("{name}: needs ch = {{ \"1\" = 1500, ... }} or lost = true")),
            (None, Some(false)) => {
                return Err(format!(
                    "{name}: lost = false means nothing: give ch to set channels, lost = true to stop"
                ));
            }
            (None, Some(true)) => None,
            (Some(ch), None) => {
                if ch.is_empty() {
                    return Err(format!("{name}: ch sets no channel"));
                }
                for (key, &value) in ch {
                    let n =
                        key.trim().parse::<usize>().ok().filter(|n| (1..=SCHEDULE_CHANNELS).contains(n)).ok_or_else(
                            || format!("{name}: channel \"{key}\" is not a channel 1..{SCHEDULE_CHANNELS}"),
                        )?;
                    let value_us =
                        u16::try_from(value).ok().filter(|v| (RC_PWM_MIN_US..=RC_PWM_MAX_US).contains(v)).ok_or_else(
                            || format!("{name}: channel {n} = {value} us is outside {RC_PWM_MIN_US}..={RC_PWM_MAX_US}"),
                        )?;
                    channels_us[n - 1] = value_us;
                }
                Some(RcFrame::of(&channels_us))
            }
        };
        out.push(((e.at_s * 1e6).round() as u64, output));
    }
    RcSchedule::new(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    /// A valid ground hover with `rc` appended.
    fn with_rc(rc: &str) -> String {
        format!(
            "name = \"x\"\nduration_s = 10.0\nmetrics = [\"steps\"]\n\
             [reference]\nkind = \"position\"\nsteps = [{{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.0] }}]\n{rc}"
        )
    }

    #[test]
    fn given_a_schedule_then_the_first_entry_starts_centred_with_throttle_low_and_later_entries_keep_the_others() {
        let s = Scenario::from_toml(
            "x",
            &with_rc(
                "[[rc]]\nat_s = 0.5\nch = { \"4\" = 2000 }\n[[rc]]\nat_s = 2.0\nch = { \"4\" = 1500, \"3\" = 1600 }\n\
                 [[rc]]\nat_s = 3.0\nlost = true\n[[rc]]\nat_s = 4.0\nch = { \"16\" = 800 }\n",
            ),
        )
        .unwrap();
        let schedule = s.rc_schedule().unwrap();
        let mut first = [1500_u16; 16];
        first[2] = 1000;
        first[3] = 2000;
        let mut second = first;
        second[2] = 1600;
        second[3] = 1500;
        let mut fourth = second;
        fourth[15] = 800;
        assert_eq!(
            schedule.entries(),
            [
                (500_000, Some(RcFrame::of(&first))),
                (2_000_000, Some(RcFrame::of(&second))),
                (3_000_000, None),
                (4_000_000, Some(RcFrame::of(&fourth)))
            ]
        );
        assert_eq!(schedule.at(0), None, "nothing before the first entry");
        assert_eq!(RcFrame::of(&first).count, 16);
        let none = Scenario::from_toml("x", &with_rc("")).unwrap();
        assert!(none.rc.is_empty() && none.rc_schedule().unwrap().entries().is_empty());
    }

    #[test]
    fn given_a_bad_entry_then_the_error_names_the_entry_and_what_is_wrong() {
        let cases = [
            ("[[rc]]\nat_s = 1.0\nch = { \"3\" = 1000 }\nbogus = 1\n", "bogus"),
            ("[[rc]]\nat_s = 1.0\nch = { \"17\" = 1000 }\n", "rc[0] (at_s = 1): channel \"17\" is not a channel 1..16"),
            ("[[rc]]\nat_s = 1.0\nch = { \"0\" = 1000 }\n", "rc[0] (at_s = 1): channel \"0\""),
            ("[[rc]]\nat_s = 1.0\nch = { \"yaw\" = 1000 }\n", "channel \"yaw\""),
            (
                "[[rc]]\nat_s = 1.0\nch = { \"3\" = 2201 }\n",
                "rc[0] (at_s = 1): channel 3 = 2201 us is outside 800..=2200",
            ),
            ("[[rc]]\nat_s = 1.0\nch = { \"3\" = 799 }\n", "channel 3 = 799 us"),
            ("[[rc]]\nat_s = 1.0\nch = { \"3\" = -5 }\n", "channel 3 = -5 us"),
            (
                "[[rc]]\nat_s = 1.0\nch = { \"3\" = 1000 }\n[[rc]]\nat_s = 0.5\nlost = true\n",
                "rc[1] (at_s = 0.5): earlier",
            ),
            ("[[rc]]\nat_s = 11.0\nlost = true\n", "rc[0] (at_s = 11): after the run's end"),
            ("[[rc]]\nat_s = -1.0\nlost = true\n", "rc[0] (at_s = -1): at_s must be"),
            ("[[rc]]\nat_s = 1.0\nch = { \"3\" = 1000 }\nlost = true\n", "either ch or lost"),
            ("[[rc]]\nat_s = 1.0\n", "needs ch"),
            ("[[rc]]\nat_s = 1.0\nlost = false\n", "lost = false"),
            ("[[rc]]\nat_s = 1.0\nch = {}\n", "ch sets no channel"),
            ("[[rc]]\nch = { \"3\" = 1000 }\n", "at_s"),
        ];
        for (rc, needle) in cases {
            let e = match Scenario::from_toml("x", &with_rc(rc)) {
                Ok(_) => panic!("{needle}: accepted"),
                Err(e) => e.to_string(),
            };
            assert!(e.contains(needle), "{needle}: {e}");
        }
    }

    #[test]
    fn given_a_schedule_or_manual_settings_then_the_in_process_runner_refuses_and_says_where_to_fly_it() {
        for extra in ["[[rc]]\nat_s = 1.0\nlost = true\n", "[manual]\narm_gesture = false\n"] {
            let s = Scenario::from_toml("x", &with_rc(extra)).unwrap();
            let opts = crate::scenario::runner::RunOptions::new(autopilot::core::control::ControllerKind::ACO);
            let e = crate::scenario::runner::run(&s, &opts).unwrap_err().to_string();
            assert!(e.contains("sitl run --scenario"), "{e}");
        }
    }

    #[test]
    fn given_manual_settings_then_the_autopilot_is_configured_with_them() {
        let text = with_rc(
            "[manual]\nfltmodes = [2, 2, 2, 2, 2, 2]\n[manual.rc.map]\nfltmode = 5\n[[rc]]\nat_s = 0.0\nch = { \"5\" = 1000 }\n",
        );
        let s = Scenario::from_toml("x", &text).unwrap();
        let opts = crate::scenario::two_process::TwoProcessOptions {
            controller: autopilot::core::control::ControllerKind::ACO,
            plant: None,
            seed: 1,
            instance: 0,
            estimator: None,
            autopilot_args: Vec::new(),
            rc_in_port: None,
        };
        let plant =
            crate::plant::Plant::new(crate::plant::PlantConfig::default(), &crate::plant::InitialState::default(), 1)
                .unwrap();
        let config = crate::scenario::two_process::autopilot_config(&s, &opts, &plant).unwrap();
        let file = autopilot::runtime::ConfigFile::from_toml_str(&config, "scenario").unwrap();
        assert_eq!(file.vehicle.manual.rc.map.fltmode, 5);
        assert_eq!(file.vehicle.manual.fltmodes, [2; 6]);
        let e = Scenario::from_toml("x", &with_rc("[manual]\nrc_map_fltmode = 5\n")).unwrap_err().to_string();
        assert!(e.contains("rc_map_fltmode"), "unknown keys are refused: {e}");
        let e =
            Scenario::from_toml("x", &with_rc("[manual]\nfltmodes = [2, 2, 2, 2, 2, 99]\n")).unwrap_err().to_string();
        assert!(e.contains("[manual]") && e.contains("COM_FLTMODE6 = 99"), "checked as the autopilot would: {e}");
    }
}
