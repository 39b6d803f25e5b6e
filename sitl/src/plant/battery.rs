//! The flight pack: a lithium-polymer battery drained by the rotors' power. In, once per plant step: the
//! step length (s), the four rotor lifts (N) and whether the motors run (the armed flag of the actuator
//! command). Out: terminal voltage (V), current (A), state of charge (0..1) and charge drawn (mAh), as a
//! battery monitor on the ARM board measures them.
//!
//! Model (one state, the charge drawn):
//! - rotor power from momentum theory, P_i = F_i^{3/2} / (FM·√(2ρA)) per rotor (A = πr² the disc area, FM
//!   the figure of merit), divided by the drive efficiency η (motor and ESC), plus the avionics' constant
//!   draw; no rotor power while the motors are stopped (disarmed);
//! - the pack: n cells in series, open-circuit voltage per cell a function of the state of charge (a
//!   typical LiPo discharge curve, linear between points every 10 %), internal resistance R: the current
//!   solves P = (n·V_oc - I·R)·I, the terminal voltage is n·V_oc - I·R;
//! - charge drawn: ∫ I dt. With `drain_s` > 0 (PX4's `SIM_BAT_DRAIN`) the state of charge instead falls
//!   linearly from full to empty in `drain_s` seconds while the motors run, so a test can empty the pack in
//!   seconds; either way it never falls below `min_remaining` (PX4's `SIM_BAT_MIN_PCT`).
//!
//! A failed pack (SIM_BAT_FAIL = 1, MAV_CMD_INJECT_FAILURE battery off, as PX4's battery failure) reports
//! empty: 0 % at the empty pack's open-circuit voltage (`cells` × [`CELL_OCV_V`]`[0]`), the current and
//! the charge drawn as measured; the pack itself drains on as before and reads true again when cleared.
//!
//! The lift does not depend on the voltage: the paper's lift curve is per PWM, and the ESCs are taken to
//! regulate rotor speed whatever the pack's sag.

use serde::Deserialize;

use super::PlantError;
use super::airframe::{finite, positive};

/// Open-circuit voltage of one LiPo cell (V) at state of charge 0 %, 10 %, ..., 100 %.
pub const CELL_OCV_V: [f64; 11] = [3.27, 3.61, 3.69, 3.73, 3.77, 3.80, 3.84, 3.87, 3.95, 4.06, 4.20];

/// The open-circuit voltage of one cell (V) at `remaining` (0..1, clamped), linear between the points of
/// [`CELL_OCV_V`].
#[must_use]
pub fn cell_ocv_v(remaining: f64) -> f64 {
    let x = remaining.clamp(0.0, 1.0) * 10.0;
    let i = (x.floor() as usize).min(9);
    let f = x - i as f64;
    CELL_OCV_V[i] + f * (CELL_OCV_V[i + 1] - CELL_OCV_V[i])
}

/// The `[battery]` table.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BatteryConfig {
    /// Whether the plant simulates (and reports) a pack at all.
    pub enabled: bool,
    /// Cells in series (1-14, as BATTERY_STATUS carries).
    pub cells: u8,
    /// Capacity (mAh).
    pub capacity_mah: f64,
    /// Internal resistance of the whole pack (Ω).
    pub internal_resistance_ohm: f64,
    /// State of charge at start (0..1].
    pub initial_remaining: f64,
    /// Rotor radius r (m): the disc area πr² of momentum theory.
    pub rotor_radius_m: f64,
    /// Rotor figure of merit FM (0..1]: ideal induced power over actual.
    pub figure_of_merit: f64,
    /// Motor and ESC efficiency η (0..1]: shaft power over electrical power.
    pub drive_efficiency: f64,
    /// Current of the avionics, drawn whether or not the motors run (A).
    pub avionics_current_a: f64,
    /// PX4's SIM_BAT_DRAIN (s): > 0 drains the pack linearly from full to empty in this time while the
    /// motors run (instead of by the current drawn); 0 = by the current.
    pub drain_s: f64,
    /// PX4's SIM_BAT_MIN_PCT as a fraction (0..1): the state of charge never falls below it.
    pub min_remaining: f64,
}

impl Default for BatteryConfig {
    /// A 6-cell 10 Ah pack: about 30 A and 20 minutes in hover for the nominal 5.2 kg airframe.
    fn default() -> Self {
        Self {
            enabled: true,
            cells: 6,
            capacity_mah: 10_000.0,
            internal_resistance_ohm: 0.015,
            initial_remaining: 1.0,
            rotor_radius_m: 0.2,
            figure_of_merit: 0.6,
            drive_efficiency: 0.75,
            avionics_current_a: 0.5,
            drain_s: 0.0,
            min_remaining: 0.0,
        }
    }
}

fn fraction(name: &'static str, value: f64, allow_zero: bool) -> Result<(), PlantError> {
    let ok = value.is_finite() && value <= 1.0 && (value > 0.0 || (allow_zero && value == 0.0));
    if ok {
        Ok(())
    } else {
        let reason = if allow_zero { "must be in [0, 1]" } else { "must be in (0, 1]" };
        Err(PlantError::InvalidValue { name, value: value.to_string(), reason })
    }
}

impl BatteryConfig {
    /// Check the values.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] naming the first value out of range.
    pub fn validate(&self) -> Result<(), PlantError> {
        if !(1..=14).contains(&self.cells) {
            return Err(PlantError::InvalidValue {
                name: "battery.cells",
                value: self.cells.to_string(),
                reason: "must be 1 to 14 (what BATTERY_STATUS carries)",
            });
        }
        positive("battery.capacity_mah", self.capacity_mah)?;
        positive("battery.rotor_radius_m", self.rotor_radius_m)?;
        finite("battery.internal_resistance_ohm", self.internal_resistance_ohm)?;
        finite("battery.avionics_current_a", self.avionics_current_a)?;
        finite("battery.drain_s", self.drain_s)?;
        for (name, v) in [
            ("battery.internal_resistance_ohm", self.internal_resistance_ohm),
            ("battery.avionics_current_a", self.avionics_current_a),
            ("battery.drain_s", self.drain_s),
        ] {
            if v < 0.0 {
                return Err(PlantError::InvalidValue { name, value: v.to_string(), reason: "must be >= 0" });
            }
        }
        fraction("battery.initial_remaining", self.initial_remaining, false)?;
        fraction("battery.figure_of_merit", self.figure_of_merit, false)?;
        fraction("battery.drive_efficiency", self.drive_efficiency, false)?;
        fraction("battery.min_remaining", self.min_remaining, true)
    }
}

/// What the pack's monitor reads now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryReading {
    /// Terminal voltage of the pack (V).
    pub voltage_v: f64,
    /// Current drawn (A).
    pub current_a: f64,
    /// State of charge (0..1).
    pub remaining: f64,
    /// Charge drawn since start (mAh).
    pub consumed_mah: f64,
    /// Energy drawn since start (J).
    pub consumed_j: f64,
    pub cells: u8,
}

/// The pack. See the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct Battery {
    config: BatteryConfig,
    remaining: f64,
    consumed_j: f64,
    current_a: f64,
    voltage_v: f64,
    /// The monitor reports the pack empty (SIM_BAT_FAIL).
    failed: bool,
}

impl Battery {
    /// A pack at `config.initial_remaining`, drawing the avionics' current.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for an invalid configuration.
    pub fn new(config: BatteryConfig) -> Result<Self, PlantError> {
        config.validate()?;
        let mut b = Self {
            config,
            remaining: config.initial_remaining,
            consumed_j: 0.0,
            current_a: 0.0,
            voltage_v: 0.0,
            failed: false,
        };
        b.settle(b.config.avionics_current_a * b.open_circuit_v());
        Ok(b)
    }

    #[must_use]
    pub fn config(&self) -> &BatteryConfig {
        &self.config
    }

    /// Changes the drain time (s; SIM_BAT_DRAIN) from now.
    pub fn set_drain_s(&mut self, drain_s: f64) {
        self.config.drain_s = drain_s.max(0.0);
    }

    /// Changes the floor (fraction; SIM_BAT_MIN_PCT / 100) from now.
    pub fn set_min_remaining(&mut self, min_remaining: f64) {
        self.config.min_remaining = min_remaining.clamp(0.0, 1.0);
    }

    /// Whether the monitor reports the pack empty from now (SIM_BAT_FAIL; see the module docs).
    pub fn set_failed(&mut self, failed: bool) {
        self.failed = failed;
    }

    /// Whether the monitor reports the pack empty.
    #[must_use]
    pub fn failed(&self) -> bool {
        self.failed
    }

    fn open_circuit_v(&self) -> f64 {
        f64::from(self.config.cells) * cell_ocv_v(self.remaining)
    }

    /// Electrical power drawn (W) for rotor lifts `lift_n` with the motors running or not.
    #[must_use]
    pub fn power_w(&self, lift_n: &[f64; 4], motors_running: bool, air_density_kgpm3: f64) -> f64 {
        let c = &self.config;
        let avionics_w = c.avionics_current_a * self.open_circuit_v();
        if !motors_running {
            return avionics_w;
        }
        let disc_m2 = std::f64::consts::PI * c.rotor_radius_m * c.rotor_radius_m;
        let induced = c.figure_of_merit * (2.0 * air_density_kgpm3 * disc_m2).sqrt();
        let shaft_w: f64 = lift_n.iter().map(|f| f.max(0.0).powf(1.5) / induced).sum();
        shaft_w / c.drive_efficiency + avionics_w
    }

    /// The current and terminal voltage that deliver `power_w` from the open-circuit voltage through the
    /// internal resistance (the lower root; at most the maximum-power current V_oc/2R).
    fn settle(&mut self, power_w: f64) {
        let v_oc = self.open_circuit_v();
        let r = self.config.internal_resistance_ohm;
        self.current_a = if r > 0.0 {
            let disc = v_oc * v_oc - 4.0 * r * power_w;
            if disc > 0.0 { (v_oc - disc.sqrt()) / (2.0 * r) } else { v_oc / (2.0 * r) }
        } else {
            power_w / v_oc
        };
        self.voltage_v = v_oc - self.current_a * r;
    }

    /// Advances by `dt_s` with rotor lifts `lift_n` (N) held and the motors running or not.
    pub fn step(&mut self, dt_s: f64, lift_n: &[f64; 4], motors_running: bool, air_density_kgpm3: f64) {
        let power_w = self.power_w(lift_n, motors_running, air_density_kgpm3);
        self.settle(power_w);
        let c = &self.config;
        let drop = if c.drain_s > 0.0 {
            if motors_running { dt_s / c.drain_s } else { 0.0 }
        } else {
            self.current_a * dt_s / 3.6 / c.capacity_mah
        };
        let before = self.remaining;
        self.remaining = (self.remaining - drop).max(c.min_remaining.min(before));
        // Energy follows the charge actually taken (none once at the floor).
        if drop > 0.0 {
            self.consumed_j += power_w * dt_s * (before - self.remaining) / drop;
        }
    }

    /// What the pack's monitor reads now (empty while failed).
    #[must_use]
    pub fn reading(&self) -> BatteryReading {
        let (voltage_v, remaining) = if self.failed {
            (f64::from(self.config.cells) * CELL_OCV_V[0], 0.0)
        } else {
            (self.voltage_v, self.remaining)
        };
        BatteryReading {
            voltage_v,
            current_a: self.current_a,
            remaining,
            consumed_mah: (self.config.initial_remaining - self.remaining) * self.config.capacity_mah,
            consumed_j: self.consumed_j,
            cells: self.config.cells,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RHO: f64 = 1.225;
    /// Hover lift per rotor of the nominal 5.2 kg airframe (N).
    const HOVER_N: f64 = 5.2 * 9.81 / 4.0;

    #[test]
    fn given_the_ocv_table_then_the_curve_is_monotonic_and_hits_its_points() {
        assert_eq!(cell_ocv_v(1.0), 4.20);
        assert_eq!(cell_ocv_v(0.0), 3.27);
        assert!((cell_ocv_v(0.55) - 3.82).abs() < 1e-12, "halfway between 50 % and 60 %");
        let mut last = 0.0;
        for k in 0..=100 {
            let v = cell_ocv_v(f64::from(k) / 100.0);
            assert!(v >= last);
            last = v;
        }
    }

    #[test]
    fn given_the_default_pack_in_hover_then_it_draws_about_30_a_and_lasts_about_20_minutes() {
        let mut b = Battery::new(BatteryConfig::default()).unwrap();
        b.step(0.002, &[HOVER_N; 4], true, RHO);
        let r = b.reading();
        assert!((27.0..33.0).contains(&r.current_a), "{} A", r.current_a);
        assert!(r.voltage_v < 6.0 * 4.2 && r.voltage_v > 24.0, "{} V (sag below 25.2 V)", r.voltage_v);
        // 10 Ah at about 30 A.
        let minutes = 10.0 / r.current_a * 60.0;
        assert!((18.0..22.0).contains(&minutes), "{minutes} min");
    }

    #[test]
    fn given_motors_stopped_then_only_the_avionics_draw_and_drain_s_does_not_run() {
        let config = BatteryConfig { drain_s: 10.0, ..BatteryConfig::default() };
        let mut b = Battery::new(config).unwrap();
        for _ in 0..1000 {
            b.step(0.01, &[11.3; 4], false, RHO);
        }
        let r = b.reading();
        assert!((r.current_a - 0.5).abs() < 0.01, "{} A", r.current_a);
        assert_eq!(r.remaining, 1.0, "SIM_BAT_DRAIN drains only while the motors run");
    }

    #[test]
    fn given_sim_bat_drain_then_the_pack_empties_linearly_down_to_its_floor() {
        let config = BatteryConfig { drain_s: 20.0, min_remaining: 0.1, ..BatteryConfig::default() };
        let mut b = Battery::new(config).unwrap();
        for _ in 0..500 {
            b.step(0.02, &[HOVER_N; 4], true, RHO);
        }
        assert!((b.reading().remaining - 0.5).abs() < 1e-9, "{}", b.reading().remaining);
        assert!((b.reading().consumed_mah - 5000.0).abs() < 1e-6);
        for _ in 0..1000 {
            b.step(0.02, &[HOVER_N; 4], true, RHO);
        }
        assert_eq!(b.reading().remaining, 0.1, "held at SIM_BAT_MIN_PCT");
        let v_end = b.reading().voltage_v;
        assert!(v_end < 6.0 * 3.7, "a nearly empty pack sags: {v_end} V");
    }

    #[test]
    fn given_a_physical_drain_then_the_charge_drawn_is_the_integral_of_the_current() {
        let mut b = Battery::new(BatteryConfig::default()).unwrap();
        let mut mah = 0.0;
        for _ in 0..6000 {
            b.step(0.01, &[HOVER_N; 4], true, RHO);
            mah += b.reading().current_a * 0.01 / 3.6;
        }
        assert!((b.reading().consumed_mah - mah).abs() < 1e-6 * mah, "{} vs {mah}", b.reading().consumed_mah);
        assert!(b.reading().consumed_j > 0.0);
    }

    #[test]
    fn given_the_pack_failed_then_its_monitor_reads_0_percent_at_the_empty_voltage_and_clearing_gives_the_truth_back() {
        let mut b = Battery::new(BatteryConfig::default()).unwrap();
        let mut reference = b.clone();
        b.set_failed(true);
        for _ in 0..500 {
            b.step(0.01, &[HOVER_N; 4], true, RHO);
            reference.step(0.01, &[HOVER_N; 4], true, RHO);
        }
        let (failed, truth) = (b.reading(), reference.reading());
        assert_eq!(failed.remaining, 0.0);
        assert!((failed.voltage_v - 6.0 * 3.27).abs() < 1e-12, "6 cells at 3.27 V: {}", failed.voltage_v);
        assert_eq!((failed.current_a, failed.consumed_mah), (truth.current_a, truth.consumed_mah), "as measured");
        assert!(truth.remaining > 0.9 && truth.voltage_v > 23.0, "the pack itself is nearly full: {truth:?}");
        b.set_failed(false);
        assert_eq!(b.reading(), truth, "the pack drained on as before");
    }

    #[test]
    fn given_bad_values_then_validation_names_them() {
        for (config, name) in [
            (BatteryConfig { cells: 0, ..BatteryConfig::default() }, "battery.cells"),
            (BatteryConfig { cells: 15, ..BatteryConfig::default() }, "battery.cells"),
            (BatteryConfig { capacity_mah: 0.0, ..BatteryConfig::default() }, "battery.capacity_mah"),
            (BatteryConfig { initial_remaining: 1.5, ..BatteryConfig::default() }, "battery.initial_remaining"),
            (BatteryConfig { min_remaining: -0.1, ..BatteryConfig::default() }, "battery.min_remaining"),
            (BatteryConfig { drain_s: f64::NAN, ..BatteryConfig::default() }, "battery.drain_s"),
        ] {
            let e = config.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
    }
}
