//! The plant's state as the plant protocol's samples: sensors, truth (plain or with the paper's
//! state noise), the battery and when it is due, and the home as the protocol's geodetic origin.

use autopilot::core::battery::BatterySample;
use autopilot::core::estimator::{GeoOrigin, TruthSample};
use autopilot::core::plant_link::HilSensorFields;
use nalgebra::UnitQuaternion;

use crate::plant::sensors::{HomeConfig, NoisyState};
use crate::plant::{BatteryReading, SensorSample, Truth};

/// The plant's [`HomeConfig`] as the protocol's geodetic origin.
#[must_use]
pub fn home_origin(home: &HomeConfig) -> GeoOrigin {
    home.origin()
}

/// Plant time between two `BATTERY_STATUS` (µs): 10 Hz, as a battery monitor samples.
pub const BATTERY_PERIOD_US: u64 = 100_000;

/// Whether the step at `time_us` (of length `dt_us`) is the first of a [`BATTERY_PERIOD_US`] period.
#[must_use]
pub fn battery_due(time_us: u64, dt_us: u64) -> bool {
    time_us % BATTERY_PERIOD_US < dt_us.max(1)
}

/// A plant pack reading as the protocol's battery sample (the ARM board's monitor reads the same).
#[must_use]
pub fn battery_fields(r: &BatteryReading) -> BatterySample {
    BatterySample {
        voltage_v: r.voltage_v,
        current_a: Some(r.current_a),
        remaining: Some(r.remaining),
        consumed_mah: Some(r.consumed_mah),
        consumed_j: Some(r.consumed_j),
        cells: r.cells,
    }
}

/// A plant sensor sample as `HIL_SENSOR` fields: the IMU always, the magnetometer and barometer when the
/// sample has them (a sensor that is off has no `fields_updated` bits).
#[must_use]
pub fn sensor_fields(sample: &SensorSample) -> HilSensorFields {
    HilSensorFields {
        time_us: sample.time_us,
        accel_frd_mps2: sample.accel_frd_mps2,
        gyro_frd_radps: sample.gyro_frd_radps,
        mag_frd_gauss: sample.mag_frd_gauss,
        baro: sample.baro,
    }
}

/// The plant's truth as the protocol's truth fields.
#[must_use]
pub fn truth_fields(truth: &Truth) -> TruthSample {
    TruthSample {
        time_us: truth.time_us,
        pos_ned_m: truth.pos_ned_m,
        vel_ned_mps: truth.vel_ned_mps,
        q_ned_frd: truth.q_ned_frd,
        rate_frd_radps: truth.rate_frd_radps,
        specific_force_frd_mps2: truth.specific_force_frd_mps2,
    }
}

/// The truth-fed state with noise as the protocol's truth fields (the attitude rebuilt from the noisy
/// Euler angles).
#[must_use]
pub fn noisy_truth_fields(state: &NoisyState) -> TruthSample {
    let e = state.euler_rad;
    TruthSample {
        time_us: state.time_us,
        pos_ned_m: state.pos_ned_m,
        vel_ned_mps: state.vel_ned_mps,
        q_ned_frd: UnitQuaternion::from_euler_angles(e.x, e.y, e.z),
        rate_frd_radps: state.rate_frd_radps,
        specific_force_frd_mps2: state.specific_force_frd_mps2,
    }
}

#[cfg(test)]
mod tests {
    use autopilot::core::plant_link::{decode_hil_sensor, encode_hil_sensor};

    use super::*;
    use crate::plant::testing::run;
    use crate::plant::{Fault, Sensor};

    #[test]
    fn given_baro_and_mag_off_then_they_are_absent_and_hil_sensor_carries_only_the_imu() {
        let faulty = run(20, |k, plant| {
            if k == 10 {
                plant.sensor_faults_mut().set(Sensor::Baro, Fault::Off).expect("baro off");
                plant.sensor_faults_mut().set(Sensor::Mag, Fault::Off).expect("mag off");
            }
        });
        let s = faulty[10];
        assert_eq!((s.mag_frd_gauss, s.baro), (None, None));
        let msg = encode_hil_sensor(&sensor_fields(&s));
        assert_eq!(msg.fields_updated.bits(), 0x3F, "accel and gyro bits only");
        let decoded = decode_hil_sensor(&msg);
        assert_eq!((decoded.mag_frd_gauss, decoded.baro), (None, None), "the autopilot reads no mag, no baro");
        assert!(faulty[9].mag_frd_gauss.is_some() && faulty[9].baro.is_some());
        let on = encode_hil_sensor(&sensor_fields(&faulty[9]));
        assert_eq!(on.fields_updated.bits() & 0x1FC0, 0x1FC0 & !0x400, "mag, pressure, altitude, temperature");
    }
}
