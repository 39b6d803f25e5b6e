//! The estimator's inputs: one sample type per sensor (IMU, magnetometer, barometer, GPS) and the
//! plant's ground truth, with the limits and checks that sanitise them before they reach the filter
//! (non-finite or absurd values are refused and counted, see the module's "Sanitising").

use nalgebra::{UnitQuaternion, Vector3};

use super::eskf;

/// Largest plausible specific force (m/s²): 16 g.
pub const MAX_ACCEL_MPS2: f64 = 16.0 * eskf::GRAVITY_MPS2;
/// Largest plausible body rate (rad/s).
pub const MAX_GYRO_RADPS: f64 = 35.0;
/// Largest plausible magnetic field (gauss); the earth's is below 0.7.
pub const MAX_FIELD_GAUSS: f64 = 4.0;
/// Plausible pressure-altitude range (m AMSL).
pub const BARO_ALT_RANGE_M: (f64, f64) = (-1_000.0, 30_000.0);
/// Largest plausible GPS speed (m/s).
pub const MAX_GPS_SPEED_MPS: f64 = 150.0;

/// One IMU sample (HIL_SENSOR), at the control rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Sample time (µs, the plant's clock).
    pub time_us: u64,
    /// Specific force (m/s², FRD): `(0, 0, -g)` at rest.
    pub accel_frd_mps2: Vector3<f64>,
    /// Body rates (rad/s, FRD).
    pub gyro_frd_radps: Vector3<f64>,
}

/// One magnetometer sample (HIL_SENSOR), taken at the time of the latest IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagSample {
    /// Magnetic field (gauss, FRD).
    pub field_frd_gauss: Vector3<f64>,
}

/// One barometer sample (HIL_SENSOR), taken at the time of the latest IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaroSample {
    /// Pressure altitude (m AMSL).
    pub pressure_alt_m: f64,
}

/// One GPS fix (HIL_GPS).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsSample {
    /// Time the fix was valid (µs, the plant's clock); it may arrive later (latency).
    pub time_us: u64,
    /// Latitude (deg, WGS-84).
    pub lat_deg: f64,
    /// Longitude (deg, WGS-84).
    pub lon_deg: f64,
    /// Altitude (m AMSL).
    pub alt_amsl_m: f64,
    /// Velocity (m/s, NED).
    pub vel_ned_mps: Vector3<f64>,
    /// 0-1 no fix, 2 2D, 3 3D, higher: 3D with corrections.
    pub fix_type: u8,
    /// Satellites used.
    pub satellites: u8,
    /// Horizontal position accuracy, one standard deviation (m).
    pub eph_m: f64,
    /// Vertical position accuracy, one standard deviation (m).
    pub epv_m: f64,
}

/// Ground truth from the plant (HIL_STATE_QUATERNION), for the `Truth` source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// Time (µs, the plant's clock).
    pub time_us: u64,
    /// Position (m, NED about the plant's home).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity (m/s, NED).
    pub vel_ned_mps: Vector3<f64>,
    /// Attitude, body FRD -> NED.
    pub q_ned_frd: UnitQuaternion<f64>,
    /// Body rates (rad/s, FRD).
    pub rate_frd_radps: Vector3<f64>,
    /// Specific force (m/s², FRD).
    pub specific_force_frd_mps2: Vector3<f64>,
}

fn finite3(v: &Vector3<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

pub(super) fn imu_plausible(imu: &ImuSample) -> bool {
    finite3(&imu.accel_frd_mps2)
        && finite3(&imu.gyro_frd_radps)
        && imu.accel_frd_mps2.norm() <= MAX_ACCEL_MPS2
        && imu.gyro_frd_radps.norm() <= MAX_GYRO_RADPS
}

/// The largest change of the specific force between two IMU samples a flying body shows (m/s², norm):
/// 8 g, beyond a crash's. Garbage uniform over ±16 g per axis jumps further most of the time.
pub const MAX_ACCEL_STEP_MPS2: f64 = 8.0 * eskf::GRAVITY_MPS2;
/// The largest change of the body rates between two IMU samples (rad/s, norm): half the gyro's range.
pub const MAX_GYRO_STEP_RADPS: f64 = 0.5 * MAX_GYRO_RADPS;

/// Whether `imu` follows `last` as a body's readings can: neither the specific force nor the rates jumped
/// further than [`MAX_ACCEL_STEP_MPS2`] and [`MAX_GYRO_STEP_RADPS`].
pub(super) fn imu_step_plausible(last: &ImuSample, imu: &ImuSample) -> bool {
    (imu.accel_frd_mps2 - last.accel_frd_mps2).norm() <= MAX_ACCEL_STEP_MPS2
        && (imu.gyro_frd_radps - last.gyro_frd_radps).norm() <= MAX_GYRO_STEP_RADPS
}

pub(super) fn mag_plausible(mag: &MagSample) -> bool {
    let norm = mag.field_frd_gauss.norm();
    finite3(&mag.field_frd_gauss) && norm > 1e-3 && norm <= MAX_FIELD_GAUSS
}

pub(super) fn baro_plausible(baro: &BaroSample) -> bool {
    (BARO_ALT_RANGE_M.0..=BARO_ALT_RANGE_M.1).contains(&baro.pressure_alt_m)
}

pub(super) fn gps_plausible(gps: &GpsSample) -> bool {
    gps.fix_type >= 3
        && (-90.0..=90.0).contains(&gps.lat_deg)
        && (-180.0..=180.0).contains(&gps.lon_deg)
        && (BARO_ALT_RANGE_M.0..=BARO_ALT_RANGE_M.1).contains(&gps.alt_amsl_m)
        && finite3(&gps.vel_ned_mps)
        && gps.vel_ned_mps.norm() <= MAX_GPS_SPEED_MPS
        && gps.eph_m >= 0.0
        && gps.epv_m >= 0.0
        && gps.eph_m.is_finite()
        && gps.epv_m.is_finite()
}

pub(super) fn truth_plausible(truth: &TruthSample) -> bool {
    finite3(&truth.pos_ned_m)
        && finite3(&truth.vel_ned_mps)
        && truth.q_ned_frd.coords.iter().all(|x| x.is_finite())
        && finite3(&truth.rate_frd_radps)
        && finite3(&truth.specific_force_frd_mps2)
}
