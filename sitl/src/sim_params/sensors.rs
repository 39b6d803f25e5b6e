//! The SIM_ parameters of the plant's sensor, battery and link faults (SIM_GPS_FAIL .. SIM_LINK_LOSS in
//! [`super::SIM_PARAMS`]): their start values read from the plant, and what a set that passed the table's
//! range check does to the plant (or why the plant refuses it, with nothing changed).
//!
//! - SIM_GPS_FAIL, SIM_BARO_FAIL, SIM_MAG_FAIL, SIM_ACC_FAIL, SIM_GYRO_FAIL: the sensor's fault as a
//!   MAVLink `FAILURE_TYPE` number ([`crate::plant::faults`]); a number inside the range that the sensor
//!   does not have (GPS 3 garbage, accelerometer or gyro 1 off) is refused, naming the ones it has.
//! - SIM_GPS_JUMP_N, SIM_GPS_JUMP_E: the wrong GPS's offset (m), from its next fix.
//! - SIM_BAT_FAIL: 1 the battery monitor reports the pack empty ([`crate::plant::battery`]); refused on a
//!   plant that simulates no pack.
//! - SIM_MOT_WRNG_EFF: stored only; the thrust an injected motor WRONG failure leaves
//!   ([`super::failure_sets`]).
//! - SIM_LINK_DELAY, SIM_LINK_LOSS: the plant link's added delay and loss ([`crate::link`]).

use crate::plant::{Fault, Plant, Sensor};

use super::idx;

/// The sensor whose fault parameter `index` is.
fn fault_sensor(index: usize) -> Option<Sensor> {
    match index {
        idx::GPS_FAIL => Some(Sensor::Gps),
        idx::BARO_FAIL => Some(Sensor::Baro),
        idx::MAG_FAIL => Some(Sensor::Mag),
        idx::ACC_FAIL => Some(Sensor::Accel),
        idx::GYRO_FAIL => Some(Sensor::Gyro),
        _ => None,
    }
}

/// The fault parameter of `sensor`.
fn fault_index(sensor: Sensor) -> usize {
    match sensor {
        Sensor::Gps => idx::GPS_FAIL,
        Sensor::Baro => idx::BARO_FAIL,
        Sensor::Mag => idx::MAG_FAIL,
        Sensor::Accel => idx::ACC_FAIL,
        Sensor::Gyro => idx::GYRO_FAIL,
    }
}

/// Whether parameter `index` is one of this module's.
pub(super) fn owns(index: usize) -> bool {
    (idx::GPS_FAIL..=idx::LINK_LOSS_PCT).contains(&index)
}

/// This module's values in `values` (indexed as [`super::SIM_PARAMS`]) as the plant has them now.
pub(super) fn initial_values(plant: &Plant, values: &mut [f32]) {
    let faults = plant.sensor_faults();
    for sensor in Sensor::ALL {
        values[fault_index(sensor)] = f32::from(faults.fault(sensor).failure_type());
    }
    let [north_m, east_m] = faults.gps_jump_ne_m();
    values[idx::GPS_JUMP_N] = north_m as f32;
    values[idx::GPS_JUMP_E] = east_m as f32;
    values[idx::BAT_FAIL] = f32::from(u8::from(plant.battery().is_some_and(crate::plant::Battery::failed)));
    values[idx::LINK_DELAY_MS] = (plant.link_faults().delay_us() / 1000) as f32;
    values[idx::LINK_LOSS_PCT] = plant.link_faults().loss_pct() as f32;
}

/// Apply a set of this module's parameter `index` to `value` (inside the table's range) to `plant`.
///
/// # Errors
/// The plant's reason for refusing it (a fault the sensor does not have, a battery fault without a pack);
/// nothing changed then.
pub(super) fn apply(index: usize, value: f32, plant: &mut Plant) -> Result<(), String> {
    if let Some(sensor) = fault_sensor(index) {
        let refused = || format!("{} has no failure type {value}", sensor.name());
        let fault = Fault::from_failure_type(value as u32).filter(|_| value >= 0.0).ok_or_else(refused)?;
        return plant.sensor_faults_mut().set(sensor, fault).map_err(|e| e.to_string());
    }
    match index {
        idx::GPS_JUMP_N | idx::GPS_JUMP_E => {
            let mut jump = plant.sensor_faults().gps_jump_ne_m();
            jump[index - idx::GPS_JUMP_N] = f64::from(value);
            plant.sensor_faults_mut().set_gps_jump_ne_m(jump);
        }
        idx::BAT_FAIL => {
            if plant.battery().is_none() {
                if value == 1.0 {
                    return Err("the plant simulates no battery ([battery] enabled = false)".into());
                }
            } else {
                plant.battery_mut().set_failed(value == 1.0);
            }
        }
        idx::LINK_DELAY_MS => plant.link_faults_mut().set_delay_us(value as u64 * 1000),
        idx::LINK_LOSS_PCT => plant.link_faults_mut().set_loss_pct(f64::from(value)),
        // SIM_MOT_WRNG_EFF: read by the failure injection, nothing to change now.
        _ => debug_assert_eq!(index, idx::MOT_WRONG_EFF),
    }
    Ok(())
}
