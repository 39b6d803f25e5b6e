//! The battery monitor: what the flight pack reports and how worried to be about it. In: the pack's
//! readings as they arrive (`BATTERY_STATUS` from the plant or the ARM board: voltage, current, state of
//! charge, charge drawn), with vehicle time (µs), and whether the vehicle is armed. Out: the latest
//! reading (none when the last is older than [`STALE_AFTER_US`]) and PX4's warning level against
//! `BAT_LOW_THR`, `BAT_CRIT_THR` and `BAT_EMERGEN_THR` (fractions of the capacity).
//!
//! As PX4's: while armed the level only rises (a pack that recovers its voltage at low load is not
//! fuller); disarmed it follows the reading, so a fresh pack clears it. The commander acts on the level
//! (see `commander::failsafe`, `COM_LOW_BAT_ACT`) and refuses to arm at `Low` or worse.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A reading older than this (µs of vehicle time) is no reading: the monitor says "unknown".
pub const STALE_AFTER_US: u64 = 5_000_000;

/// One reading of the pack.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BatterySample {
    /// Terminal voltage of the pack (V).
    pub voltage_v: f64,
    /// Current drawn (A), if measured.
    pub current_a: Option<f64>,
    /// State of charge (0..1), if estimated.
    pub remaining: Option<f64>,
    /// Charge drawn (mAh), if counted.
    pub consumed_mah: Option<f64>,
    /// Energy drawn (J), if counted.
    pub consumed_j: Option<f64>,
    /// Cells whose voltages were reported (0: the total only).
    pub cells: u8,
}

/// PX4's battery warning levels, in rising order of worry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize)]
pub enum BatteryWarning {
    #[default]
    None,
    Low,
    Critical,
    Emergency,
}

impl BatteryWarning {
    /// For the announcement: "low", "critical", "emergency".
    #[must_use]
    pub const fn word(self) -> &'static str {
        match self {
            Self::None => "ok",
            Self::Low => "low",
            Self::Critical => "critical",
            Self::Emergency => "emergency",
        }
    }
}

/// The thresholds (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BatteryConfig {
    /// Low below this state of charge (fraction; BAT_LOW_THR): warn, and refuse to arm.
    pub low_thr: f64,
    /// Critical below this (fraction; BAT_CRIT_THR): COM_LOW_BAT_ACT's first action.
    pub crit_thr: f64,
    /// Emergency below this (fraction; BAT_EMERGEN_THR): COM_LOW_BAT_ACT's last action.
    pub emergen_thr: f64,
}

impl Default for BatteryConfig {
    /// PX4's defaults: 15 %, 7 %, 5 %.
    fn default() -> Self {
        Self { low_thr: 0.15, crit_thr: 0.07, emergen_thr: 0.05 }
    }
}

/// Thresholds that are not fractions in falling order.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("battery thresholds: {0}")]
pub struct BatteryConfigError(pub String);

impl BatteryConfig {
    /// # Errors
    /// Unless 0 < emergency < critical < low < 1 (as PX4 requires).
    pub fn validate(&self) -> Result<(), BatteryConfigError> {
        let (l, c, e) = (self.low_thr, self.crit_thr, self.emergen_thr);
        if [l, c, e].iter().all(|x| x.is_finite()) && 0.0 < e && e < c && c < l && l < 1.0 {
            Ok(())
        } else {
            Err(BatteryConfigError(format!(
                "BAT_EMERGEN_THR {e} < BAT_CRIT_THR {c} < BAT_LOW_THR {l} must hold, all in (0, 1)"
            )))
        }
    }

    /// The level of a state of charge.
    #[must_use]
    pub fn level(&self, remaining: f64) -> BatteryWarning {
        if remaining < self.emergen_thr {
            BatteryWarning::Emergency
        } else if remaining < self.crit_thr {
            BatteryWarning::Critical
        } else if remaining < self.low_thr {
            BatteryWarning::Low
        } else {
            BatteryWarning::None
        }
    }
}

/// What the monitor says now.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BatteryStatus {
    /// The latest reading, unless stale.
    pub sample: Option<BatterySample>,
    pub level: BatteryWarning,
}

impl BatteryStatus {
    /// The state of charge (0..1), if known.
    #[must_use]
    pub fn remaining(&self) -> Option<f64> {
        self.sample.and_then(|s| s.remaining)
    }

    /// The state of charge in whole percent, truncated as a gauge reads (14.99 % is 14 %), if known (for
    /// texts and the wire).
    #[must_use]
    pub fn remaining_pct(&self) -> Option<u8> {
        self.remaining().map(|r| (r * 100.0 + 1e-9).floor().clamp(0.0, 100.0) as u8)
    }
}

/// The monitor. See the module docs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BatteryMonitor {
    config: BatteryConfig,
    last: Option<(u64, BatterySample)>,
    level: BatteryWarning,
}

impl BatteryMonitor {
    /// # Errors
    /// [`BatteryConfigError`] for thresholds out of order.
    pub fn new(config: BatteryConfig) -> Result<Self, BatteryConfigError> {
        config.validate()?;
        Ok(Self { config, last: None, level: BatteryWarning::None })
    }

    /// New thresholds, from the next update.
    ///
    /// # Errors
    /// [`BatteryConfigError`]; nothing changes then.
    pub fn set_config(&mut self, config: BatteryConfig) -> Result<(), BatteryConfigError> {
        config.validate()?;
        self.config = config;
        Ok(())
    }

    /// A reading (if one arrived) at `now_us`; the level while `armed` or not.
    pub fn update(&mut self, now_us: u64, sample: Option<BatterySample>, armed: bool) {
        let finite = |s: &BatterySample| {
            s.voltage_v.is_finite() && s.remaining.is_none_or(f64::is_finite) && s.current_a.is_none_or(f64::is_finite)
        };
        if let Some(s) = sample.filter(finite) {
            self.last = Some((now_us, s));
        }
        let level = self.status(now_us).remaining().map_or(BatteryWarning::None, |r| self.config.level(r));
        self.level = if armed { self.level.max(level) } else { level };
    }

    /// The reading (unless stale at `now_us`) and the level.
    #[must_use]
    pub fn status(&self, now_us: u64) -> BatteryStatus {
        let sample =
            self.last.filter(|(t, _)| now_us.saturating_sub(*t) <= STALE_AFTER_US && now_us >= *t).map(|(_, s)| s);
        BatteryStatus { sample, level: self.level }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(remaining: f64) -> Option<BatterySample> {
        Some(BatterySample { voltage_v: 22.0, remaining: Some(remaining), ..BatterySample::default() })
    }

    #[test]
    fn given_px4_thresholds_then_levels_fall_in_order_and_bad_orders_are_refused() {
        let c = BatteryConfig::default();
        assert_eq!(c.level(0.5), BatteryWarning::None);
        assert_eq!(c.level(0.149), BatteryWarning::Low);
        assert_eq!(c.level(0.06), BatteryWarning::Critical);
        assert_eq!(c.level(0.01), BatteryWarning::Emergency);
        assert!(BatteryConfig { crit_thr: 0.2, ..c }.validate().is_err(), "critical above low");
        assert!(BatteryConfig { emergen_thr: 0.0, ..c }.validate().is_err());
        assert!(BatteryConfig { low_thr: f64::NAN, ..c }.validate().is_err());
    }

    #[test]
    fn given_armed_then_the_level_only_rises_and_disarmed_it_follows_the_pack() {
        let mut m = BatteryMonitor::new(BatteryConfig::default()).unwrap();
        m.update(0, at(0.06), true);
        assert_eq!(m.status(0).level, BatteryWarning::Critical);
        m.update(1, at(0.2), true);
        assert_eq!(m.status(1).level, BatteryWarning::Critical, "a recovering voltage is not a fuller pack");
        m.update(2, at(0.2), false);
        assert_eq!(m.status(2).level, BatteryWarning::None, "a fresh pack clears it on the ground");
    }

    #[test]
    fn given_no_reading_for_5_s_then_the_pack_is_unknown() {
        let mut m = BatteryMonitor::new(BatteryConfig::default()).unwrap();
        m.update(0, at(0.5), false);
        assert!(m.status(STALE_AFTER_US).sample.is_some());
        assert!(m.status(STALE_AFTER_US + 1).sample.is_none());
        m.update(1, Some(BatterySample { voltage_v: f64::NAN, ..BatterySample::default() }), false);
        assert_eq!(m.status(1).remaining(), Some(0.5), "a non-finite reading is dropped");
        assert_eq!(m.status(1).remaining_pct(), Some(50));
    }
}
