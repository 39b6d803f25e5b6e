//! The plant protocol (MAVLink 2 HIL messages, as PX4 uses with its simulators), pure: no sockets, clocks or
//! files. In from the plant: byte streams or datagrams holding `HIL_SENSOR` (every plant step, 500 Hz by
//! default), `HIL_GPS` (when a fix is released, 10 Hz by default), `HIL_STATE_QUATERNION` (ground truth,
//! every step), `BATTERY_STATUS` (the pack, 10 Hz) and `RC_CHANNELS` (the board's radio receiver, as it
//! reads it; the [`RcFrame`] for the vehicle's manual control); out to the estimator: [`ImuSample`], [`MagSample`],
//! [`BaroSample`], [`GpsSample`] and [`TruthSample`], and to the battery monitor a [`BatterySample`]. Out to the plant, once per sensor sample: the four motor commands as
//! `HIL_ACTUATOR_CONTROLS` (`controls[i] = (pwm_us - 1000) / 1000` for the paper's rotors 1..4, the armed
//! flag in `mode`, `time_usec` echoing the sensor sample it answers).
//!
//! # Forwarded commands (failure injection)
//!
//! A ground station's MAV_CMD_INJECT_FAILURE (420) is the plant's business: the autopilot (with
//! `SYS_FAILURE_EN` = 1, `core::mavlink::failure`) forwards it as a `COMMAND_LONG` (command 420, param1 the
//! FAILURE_UNIT, param2 the FAILURE_TYPE, param3 the instance, 0 = all; target 0/0) written on the plant
//! link just before the step's `HIL_ACTUATOR_CONTROLS`, in the same datagram or serial write. The plant
//! answers each with exactly one `COMMAND_ACK` (command 420; ACCEPTED, UNSUPPORTED for a combination it
//! does not simulate, DENIED for one it refuses) before the `HIL_SENSOR` of a following step (the sensor
//! message stays last: the autopilot ticks on it). A real board that does not know the command simply
//! never answers; the autopilot then answers the ground station UNSUPPORTED after 0.3 s.
//!
//! # Who runs the motors
//!
//! The plant runs its motors on `controls` when `mode` has `MAV_MODE_FLAG_SAFETY_ARMED` (the vehicle is
//! armed) or `MAV_MODE_FLAG_TEST_ENABLED` (a motor test, MAV_CMD_ACTUATOR_TEST or MAV_CMD_DO_MOTOR_TEST,
//! drives the outputs of the disarmed vehicle, as PX4's actuator test drives a disarmed board's ESCs);
//! with neither it holds every motor at 1000 µs whatever `controls` says
//! ([`ActuatorCommand::effective_pwm_us`]). The test flag is its own bit rather than a borrowed "armed",
//! so that the plant (and a log of the link) can tell a bench test from a flight.
//!
//! The plant-independent encoders live here too (from the neutral [`HilSensorFields`] and the estimator
//! types), so both ends share one definition of every scale factor; `sitl::link` only maps its plant types
//! onto them.
//!
//! # Scaling and round-trip precision (encode then decode)
//!
//! | quantity | wire field | wire unit / type | round-trip error |
//! |---|---|---|---|
//! | time | `time_usec` | µs, u64 | exact |
//! | specific force, rates, field | `x/y/zacc`, `x/y/zgyro`, `x/y/zmag` | m/s², rad/s, gauss; f32 | ≤ 2⁻²⁴·\|x\| (6e-8 relative) |
//! | pressure, pressure altitude, temperature | `abs_pressure`, `pressure_alt`, `temperature` | hPa, m, °C; f32 | ≤ 2⁻²⁴·\|x\| (3e-5 m at 500 m) |
//! | GPS / truth latitude, longitude | `lat`, `lon` | degE7, i32 | ≤ 0.5e-7 deg (≤ 5.6 mm north, ≤ 5.6 mm·cos φ east) |
//! | GPS / truth altitude | `alt` | mm AMSL, i32 | ≤ 0.5 mm |
//! | GPS / truth velocity | `vn/ve/vd`, `vx/vy/vz` | cm/s, i16 (±327.67 m/s, saturating) | ≤ 0.5 cm/s |
//! | GPS accuracy | `eph`, `epv` | cm, u16 (65535 = unknown -> +inf, refused by the estimator) | ≤ 0.5 cm |
//! | truth attitude | `attitude_quaternion` | [w, x, y, z] FRD -> NED, f32 | ≤ 1.2e-7 rad |
//! | truth specific force | `xacc/yacc/zacc` | mG (1 mG = 9.80665e-3 m/s²), i16 (±32.767 g, saturating) | ≤ 4.9e-3 m/s² |
//! | precise truth (optional) | `ODOMETRY` x/y/z, vx/vy/vz, q, rates | m, m/s, rad/s NED/FRD; f32 | ≤ 6e-8 relative |
//! | motor command | `controls[0..4]` | (pwm_us - 1000)/1000, f32 | ≤ 3e-5 µs |
//! | pack voltage | `voltages` (per cell), `voltages_ext` | mV, u16 | ≤ 0.5 mV per cell |
//! | pack current, charge, energy | `current_battery`, `current_consumed`, `energy_consumed` | cA i16, mAh i32, hJ i32 | ≤ 5 mA, 0.5 mAh, 50 J |
//! | state of charge | `battery_remaining` | %, i8, truncated (a gauge never overstates) | < 1 % low |
//!
//! Integer fields saturate at their range (NaN encodes as 0). The extension fields (`HIL_SENSOR.id`,
//! `HIL_GPS.id`, `HIL_GPS.yaw`) are left 0 (sensor instance 0, no GPS yaw); MAVLink 2 truncates trailing
//! zeros, as the protocol allows.
//!
//! The frames themselves (MAVLink v2 and v1 out, [`FrameDecoder`] in) are [`crate::core::mavlink::frame`]'s,
//! shared with the ground-station links; their names are re-exported here.

use mavlink::dialects::common::{
    BATTERY_STATUS_DATA, COMMAND_LONG_DATA, HIL_ACTUATOR_CONTROLS_DATA, HIL_GPS_DATA, HIL_SENSOR_DATA,
    HIL_STATE_QUATERNION_DATA, HilActuatorControlsFlags, HilSensorUpdatedFlags, MavBatteryChargeState,
    MavBatteryFunction, MavBatteryType, MavCmd, MavFrame, MavMessage, MavModeFlag, MavResult, ODOMETRY_DATA,
    RC_CHANNELS_DATA,
};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::battery::BatterySample;
use super::estimator::{BaroSample, GeoOrigin, GpsSample, ImuSample, MagSample, TruthSample};
use super::manual::RcFrame;
pub use super::mavlink::frame::{DecodedFrame, DecoderStats, FrameDecoder, encode_frame_v1, encode_frame_v2};

/// The plant's default UDP port (the plant listens on it), as PX4's simulators.
pub const DEFAULT_PLANT_PORT: u16 = 4560;

/// Standard gravity (m/s²) per g, for the milli-g fields of `HIL_STATE_QUATERNION`.
pub const MPS2_PER_G: f64 = 9.806_65;

/// The motor command range (µs), the distributor's: `controls[i] = (pwm_us - PWM_MIN_US) / (PWM_MAX_US -
/// PWM_MIN_US)`.
pub use crate::core::control::distributor::{PWM_MAX_US, PWM_MIN_US};

/// `MAV_MODE_FLAG_SAFETY_ARMED` in `HIL_ACTUATOR_CONTROLS.mode`.
pub const MODE_FLAG_SAFETY_ARMED: u8 = 128;

/// `HIL_GPS`/`HIL_STATE_QUATERNION` "unknown" value of the u16 accuracy, speed and course fields.
pub const UNKNOWN_U16: u16 = u16::MAX;

// ---------------------------------------------------------------------------------------------------------
// Scalar conversions (each names its units; integer ones round to nearest and saturate, NaN -> 0)
// ---------------------------------------------------------------------------------------------------------

/// Degrees -> degE7 (i32), rounded, saturating.
#[must_use]
pub fn deg_to_dege7(angle_deg: f64) -> i32 {
    (angle_deg * 1e7).round() as i32
}

/// degE7 -> degrees.
#[must_use]
pub fn dege7_to_deg(angle_dege7: i32) -> f64 {
    f64::from(angle_dege7) * 1e-7
}

/// Metres -> millimetres (i32), rounded, saturating.
#[must_use]
pub fn m_to_mm(length_m: f64) -> i32 {
    (length_m * 1e3).round() as i32
}

/// Millimetres -> metres.
#[must_use]
pub fn mm_to_m(length_mm: i32) -> f64 {
    f64::from(length_mm) * 1e-3
}

/// Signed speed m/s -> cm/s (i16), rounded, saturating at ±327.67 m/s.
#[must_use]
pub fn mps_to_cmps_i16(speed_mps: f64) -> i16 {
    (speed_mps * 100.0).round() as i16
}

/// cm/s (i16) -> m/s.
#[must_use]
pub fn cmps_i16_to_mps(speed_cmps: i16) -> f64 {
    f64::from(speed_cmps) * 0.01
}

/// Non-negative metres or m/s -> centi-units (u16), rounded, saturating below [`UNKNOWN_U16`]; non-finite
/// or negative -> [`UNKNOWN_U16`] (the protocol's "unknown").
#[must_use]
pub fn to_centi_u16(value: f64) -> u16 {
    if value.is_finite() && value >= 0.0 {
        (value * 100.0).round().min(f64::from(UNKNOWN_U16 - 1)) as u16
    } else {
        UNKNOWN_U16
    }
}

/// Centi-units (u16) -> units; [`UNKNOWN_U16`] -> +inf.
#[must_use]
pub fn centi_u16_to(value_centi: u16) -> f64 {
    if value_centi == UNKNOWN_U16 { f64::INFINITY } else { f64::from(value_centi) * 0.01 }
}

/// Specific force m/s² -> milli-g (i16), rounded, saturating at ±32.767 g.
#[must_use]
pub fn mps2_to_mg(accel_mps2: f64) -> i16 {
    (accel_mps2 / MPS2_PER_G * 1e3).round() as i16
}

/// Milli-g (i16) -> m/s².
#[must_use]
pub fn mg_to_mps2(accel_mg: i16) -> f64 {
    f64::from(accel_mg) * 1e-3 * MPS2_PER_G
}

/// Motor command PWM (µs) -> HIL control in [0, 1]: non-finite -> 1000 µs, clamped to 1000-2000 µs.
#[must_use]
pub fn pwm_us_to_control(pwm_us: f64) -> f32 {
    let pwm_us = if pwm_us.is_finite() { pwm_us.clamp(PWM_MIN_US, PWM_MAX_US) } else { PWM_MIN_US };
    ((pwm_us - PWM_MIN_US) / (PWM_MAX_US - PWM_MIN_US)) as f32
}

/// HIL control -> PWM (µs): non-finite -> 1000 µs, clamped to [0, 1] (negative reverse-thrust values of
/// other vehicles mean 1000 µs here).
#[must_use]
pub fn control_to_pwm_us(control: f32) -> f64 {
    let control = if control.is_finite() { f64::from(control).clamp(0.0, 1.0) } else { 0.0 };
    PWM_MIN_US + control * (PWM_MAX_US - PWM_MIN_US)
}

fn vec3_f32(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

fn vec3_f64(x: f32, y: f32, z: f32) -> Vector3<f64> {
    Vector3::new(f64::from(x), f64::from(y), f64::from(z))
}

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
    let cog_cdeg = ((course_deg(v) * 100.0).round() as u16) % 36_000;
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
        cog: if v.iter().all(|x| x.is_finite()) { cog_cdeg } else { UNKNOWN_U16 },
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

// ---------------------------------------------------------------------------------------------------------
// HIL_STATE_QUATERNION
// ---------------------------------------------------------------------------------------------------------

/// [`TruthSample`] -> `HIL_STATE_QUATERNION`: position mapped to lat/lon (degE7) and alt (mm AMSL) about
/// `home` (the plant's NED origin, same flat-earth map as the plant's), velocity NED cm/s, quaternion
/// [w, x, y, z] FRD -> NED, rates rad/s FRD, specific force mG FRD; both airspeed fields `airspeed_mps` in
/// cm/s.
#[must_use]
pub fn encode_hil_state_quaternion(
    truth: &TruthSample,
    home: &GeoOrigin,
    airspeed_mps: f64,
) -> HIL_STATE_QUATERNION_DATA {
    let (lat_deg, lon_deg, alt_amsl_m) = home.geodetic_from_ned(&truth.pos_ned_m);
    let q = truth.q_ned_frd.quaternion();
    let airspeed_cmps = to_centi_u16(airspeed_mps);
    HIL_STATE_QUATERNION_DATA {
        time_usec: truth.time_us,
        attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        rollspeed: truth.rate_frd_radps.x as f32,
        pitchspeed: truth.rate_frd_radps.y as f32,
        yawspeed: truth.rate_frd_radps.z as f32,
        lat: deg_to_dege7(lat_deg),
        lon: deg_to_dege7(lon_deg),
        alt: m_to_mm(alt_amsl_m),
        vx: mps_to_cmps_i16(truth.vel_ned_mps.x),
        vy: mps_to_cmps_i16(truth.vel_ned_mps.y),
        vz: mps_to_cmps_i16(truth.vel_ned_mps.z),
        ind_airspeed: airspeed_cmps,
        true_airspeed: airspeed_cmps,
        xacc: mps2_to_mg(truth.specific_force_frd_mps2.x),
        yacc: mps2_to_mg(truth.specific_force_frd_mps2.y),
        zacc: mps2_to_mg(truth.specific_force_frd_mps2.z),
    }
}

/// `HIL_STATE_QUATERNION` -> [`TruthSample`], position in NED about `home`. The quaternion is renormalised;
/// a zero or non-finite one decodes as non-finite (the estimator refuses it).
#[must_use]
pub fn decode_hil_state_quaternion(msg: &HIL_STATE_QUATERNION_DATA, home: &GeoOrigin) -> TruthSample {
    let [w, x, y, z] = msg.attitude_quaternion.map(f64::from);
    TruthSample {
        time_us: msg.time_usec,
        pos_ned_m: home.ned_from_geodetic(dege7_to_deg(msg.lat), dege7_to_deg(msg.lon), mm_to_m(msg.alt)),
        vel_ned_mps: Vector3::new(cmps_i16_to_mps(msg.vx), cmps_i16_to_mps(msg.vy), cmps_i16_to_mps(msg.vz)),
        q_ned_frd: UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z)),
        rate_frd_radps: vec3_f64(msg.rollspeed, msg.pitchspeed, msg.yawspeed),
        specific_force_frd_mps2: Vector3::new(mg_to_mps2(msg.xacc), mg_to_mps2(msg.yacc), mg_to_mps2(msg.zacc)),
    }
}

// ---------------------------------------------------------------------------------------------------------
// ODOMETRY (precise truth)
// ---------------------------------------------------------------------------------------------------------

/// Truth in the plant's local NED frame at float precision, sent as `ODOMETRY` (frame LOCAL_NED, child
/// BODY_FRD) after `HIL_STATE_QUATERNION` when the plant is asked to: degE7 latitude and longitude
/// quantise the position to ±5.6 mm, which is a quarter of the paper's 2 cm state noise and the size of
/// the steady hover error of the truth-fed runs. Position m, velocity m/s, rates rad/s (f32: ≤ 6e-8
/// relative); the covariances are "unknown" (NaN first element).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalTruth {
    pub time_us: u64,
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    pub q_ned_frd: UnitQuaternion<f64>,
    pub rate_frd_radps: Vector3<f64>,
}

impl LocalTruth {
    /// `truth` with its position, velocity, attitude and rates replaced by these (same sample time).
    #[must_use]
    pub fn refine(&self, truth: &TruthSample) -> TruthSample {
        TruthSample {
            pos_ned_m: self.pos_ned_m,
            vel_ned_mps: self.vel_ned_mps,
            q_ned_frd: self.q_ned_frd,
            rate_frd_radps: self.rate_frd_radps,
            ..*truth
        }
    }
}

/// [`TruthSample`] (position in the plant's NED about its home) -> `ODOMETRY`.
#[must_use]
pub fn encode_odometry(truth: &TruthSample) -> ODOMETRY_DATA {
    let q = truth.q_ned_frd.quaternion();
    let mut unknown = [0.0_f32; 21];
    unknown[0] = f32::NAN;
    ODOMETRY_DATA {
        time_usec: truth.time_us,
        x: truth.pos_ned_m.x as f32,
        y: truth.pos_ned_m.y as f32,
        z: truth.pos_ned_m.z as f32,
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        vx: truth.vel_ned_mps.x as f32,
        vy: truth.vel_ned_mps.y as f32,
        vz: truth.vel_ned_mps.z as f32,
        rollspeed: truth.rate_frd_radps.x as f32,
        pitchspeed: truth.rate_frd_radps.y as f32,
        yawspeed: truth.rate_frd_radps.z as f32,
        pose_covariance: unknown,
        velocity_covariance: unknown,
        frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        child_frame_id: MavFrame::MAV_FRAME_BODY_FRD,
        ..Default::default()
    }
}

/// `ODOMETRY` -> [`LocalTruth`], or `None` unless its frames are LOCAL_NED / BODY_FRD (the plant's truth;
/// anything else is some other source's odometry).
#[must_use]
pub fn decode_odometry(msg: &ODOMETRY_DATA) -> Option<LocalTruth> {
    if msg.frame_id != MavFrame::MAV_FRAME_LOCAL_NED || msg.child_frame_id != MavFrame::MAV_FRAME_BODY_FRD {
        return None;
    }
    let [w, x, y, z] = msg.q.map(f64::from);
    Some(LocalTruth {
        time_us: msg.time_usec,
        pos_ned_m: vec3_f64(msg.x, msg.y, msg.z),
        vel_ned_mps: vec3_f64(msg.vx, msg.vy, msg.vz),
        q_ned_frd: UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z)),
        rate_frd_radps: vec3_f64(msg.rollspeed, msg.pitchspeed, msg.yawspeed),
    })
}

// ---------------------------------------------------------------------------------------------------------
// HIL_ACTUATOR_CONTROLS
// ---------------------------------------------------------------------------------------------------------

/// The autopilot's answer to one sensor sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorCommand {
    /// The `time_usec` of the `HIL_SENSOR` this answers (µs, the plant's clock).
    pub time_us: u64,
    /// Motor commands of the paper's rotors 1..4 (µs, 1000-2000).
    pub pwm_us: [f64; 4],
    /// `MAV_MODE_FLAG_SAFETY_ARMED`.
    pub armed: bool,
    /// `MAV_MODE_FLAG_TEST_ENABLED`: a motor test drives the outputs of the disarmed vehicle.
    pub motor_test: bool,
}

impl ActuatorCommand {
    /// Whether the motors run on `pwm_us`: armed, or a motor test (see the module docs).
    #[must_use]
    pub fn motors_running(&self) -> bool {
        self.armed || self.motor_test
    }

    /// What the motors get: `pwm_us` while they run, 1000 µs each otherwise.
    #[must_use]
    pub fn effective_pwm_us(&self) -> [f64; 4] {
        if self.motors_running() { self.pwm_us } else { [PWM_MIN_US; 4] }
    }
}

/// [`ActuatorCommand`] -> `HIL_ACTUATOR_CONTROLS`: `controls[0..4]` from the PWM (see [`pwm_us_to_control`]),
/// the rest 0; `mode` = SAFETY_ARMED when armed, TEST_ENABLED during a motor test, else empty; `flags` =
/// LOCKSTEP.
#[must_use]
pub fn encode_actuator_controls(cmd: &ActuatorCommand) -> HIL_ACTUATOR_CONTROLS_DATA {
    let mut controls = [0.0_f32; 16];
    for (control, pwm_us) in controls.iter_mut().zip(cmd.pwm_us) {
        *control = pwm_us_to_control(pwm_us);
    }
    HIL_ACTUATOR_CONTROLS_DATA {
        time_usec: cmd.time_us,
        flags: HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP,
        controls,
        mode: (if cmd.armed { MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED } else { MavModeFlag::empty() })
            | if cmd.motor_test { MavModeFlag::MAV_MODE_FLAG_TEST_ENABLED } else { MavModeFlag::empty() },
    }
}

/// `HIL_ACTUATOR_CONTROLS` -> [`ActuatorCommand`] (see [`control_to_pwm_us`]).
#[must_use]
pub fn decode_actuator_controls(msg: &HIL_ACTUATOR_CONTROLS_DATA) -> ActuatorCommand {
    ActuatorCommand {
        time_us: msg.time_usec,
        pwm_us: [0, 1, 2, 3].map(|i| control_to_pwm_us(msg.controls[i])),
        armed: msg.mode.bits() & MODE_FLAG_SAFETY_ARMED != 0,
        motor_test: msg.mode.contains(MavModeFlag::MAV_MODE_FLAG_TEST_ENABLED),
    }
}

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

// ---------------------------------------------------------------------------------------------------------
// Dispatch and framing
// ---------------------------------------------------------------------------------------------------------

/// The plant's answer to a command the autopilot forwarded on the plant link (`COMMAND_ACK`): which
/// command (its MAVLink id, e.g. 420 for MAV_CMD_INJECT_FAILURE) and the result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantCommandAck {
    pub command_id: u32,
    pub result: MavResult,
}

/// The COMMAND_LONG that forwards a failure injection to the plant (see the module docs): unit, type and
/// instance as MAV_CMD_INJECT_FAILURE's param1..3, addressed to whoever is at the other end of the link.
#[must_use]
pub fn encode_inject_failure([unit, failure_type, instance]: [f32; 3]) -> COMMAND_LONG_DATA {
    COMMAND_LONG_DATA {
        param1: unit,
        param2: failure_type,
        param3: instance,
        command: MavCmd::MAV_CMD_INJECT_FAILURE,
        target_system: 0,
        target_component: 0,
        ..Default::default()
    }
}

/// A decoded plant-protocol message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HilInput {
    Sensor(HilSensorFields),
    Gps(GpsSample),
    Truth(TruthSample),
    /// Precise truth, refining the `Truth` of the same datagram.
    LocalTruth(LocalTruth),
    Actuators(ActuatorCommand),
    Battery(BatterySample),
    /// The board's radio receiver.
    Rc(RcFrame),
    /// The plant's answer to a forwarded command.
    CommandAck(PlantCommandAck),
}

/// The plant-protocol content of `msg` (truth positions about `home`), or `None` for any other message.
#[must_use]
pub fn decode_hil_message(msg: &MavMessage, home: &GeoOrigin) -> Option<HilInput> {
    match msg {
        MavMessage::HIL_SENSOR(m) => Some(HilInput::Sensor(decode_hil_sensor(m))),
        MavMessage::HIL_GPS(m) => Some(HilInput::Gps(decode_hil_gps(m))),
        MavMessage::HIL_STATE_QUATERNION(m) => Some(HilInput::Truth(decode_hil_state_quaternion(m, home))),
        MavMessage::ODOMETRY(m) => decode_odometry(m).map(HilInput::LocalTruth),
        MavMessage::HIL_ACTUATOR_CONTROLS(m) => Some(HilInput::Actuators(decode_actuator_controls(m))),
        MavMessage::BATTERY_STATUS(m) => Some(HilInput::Battery(decode_battery_status(m))),
        MavMessage::RC_CHANNELS(m) => Some(HilInput::Rc(decode_rc_channels(m))),
        MavMessage::COMMAND_ACK(m) => {
            Some(HilInput::CommandAck(PlantCommandAck { command_id: m.command as u32, result: m.result }))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::MavHeader;
    use proptest::prelude::*;

    const HOME: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };

    fn header() -> MavHeader {
        MavHeader { system_id: 1, component_id: 1, sequence: 7 }
    }

    /// Half an f32 ulp of `x` plus a denormal floor: the error bound of one f64 -> f32 rounding.
    fn f32_tol(x: f64) -> f64 {
        x.abs() * f64::from(f32::EPSILON) * 0.5 + 1e-30
    }

    fn vec_close_f32(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        a.iter().zip(b.iter()).all(|(x, y)| (x - y).abs() <= f32_tol(*x))
    }

    fn sensor_fields(v: [f64; 12], t: u64, mag: bool, baro: bool) -> HilSensorFields {
        HilSensorFields {
            time_us: t,
            accel_frd_mps2: Vector3::new(v[0], v[1], v[2]),
            gyro_frd_radps: Vector3::new(v[3], v[4], v[5]),
            mag_frd_gauss: mag.then(|| Vector3::new(v[6], v[7], v[8])),
            baro: baro.then_some(HilBaroFields { pressure_hpa: v[9], pressure_alt_m: v[10], temperature_degc: v[11] }),
        }
    }

    fn gps_sample(t: u64, lat: f64, lon: f64, alt: f64, vel: [f64; 3], eph: f64) -> GpsSample {
        GpsSample {
            time_us: t,
            lat_deg: lat,
            lon_deg: lon,
            alt_amsl_m: alt,
            vel_ned_mps: Vector3::from(vel),
            fix_type: 3,
            satellites: 12,
            eph_m: eph,
            epv_m: eph * 1.5,
        }
    }

    #[test]
    fn odometry_of_another_frame_is_not_the_plants_truth() {
        let truth = TruthSample {
            time_us: 1,
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: UnitQuaternion::identity(),
            rate_frd_radps: Vector3::zeros(),
            specific_force_frd_mps2: Vector3::zeros(),
        };
        let mut msg = encode_odometry(&truth);
        assert!(decode_odometry(&msg).is_some());
        msg.frame_id = MavFrame::MAV_FRAME_LOCAL_FRD;
        assert_eq!(decode_odometry(&msg), None);
    }

    proptest! {
        #[test]
        fn rc_channels_round_trip_exactly(
            channels in prop::array::uniform18(any::<u16>()), count in 0_u8..=18, rssi in any::<u8>(),
        ) {
            let frame = RcFrame { channels_us: channels, count, rssi };
            let bytes = encode_frame_v2(header(), &MavMessage::RC_CHANNELS(encode_rc_channels(&frame, 1234)));
            let decoded = FrameDecoder::new().decode_datagram(&bytes);
            prop_assert_eq!(decoded.len(), 1);
            prop_assert_eq!(decode_hil_message(&decoded[0].message, &HOME), Some(HilInput::Rc(frame)));
        }

        #[test]
        fn hil_sensor_round_trips_within_f32(
            v in prop::array::uniform12(-2000.0_f64..2000.0), t in any::<u64>(), mag in any::<bool>(),
            baro in any::<bool>(),
        ) {
            let fields = sensor_fields(v, t, mag, baro);
            let frame = encode_frame_v2(header(), &MavMessage::HIL_SENSOR(encode_hil_sensor(&fields)));
            let decoded = FrameDecoder::new().decode_datagram(&frame);
            prop_assert_eq!(decoded.len(), 1);
            let MavMessage::HIL_SENSOR(msg) = &decoded[0].message else { panic!("not HIL_SENSOR") };
            let back = decode_hil_sensor(msg);
            prop_assert_eq!(back.time_us, t);
            prop_assert!(vec_close_f32(&fields.accel_frd_mps2, &back.accel_frd_mps2));
            prop_assert!(vec_close_f32(&fields.gyro_frd_radps, &back.gyro_frd_radps));
            prop_assert_eq!(back.mag_frd_gauss.is_some(), mag);
            if let (Some(a), Some(b)) = (fields.mag_frd_gauss, back.mag_frd_gauss) {
                prop_assert!(vec_close_f32(&a, &b));
            }
            prop_assert_eq!(back.baro.is_some(), baro);
            if let (Some(a), Some(b)) = (fields.baro, back.baro) {
                prop_assert!((a.pressure_hpa - b.pressure_hpa).abs() <= f32_tol(a.pressure_hpa));
                prop_assert!((a.pressure_alt_m - b.pressure_alt_m).abs() <= f32_tol(a.pressure_alt_m));
                prop_assert!((a.temperature_degc - b.temperature_degc).abs() <= f32_tol(a.temperature_degc));
            }
            let samples = SensorSamples::from(&back);
            prop_assert_eq!(samples.imu.time_us, t);
            prop_assert_eq!(samples.mag.is_some(), mag);
            prop_assert_eq!(samples.baro.is_some(), baro);
        }

        #[test]
        fn hil_gps_round_trips_within_stated_precision(
            lat in -89.9_f64..89.9, lon in -179.9_f64..179.9, alt in -400.0_f64..9000.0,
            vel in prop::array::uniform3(-300.0_f64..300.0), eph in 0.0_f64..400.0, t in any::<u64>(),
        ) {
            let gps = gps_sample(t, lat, lon, alt, vel, eph);
            let msg = encode_hil_gps(&gps);
            let frame = encode_frame_v2(header(), &MavMessage::HIL_GPS(msg));
            let decoded = FrameDecoder::new().decode_datagram(&frame);
            let MavMessage::HIL_GPS(msg) = &decoded[0].message else { panic!("not HIL_GPS") };
            let back = decode_hil_gps(msg);
            prop_assert_eq!(back.time_us, t);
            prop_assert!((back.lat_deg - lat).abs() <= 0.5e-7 + 1e-12);
            prop_assert!((back.lon_deg - lon).abs() <= 0.5e-7 + 1e-12);
            prop_assert!((back.alt_amsl_m - alt).abs() <= 0.5e-3 + 1e-9);
            prop_assert!((back.vel_ned_mps - gps.vel_ned_mps).amax() <= 0.005 + 1e-9);
            prop_assert!((back.eph_m - eph).abs() <= 0.005 + 1e-9);
            prop_assert!((back.epv_m - gps.epv_m).abs() <= 0.005 + 1e-9);
            prop_assert_eq!((back.fix_type, back.satellites), (3, 12));
            prop_assert!(msg.cog < 36_000);
            let speed = vel[0].hypot(vel[1]);
            prop_assert!((f64::from(msg.vel) * 0.01 - speed).abs() <= 0.005 + 1e-9);
        }

        #[test]
        fn hil_state_quaternion_round_trips_within_stated_precision(
            pos in prop::array::uniform3(-3000.0_f64..3000.0), vel in prop::array::uniform3(-300.0_f64..300.0),
            axis_angle in prop::array::uniform3(-3.0_f64..3.0), rate in prop::array::uniform3(-30.0_f64..30.0),
            acc in prop::array::uniform3(-300.0_f64..300.0), t in any::<u64>(),
        ) {
            let truth = TruthSample {
                time_us: t,
                pos_ned_m: Vector3::from(pos),
                vel_ned_mps: Vector3::from(vel),
                q_ned_frd: UnitQuaternion::from_scaled_axis(Vector3::from(axis_angle)),
                rate_frd_radps: Vector3::from(rate),
                specific_force_frd_mps2: Vector3::from(acc),
            };
            let msg = encode_hil_state_quaternion(&truth, &HOME, 12.34);
            let frame = encode_frame_v2(header(), &MavMessage::HIL_STATE_QUATERNION(msg));
            let decoded = FrameDecoder::new().decode_datagram(&frame);
            let MavMessage::HIL_STATE_QUATERNION(msg) = &decoded[0].message else { panic!("not HIL_STATE_QUATERNION") };
            let back = decode_hil_state_quaternion(msg, &HOME);
            prop_assert_eq!(back.time_us, t);
            // degE7 rounding: ≤ 5.6 mm north, ≤ 5.6 mm·cos φ east (+ f64 noise of the map); mm altitude.
            let dp = back.pos_ned_m - truth.pos_ned_m;
            prop_assert!(dp.x.abs() <= 5.6e-3 && dp.y.abs() <= 5.6e-3 && dp.z.abs() <= 0.5e-3 + 1e-9, "dp {:?}", dp);
            prop_assert!((back.vel_ned_mps - truth.vel_ned_mps).amax() <= 0.005 + 1e-9);
            prop_assert!(back.q_ned_frd.angle_to(&truth.q_ned_frd) <= 2.5e-7);
            prop_assert!(vec_close_f32(&truth.rate_frd_radps, &back.rate_frd_radps));
            prop_assert!((back.specific_force_frd_mps2 - truth.specific_force_frd_mps2).amax() <= 0.5e-3 * MPS2_PER_G + 1e-9);
            prop_assert_eq!((msg.ind_airspeed, msg.true_airspeed), (1234, 1234));
        }

        #[test]
        fn odometry_refines_truth_to_f32_precision(
            pos in prop::array::uniform3(-300.0_f64..300.0), vel in prop::array::uniform3(-30.0_f64..30.0),
            axis_angle in prop::array::uniform3(-3.0_f64..3.0), t in any::<u64>(),
        ) {
            let truth = TruthSample {
                time_us: t,
                pos_ned_m: Vector3::from(pos),
                vel_ned_mps: Vector3::from(vel),
                q_ned_frd: UnitQuaternion::from_scaled_axis(Vector3::from(axis_angle)),
                rate_frd_radps: Vector3::new(0.1, -0.2, 0.3),
                specific_force_frd_mps2: Vector3::new(0.0, 0.0, -9.8),
            };
            let frame = encode_frame_v2(header(), &MavMessage::ODOMETRY(encode_odometry(&truth)));
            let decoded = FrameDecoder::new().decode_datagram(&frame);
            let Some(HilInput::LocalTruth(local)) = decode_hil_message(&decoded[0].message, &HOME) else {
                panic!("not the plant's ODOMETRY")
            };
            let coarse = TruthSample { pos_ned_m: truth.pos_ned_m.add_scalar(0.005), ..truth };
            let back = local.refine(&coarse);
            prop_assert!(vec_close_f32(&truth.pos_ned_m, &back.pos_ned_m), "{:?}", back.pos_ned_m - truth.pos_ned_m);
            prop_assert!(vec_close_f32(&truth.vel_ned_mps, &back.vel_ned_mps));
            prop_assert!(back.q_ned_frd.angle_to(&truth.q_ned_frd) <= 2.5e-7);
            prop_assert_eq!(back.specific_force_frd_mps2, truth.specific_force_frd_mps2);
        }

        #[test]
        fn pwm_round_trips_within_f32(
            pwm in prop::array::uniform4(1000.0_f64..=2000.0), t in any::<u64>(), armed in any::<bool>(),
            motor_test in any::<bool>(),
        ) {
            let cmd = ActuatorCommand { time_us: t, pwm_us: pwm, armed, motor_test };
            let frame = encode_frame_v2(header(), &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)));
            let decoded = FrameDecoder::new().decode_datagram(&frame);
            let MavMessage::HIL_ACTUATOR_CONTROLS(msg) = &decoded[0].message else { panic!("not HIL_ACTUATOR_CONTROLS") };
            let back = decode_actuator_controls(msg);
            prop_assert_eq!((back.time_us, back.armed, back.motor_test), (t, armed, motor_test));
            for (a, b) in back.pwm_us.iter().zip(pwm) {
                prop_assert!((a - b).abs() <= 3e-5, "{} vs {}", a, b);
            }
        }


    }

    #[test]
    fn pwm_mapping_edge_cases() {
        assert_eq!(pwm_us_to_control(1000.0), 0.0);
        assert_eq!(pwm_us_to_control(2000.0), 1.0);
        assert_eq!(pwm_us_to_control(1500.0), 0.5);
        assert_eq!(pwm_us_to_control(999.0), 0.0);
        assert_eq!(pwm_us_to_control(-1e300), 0.0);
        assert_eq!(pwm_us_to_control(2500.0), 1.0);
        assert_eq!(pwm_us_to_control(f64::NAN), 0.0);
        assert_eq!(pwm_us_to_control(f64::INFINITY), 0.0);
        assert_eq!(pwm_us_to_control(f64::NEG_INFINITY), 0.0);
        assert_eq!(control_to_pwm_us(0.0), 1000.0);
        assert_eq!(control_to_pwm_us(1.0), 2000.0);
        assert_eq!(control_to_pwm_us(-1.0), 1000.0);
        assert_eq!(control_to_pwm_us(1.5), 2000.0);
        assert_eq!(control_to_pwm_us(f32::NAN), 1000.0);
        assert_eq!(control_to_pwm_us(f32::INFINITY), 1000.0);
        let cmd =
            ActuatorCommand { time_us: 5, pwm_us: [f64::NAN, 3000.0, 500.0, 1234.5], armed: true, motor_test: false };
        let msg = encode_actuator_controls(&cmd);
        assert_eq!(&msg.controls[..4], &[0.0, 1.0, 0.0, 0.2345]);
        assert!(msg.controls[4..].iter().all(|&c| c == 0.0));
        assert_eq!(msg.mode.bits(), MODE_FLAG_SAFETY_ARMED);
        let back = decode_actuator_controls(&msg);
        assert_eq!(back.pwm_us[..3], [1000.0, 2000.0, 1000.0]);
        assert!((back.pwm_us[3] - 1234.5).abs() < 3e-5);
        let disarmed = decode_actuator_controls(&encode_actuator_controls(&ActuatorCommand { armed: false, ..cmd }));
        assert!(!disarmed.armed);
        assert_eq!(encode_actuator_controls(&disarmed).mode.bits(), 0);
        assert_eq!(disarmed.effective_pwm_us(), [1000.0; 4]);
        // A motor test on the disarmed vehicle: its own flag, and the plant runs the motors on the PWM.
        let test = ActuatorCommand { armed: false, motor_test: true, pwm_us: [1000.0, 1000.0, 1200.0, 1000.0], ..cmd };
        let msg = encode_actuator_controls(&test);
        assert_eq!(msg.mode, MavModeFlag::MAV_MODE_FLAG_TEST_ENABLED);
        let back = decode_actuator_controls(&msg);
        assert!(back.motor_test && !back.armed && back.motors_running());
        assert!((back.effective_pwm_us()[2] - 1200.0).abs() < 3e-5);
    }

    #[test]
    fn integer_fields_saturate_and_unknowns_decode_as_infinite() {
        assert_eq!(mps_to_cmps_i16(1e9), i16::MAX);
        assert_eq!(mps_to_cmps_i16(-1e9), i16::MIN);
        assert_eq!(mps_to_cmps_i16(f64::NAN), 0);
        assert_eq!(mps2_to_mg(1e9), i16::MAX);
        assert_eq!(to_centi_u16(1e9), UNKNOWN_U16 - 1);
        assert_eq!(to_centi_u16(f64::NAN), UNKNOWN_U16);
        assert_eq!(to_centi_u16(-1.0), UNKNOWN_U16);
        assert_eq!(centi_u16_to(UNKNOWN_U16), f64::INFINITY);
        assert_eq!(deg_to_dege7(47.397_742_3), 473_977_423);
        assert_eq!(course_deg(&Vector3::new(0.0, -1.0, 0.0)), 270.0);
        let msg = encode_hil_gps(&gps_sample(1, 0.0, 0.0, 0.0, [f64::NAN, 0.0, 0.0], f64::NAN));
        assert_eq!((msg.cog, msg.eph), (UNKNOWN_U16, UNKNOWN_U16));
        assert_eq!(decode_hil_gps(&msg).eph_m, f64::INFINITY);
    }

    #[test]
    fn hil_sensor_encodes_pressure_units_and_flags() {
        let fields =
            sensor_fields([0.0, 0.0, -9.80665, 0.1, 0.2, 0.3, 0.2, 0.0, 0.4, 955.0, 488.0, 11.8], 2000, true, true);
        let msg = encode_hil_sensor(&fields);
        assert_eq!(msg.fields_updated.bits(), 0x1FFF & !0x400); // all but diff_pressure
        assert_eq!((msg.abs_pressure, msg.pressure_alt, msg.temperature), (955.0, 488.0, 11.8));
        let imu_only = encode_hil_sensor(&sensor_fields([0.0; 12], 0, false, false));
        assert_eq!(imu_only.fields_updated.bits(), 0x3F);
    }

    #[test]
    fn given_a_pack_reading_when_battery_status_round_trips_then_within_the_wire_resolution() {
        use crate::core::battery::BatterySample;
        for cells in [0_u8, 6, 12, 14] {
            let b = BatterySample {
                voltage_v: 22.2,
                current_a: Some(31.234),
                remaining: Some(0.4567),
                consumed_mah: Some(5432.4),
                consumed_j: Some(123_456.0),
                cells,
            };
            let msg = MavMessage::BATTERY_STATUS(encode_battery_status(
                &b,
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK,
            ));
            let frame = encode_frame_v2(header(), &msg);
            let decoded = FrameDecoder::new().push(&frame);
            let Some(HilInput::Battery(got)) = decode_hil_message(&decoded[0].message, &HOME) else {
                panic!("not a battery")
            };
            assert_eq!(got.cells, cells);
            assert!(
                (got.voltage_v - 22.2).abs() <= 0.0005 * f64::from(cells.max(1)),
                "{cells} cells: {}",
                got.voltage_v
            );
            assert_eq!(got.current_a, Some(31.23));
            assert_eq!(got.remaining, Some(0.45), "truncated to whole percent");
            assert_eq!(got.consumed_mah, Some(5432.0));
            assert_eq!(got.consumed_j, Some(123_500.0));
        }
        let unknown = BatterySample { voltage_v: 12.0, ..BatterySample::default() };
        let got = decode_battery_status(&encode_battery_status(
            &unknown,
            MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED,
        ));
        assert_eq!((got.current_a, got.remaining, got.consumed_mah, got.consumed_j), (None, None, None, None));
    }
}
