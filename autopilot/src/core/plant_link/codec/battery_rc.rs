//! The board's pack and radio receiver: `BATTERY_STATUS` ([`BatterySample`]) and `RC_CHANNELS`
//! ([`RcFrame`]), both also the vehicle's reports to ground stations.

use mavlink::dialects::common::{
    BATTERY_STATUS_DATA, MavBatteryChargeState, MavBatteryFunction, MavBatteryType, RC_CHANNELS_DATA,
};

use crate::core::battery::BatterySample;
use crate::core::manual::RcFrame;

// ---------------------------------------------------------------------------------------------------------
// BATTERY_STATUS
// ---------------------------------------------------------------------------------------------------------

/// [`BatterySample`] -> `BATTERY_STATUS` (the plant's and the ARM board's pack, and the autopilot's report
/// to ground stations with its `charge_state`): the pack voltage split evenly over `cells` cells in mV
/// (cells 1-10 in `voltages`, 11-14 in `voltages_ext`; with `cells` 0 the total in cell 1), current in cA,
/// charge in mAh, energy in hJ, state of charge in whole percent (truncated); unknowns as MAVLink's invalid values.
#[must_use]
pub fn encode_battery_status(b: &BatterySample, charge_state: MavBatteryChargeState) -> BATTERY_STATUS_DATA {
    let mut voltages = [u16::MAX; 10];
    let mut voltages_ext = [0_u16; 4];
    let cells = usize::from(b.cells.min(14));
    let cell_mv = |v: f64| (v * 1e3).round().clamp(1.0, f64::from(u16::MAX - 1)) as u16;
    if cells == 0 {
        voltages[0] = cell_mv(b.voltage_v);
    } else {
        let per_cell = cell_mv(b.voltage_v / cells as f64);
        for i in 0..cells {
            if i < 10 { voltages[i] = per_cell } else { voltages_ext[i - 10] = per_cell }
        }
    }
    let opt_i32 =
        |v: Option<f64>, scale: f64| v.map_or(-1, |x| (x * scale).round().clamp(0.0, f64::from(i32::MAX)) as i32);
    BATTERY_STATUS_DATA {
        current_consumed: opt_i32(b.consumed_mah, 1.0),
        energy_consumed: opt_i32(b.consumed_j, 0.01),
        temperature: i16::MAX,
        voltages,
        current_battery: b.current_a.map_or(-1, |a| (a * 100.0).round().clamp(0.0, f64::from(i16::MAX)) as i16),
        id: 0,
        battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
        mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
        battery_remaining: b.remaining.map_or(-1, |r| (r * 100.0 + 1e-9).floor().clamp(0.0, 100.0) as i8),
        charge_state,
        voltages_ext,
        ..Default::default()
    }
}

/// `BATTERY_STATUS` -> [`BatterySample`]: the voltage is the sum of the valid cells, `cells` how many there
/// were (a single total in cell 1 counts as 0 cells); MAVLink's invalid values are `None`.
#[must_use]
pub fn decode_battery_status(m: &BATTERY_STATUS_DATA) -> BatterySample {
    let main = m.voltages.iter().take_while(|&&v| v != u16::MAX);
    let ext = m.voltages_ext.iter().take_while(|&&v| v != 0);
    let cells_mv: Vec<u16> = main.chain(ext).copied().collect();
    let voltage_v = cells_mv.iter().map(|&v| f64::from(v)).sum::<f64>() * 1e-3;
    let cells = if cells_mv.len() == 1 && voltage_v > 5.0 { 0 } else { cells_mv.len() as u8 };
    BatterySample {
        voltage_v,
        current_a: (m.current_battery >= 0).then(|| f64::from(m.current_battery) * 0.01),
        remaining: (0..=100).contains(&m.battery_remaining).then(|| f64::from(m.battery_remaining) * 0.01),
        consumed_mah: (m.current_consumed >= 0).then(|| f64::from(m.current_consumed)),
        consumed_j: (m.energy_consumed >= 0).then(|| f64::from(m.energy_consumed) * 100.0),
        cells,
    }
}

// ---------------------------------------------------------------------------------------------------------
// RC_CHANNELS
// ---------------------------------------------------------------------------------------------------------

/// [`RcFrame`] -> `RC_CHANNELS` (the board's radio receiver, and the vehicle's RC telemetry): the 18
/// channels in µs (0 where the receiver has none), their count and RSSI; `time_boot_ms` the sender's clock.
#[must_use]
pub fn encode_rc_channels(frame: &RcFrame, time_boot_ms: u32) -> RC_CHANNELS_DATA {
    let c = &frame.channels_us;
    RC_CHANNELS_DATA {
        time_boot_ms,
        chan1_raw: c[0],
        chan2_raw: c[1],
        chan3_raw: c[2],
        chan4_raw: c[3],
        chan5_raw: c[4],
        chan6_raw: c[5],
        chan7_raw: c[6],
        chan8_raw: c[7],
        chan9_raw: c[8],
        chan10_raw: c[9],
        chan11_raw: c[10],
        chan12_raw: c[11],
        chan13_raw: c[12],
        chan14_raw: c[13],
        chan15_raw: c[14],
        chan16_raw: c[15],
        chan17_raw: c[16],
        chan18_raw: c[17],
        chancount: frame.count.min(18),
        rssi: frame.rssi,
    }
}

/// `RC_CHANNELS` -> [`RcFrame`] (exact: every field is carried as it is; a count above 18 reads as 18).
#[must_use]
pub fn decode_rc_channels(m: &RC_CHANNELS_DATA) -> RcFrame {
    RcFrame {
        channels_us: [
            m.chan1_raw,
            m.chan2_raw,
            m.chan3_raw,
            m.chan4_raw,
            m.chan5_raw,
            m.chan6_raw,
            m.chan7_raw,
            m.chan8_raw,
            m.chan9_raw,
            m.chan10_raw,
            m.chan11_raw,
            m.chan12_raw,
            m.chan13_raw,
            m.chan14_raw,
            m.chan15_raw,
            m.chan16_raw,
            m.chan17_raw,
            m.chan18_raw,
        ],
        count: m.chancount.min(18),
        rssi: m.rssi,
    }
}
