//! `HIL_SENSOR` (the IMU, magnetometer and barometer of one plant step) and `HIL_GPS` (a released fix),
//! to and from the neutral [`HilSensorFields`] and the estimator's samples.

use mavlink::dialects::common::{HIL_GPS_DATA, HIL_SENSOR_DATA, HilSensorUpdatedFlags};
use nalgebra::Vector3;

use super::{vec3_f32, vec3_f64};
use crate::core::estimator::{BaroSample, GpsSample, ImuSample, MagSample};
use crate::core::mavlink::units::{
    UNKNOWN_U16, centi_u16_to, cmps_i16_to_mps, deg_to_dege7, dege7_to_deg, m_to_mm, mm_to_m, mps_to_cmps_i16,
    rad_to_cdeg_0_360, to_centi_u16,
};

// ---------------------------------------------------------------------------------------------------------
// HIL_SENSOR
// ---------------------------------------------------------------------------------------------------------

/// Everything one `HIL_SENSOR` carries, in SI-ish units: the neutral type both ends map onto.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HilSensorFields {
    /// Sample time (µs, the plant's clock).
    pub time_us: u64,
    /// Specific force (m/s², FRD): `(0, 0, -g)` at rest.
    pub accel_frd_mps2: Vector3<f64>,
    /// Body rates (rad/s, FRD).
    pub gyro_frd_radps: Vector3<f64>,
    /// Magnetic field (gauss, FRD); `None` = not updated in this sample.
    pub mag_frd_gauss: Option<Vector3<f64>>,
    /// Barometer; `None` = not updated in this sample.
    pub baro: Option<HilBaroFields>,
}

/// The barometer part of `HIL_SENSOR`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HilBaroFields {
    /// Static pressure (hPa).
    pub pressure_hpa: f64,
    /// Pressure altitude (m AMSL).
    pub pressure_alt_m: f64,
    /// Air temperature (°C).
    pub temperature_degc: f64,
}

fn accel_gyro_flags() -> HilSensorUpdatedFlags {
    HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_XACC
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_YACC
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ZACC
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_XGYRO
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_YGYRO
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ZGYRO
}

fn mag_flags() -> HilSensorUpdatedFlags {
    HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_XMAG
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_YMAG
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ZMAG
}

fn baro_flags() -> HilSensorUpdatedFlags {
    HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ABS_PRESSURE
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_PRESSURE_ALT
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_TEMPERATURE
}

/// [`HilSensorFields`] -> `HIL_SENSOR` (f32 fields, `fields_updated` naming what is present).
#[must_use]
pub fn encode_hil_sensor(fields: &HilSensorFields) -> HIL_SENSOR_DATA {
    let [xacc, yacc, zacc] = vec3_f32(&fields.accel_frd_mps2);
    let [xgyro, ygyro, zgyro] = vec3_f32(&fields.gyro_frd_radps);
    let mut fields_updated = accel_gyro_flags();
    let [xmag, ymag, zmag] = match &fields.mag_frd_gauss {
        Some(mag) => {
            fields_updated |= mag_flags();
            vec3_f32(mag)
        }
        None => [0.0; 3],
    };
    let (abs_pressure, pressure_alt, temperature) = match &fields.baro {
        Some(baro) => {
            fields_updated |= baro_flags();
            (baro.pressure_hpa as f32, baro.pressure_alt_m as f32, baro.temperature_degc as f32)
        }
        None => (0.0, 0.0, 0.0),
    };
    HIL_SENSOR_DATA {
        time_usec: fields.time_us,
        xacc,
        yacc,
        zacc,
        xgyro,
        ygyro,
        zgyro,
        xmag,
        ymag,
        zmag,
        abs_pressure,
        diff_pressure: 0.0,
        pressure_alt,
        temperature,
        fields_updated,
        ..Default::default()
    }
}

/// `HIL_SENSOR` -> [`HilSensorFields`]: the magnetometer and barometer only when all their
/// `fields_updated` bits are set (the IMU part is always taken: the plant sends it every step).
#[must_use]
pub fn decode_hil_sensor(msg: &HIL_SENSOR_DATA) -> HilSensorFields {
    let flags = msg.fields_updated;
    HilSensorFields {
        time_us: msg.time_usec,
        accel_frd_mps2: vec3_f64(msg.xacc, msg.yacc, msg.zacc),
        gyro_frd_radps: vec3_f64(msg.xgyro, msg.ygyro, msg.zgyro),
        mag_frd_gauss: flags.contains(mag_flags()).then(|| vec3_f64(msg.xmag, msg.ymag, msg.zmag)),
        baro: flags.contains(baro_flags()).then(|| HilBaroFields {
            pressure_hpa: f64::from(msg.abs_pressure),
            pressure_alt_m: f64::from(msg.pressure_alt),
            temperature_degc: f64::from(msg.temperature),
        }),
    }
}

/// The estimator's samples of one `HIL_SENSOR`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSamples {
    pub imu: ImuSample,
    pub mag: Option<MagSample>,
    pub baro: Option<BaroSample>,
}

impl From<&HilSensorFields> for SensorSamples {
    fn from(f: &HilSensorFields) -> Self {
        Self {
            imu: ImuSample { time_us: f.time_us, accel_frd_mps2: f.accel_frd_mps2, gyro_frd_radps: f.gyro_frd_radps },
            mag: f.mag_frd_gauss.map(|field_frd_gauss| MagSample { field_frd_gauss }),
            baro: f.baro.map(|b| BaroSample { pressure_alt_m: b.pressure_alt_m }),
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// HIL_GPS
// ---------------------------------------------------------------------------------------------------------

/// Course over ground (deg, 0..360 clockwise from north) of a NED velocity; 0 when standing still.
#[must_use]
pub fn course_deg(vel_ned_mps: &Vector3<f64>) -> f64 {
    vel_ned_mps.y.atan2(vel_ned_mps.x).to_degrees().rem_euclid(360.0)
}

/// [`GpsSample`] -> `HIL_GPS`: lat/lon degE7, alt mm AMSL, eph/epv cm, ground speed and NED velocity cm/s,
/// course over ground cdeg (0..35999). `time_usec` is the time the fix was valid.
#[must_use]
pub fn encode_hil_gps(gps: &GpsSample) -> HIL_GPS_DATA {
    let v = &gps.vel_ned_mps;
    HIL_GPS_DATA {
        time_usec: gps.time_us,
        lat: deg_to_dege7(gps.lat_deg),
        lon: deg_to_dege7(gps.lon_deg),
        alt: m_to_mm(gps.alt_amsl_m),
        eph: to_centi_u16(gps.eph_m),
        epv: to_centi_u16(gps.epv_m),
        vel: to_centi_u16(v.x.hypot(v.y)),
        vn: mps_to_cmps_i16(v.x),
        ve: mps_to_cmps_i16(v.y),
        vd: mps_to_cmps_i16(v.z),
        cog: if v.iter().all(|x| x.is_finite()) { rad_to_cdeg_0_360(v.y.atan2(v.x)) } else { UNKNOWN_U16 },
        fix_type: gps.fix_type,
        satellites_visible: gps.satellites,
        ..Default::default()
    }
}

/// `HIL_GPS` -> [`GpsSample`] (unknown eph/epv -> +inf, which the estimator refuses).
#[must_use]
pub fn decode_hil_gps(msg: &HIL_GPS_DATA) -> GpsSample {
    GpsSample {
        time_us: msg.time_usec,
        lat_deg: dege7_to_deg(msg.lat),
        lon_deg: dege7_to_deg(msg.lon),
        alt_amsl_m: mm_to_m(msg.alt),
        vel_ned_mps: Vector3::new(cmps_i16_to_mps(msg.vn), cmps_i16_to_mps(msg.ve), cmps_i16_to_mps(msg.vd)),
        fix_type: msg.fix_type,
        satellites: msg.satellites_visible,
        eph_m: centi_u16_to(msg.eph),
        epv_m: centi_u16_to(msg.epv),
    }
}
