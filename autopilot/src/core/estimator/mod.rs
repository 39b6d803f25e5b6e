//! State estimation. In: IMU samples (specific force m/s², rates rad/s, FRD, with `time_us`) at the control
//! rate (250-1000 Hz), magnetometer (gauss, FRD) with the IMU or slower, barometric altitude (m AMSL,
//! ~50-500 Hz), GPS (WGS-84 deg, m AMSL, m/s NED, stamped with the time the fix was valid, 5-10 Hz,
//! possibly ~100 ms late), or, for the paper's truth-fed runs, the plant's ground truth. Out: an
//! [`EstimatorState`] after every sample: NED position (m) about a latched [`GeoOrigin`], NED velocity
//! (m/s), `q_ned_frd` and ZYX Euler angles (rad), bias-corrected rates (rad/s) and specific force (m/s²),
//! the bias estimates, and health/validity flags for the arming checks. Time is only ever the `time_us`
//! (µs) of the samples; nothing here reads a clock or draws a random number.
//!
//! # Design: one 16-state error-state Kalman filter (`eskf`), and why
//!
//! State: position and velocity (NED), attitude, accelerometer bias, gyro bias (FRD) and a barometer
//! offset; the attitude error is a 3-vector in the NED frame. The IMU drives the prediction (strapdown
//! integration), GPS position and velocity, barometric height and magnetometer heading correct it.
//!
//! Why one filter rather than an attitude complementary filter plus a linear position filter: the
//! accelerometer's horizontal bias and the tilt are indistinguishable at a constant heading (a bias `b`
//! looks exactly like a tilt `b/g`), and what separates them is yaw motion, through the cross-covariance
//! between attitude, velocity and bias. A Mahony-type filter levels itself on the biased accelerometer
//! with its own gain, so a downstream position filter never sees the bias and cannot estimate it; the
//! joint filter does (the accelerometer-bias test below needs it). The cost is a 16x16 covariance update
//! per IMU sample, a few tens of microseconds. It is PX4 EKF2's structure, reduced to the sensors we have.
//!
//! - **Alignment** (`fusion`): for `align_time_s` after the first IMU sample the vehicle is assumed still;
//!   roll and pitch come from the mean specific force, yaw from the mean tilt-compensated field. Until then
//!   the state is level and zero and no flag is set.
//! - **Magnetometer**: heading only (the tilt-compensated field's direction plus the configured declination),
//!   so magnetic disturbances cannot tilt the estimate. Its observation row models how a tilt error leaks
//!   into the levelled heading (`tan(dip)` times the tilt error about the field's horizontal direction), with
//!   the dip measured at heading alignment; without that term a 0.01 rad tilt error would cost about
//!   0.02 rad of heading at a 63 degree dip.
//! - **GPS**: the origin is latched at the first fix passing the quality checks (3D, satellites, eph, epv);
//!   positions map to NED by the flat-earth map of `geo` (WGS-84 radii). Latency: the fix carries the time
//!   it was valid; its innovation is taken against the state at that time from a 0.5 s history of
//!   positions and velocities (`history`), and the correction is applied to the current state (and to the
//!   history, so the next delayed fix sees it): the error state is taken as constant over the delay, sound
//!   for delays far below the filter's error time constants (seconds). `latency_compensation = false`
//!   fuses against the current state instead, for comparison. When aiding (re)starts after an outage the
//!   position (horizontal; the height too at the first fix) and velocity are reset to the fix.
//! - **Barometer**: `pressure_alt_m = -pos_d + offset` with the offset a slow random-walk state, so GPS
//!   height calibrates it; it is (re)initialised to agree with the current height at the first sample and
//!   after an outage.
//! - **No aiding**: before the first fix the vehicle is assumed on the ground and its horizontal position is
//!   held (pseudo-measurement, `align_pos_noise_m`), which keeps the attitude and biases observable; after a
//!   GPS loss it dead-reckons, and after `no_aid_timeout_s` a loose hold (`no_aid_pos_noise_m`) bounds it.
//! - **Gating**: every measurement is gated on its normalised innovation (`innovation_gate_sigma`).
//! - **Health** ([`EstimatorFlags`]): a sensor is ok when fused within its timeout on the sample clock (IMU
//!   0.1 s, baro 0.5 s, GPS 1 s, mag 0.5 s). Valid attitude/velocity/position need the sensor and a
//!   standard deviation under a bound; `converged` needs, in addition, GPS aiding for `converge_gps_s`, the
//!   attitude settled for `converge_settle_s` (tilt and yaw standard deviations small and the low-passed
//!   normalised GPS velocity innovation, which a tilt error drives first, small) and tighter position and
//!   velocity bounds. Flags are recomputed from scratch at every sample, so they drop as soon as a
//!   condition fails.
//! - **Sanitising** (here, with the limits and checks in `samples`): non-finite or absurd samples
//!   (|accel| > 16 g, |gyro| > 35 rad/s, a field beyond 4 G, GPS without a 3D fix, out-of-range
//!   coordinates, IMU time not increasing, GPS older than the history) are refused before they touch the
//!   filter and counted in [`Estimator::rejected_samples`].

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

pub mod eskf;
mod fusion;
pub mod geo;
mod health;
mod history;
mod samples;

#[cfg(test)]
mod fault_tests;
#[cfg(test)]
mod sim;
#[cfg(test)]
mod tests;

pub use geo::GeoOrigin;
pub use health::{
    EstimatorEvent, EventSeverity, HeightSource, MAX_PENDING_EVENTS, STUCK_MIN_REPEATS, Source, SourceFault,
    SourceHealth,
};
pub use samples::{
    BARO_ALT_RANGE_M, BaroSample, GpsSample, ImuSample, MAX_ACCEL_MPS2, MAX_ACCEL_STEP_MPS2, MAX_FIELD_GAUSS,
    MAX_GPS_SPEED_MPS, MAX_GYRO_RADPS, MAX_GYRO_STEP_RADPS, MagSample, TruthSample,
};

use fusion::Fusion;
use samples::{baro_plausible, gps_plausible, imu_plausible, imu_step_plausible, mag_plausible, truth_plausible};

/// Health and validity, for the arming checks and failsafes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EstimatorFlags {
    /// Aligned, IMU fresh, tilt and yaw uncertainties within bounds.
    pub attitude_valid: bool,
    /// Attitude valid, GPS aiding, velocity uncertainty within bound.
    pub velocity_valid: bool,
    /// Velocity valid, origin set, position uncertainty within bound.
    pub position_valid: bool,
    /// Position valid, GPS aiding and attitude settled for their hold times, tighter bounds met.
    pub converged: bool,
    /// A GPS fix was fused within `gps_timeout_s` and the GPS is not faulted.
    pub gps_ok: bool,
    /// A barometer sample was fused within `baro_timeout_s` and the barometer is not faulted.
    pub baro_ok: bool,
    /// A magnetometer heading was fused within `mag_timeout_s` and the magnetometer is not faulted.
    pub mag_ok: bool,
    /// Why each source is not fused, if it is not (see the module's "Sensor faults").
    pub health: SourceHealth,
    /// What aids the height.
    pub height_source: HeightSource,
}

/// The estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorState {
    /// Time of the latest sample (µs).
    pub time_us: u64,
    /// Position (m, NED about `origin`; about the alignment point before the first fix).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity (m/s, NED).
    pub vel_ned_mps: Vector3<f64>,
    /// Attitude, body FRD -> NED.
    pub q_ned_frd: UnitQuaternion<f64>,
    /// ZYX Euler angles `(phi, theta, psi)` (rad) of `q_ned_frd`.
    pub euler_rad: Vector3<f64>,
    /// Latest gyro sample minus the estimated bias (rad/s, FRD).
    pub rate_frd_radps: Vector3<f64>,
    /// Latest accelerometer sample minus the estimated bias (m/s², FRD).
    pub specific_force_frd_mps2: Vector3<f64>,
    /// Estimated accelerometer bias (m/s², FRD).
    pub accel_bias_frd_mps2: Vector3<f64>,
    /// Estimated gyro bias (rad/s, FRD).
    pub gyro_bias_frd_radps: Vector3<f64>,
    /// The geodetic point of NED `(0, 0, 0)`, once latched.
    pub origin: Option<GeoOrigin>,
    pub flags: EstimatorFlags,
}

impl Default for EstimatorState {
    fn default() -> Self {
        Self {
            time_us: 0,
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: UnitQuaternion::identity(),
            euler_rad: Vector3::zeros(),
            rate_frd_radps: Vector3::zeros(),
            specific_force_frd_mps2: Vector3::zeros(),
            accel_bias_frd_mps2: Vector3::zeros(),
            gyro_bias_frd_radps: Vector3::zeros(),
            origin: None,
            flags: EstimatorFlags::default(),
        }
    }
}

/// Where the state comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorSource {
    /// The sensor-fusion filter (truth is ignored).
    #[default]
    Fused,
    /// The plant's ground truth, copied (sensors are ignored): the paper's truth-fed runs.
    Truth,
}

/// Settings. Noises are one standard deviation; times in seconds of the sample clock.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EstimatorConfig {
    pub source: EstimatorSource,
    /// Origin reported with the `Truth` source (the plant's home), if known.
    pub truth_origin: Option<GeoOrigin>,

    /// Accelerometer noise of one sample at the IMU rate (m/s²).
    pub accel_noise_mps2: f64,
    /// Gyro noise of one sample at the IMU rate (rad/s).
    pub gyro_noise_radps: f64,
    /// Accelerometer-bias random walk (m/s² per sqrt(s)).
    pub accel_bias_walk_mps2_per_sqrt_s: f64,
    /// Gyro-bias random walk (rad/s per sqrt(s)).
    pub gyro_bias_walk_radps_per_sqrt_s: f64,
    /// Barometer-offset random walk (m per sqrt(s)).
    pub baro_offset_walk_m_per_sqrt_s: f64,

    /// Initial uncertainties after alignment.
    pub init_pos_std_m: f64,
    pub init_vel_std_mps: f64,
    pub init_tilt_std_rad: f64,
    pub init_yaw_std_rad: f64,
    pub init_accel_bias_std_mps2: f64,
    pub init_gyro_bias_std_radps: f64,

    /// GPS horizontal position noise floor (m); the fix's `eph_m` is used when larger.
    pub gps_pos_noise_m: f64,
    /// GPS height noise floor (m); the fix's `epv_m` is used when larger.
    pub gps_hgt_noise_m: f64,
    /// GPS velocity noise (m/s).
    pub gps_vel_noise_mps: f64,
    /// Barometer noise (m).
    pub baro_noise_m: f64,
    /// Magnetometer heading noise (rad).
    pub mag_heading_noise_rad: f64,
    /// Magnetic declination, east of true north positive (deg). Default: the SITL plant's home (Zurich).
    pub mag_declination_deg: f64,
    /// Innovation gate (standard deviations).
    pub innovation_gate_sigma: f64,

    /// Latency of the GPS not reflected in its `time_us` (µs), subtracted from it.
    pub gps_delay_us: u64,
    /// Fuse GPS against the state of its time (true) or against the current state (false).
    pub latency_compensation: bool,
    /// GPS quality needed to fuse (and to latch the origin).
    pub gps_min_satellites: u8,
    pub gps_max_eph_m: f64,
    pub gps_max_epv_m: f64,

    /// Time the vehicle is assumed still for the initial attitude (s).
    pub align_time_s: f64,
    /// Horizontal position hold before the first fix (m).
    pub align_pos_noise_m: f64,
    /// Dead reckoning after a GPS loss before the loose position hold starts (s).
    pub no_aid_timeout_s: f64,
    /// Loose horizontal position hold without GPS (m).
    pub no_aid_pos_noise_m: f64,

    /// Sensor timeouts (s): a source silent this long is lost.
    pub imu_timeout_s: f64,
    pub baro_timeout_s: f64,
    pub gps_timeout_s: f64,
    pub mag_timeout_s: f64,
    /// A GPS or barometer repeating bit-identical samples this long (and at least [`STUCK_MIN_REPEATS`]
    /// times) while the IMU shows motion is stuck (s).
    pub stuck_time_s: f64,
    /// The same for the magnetometer (s): shorter, because every stuck heading fused while the vehicle
    /// turns teaches the filter a wrong gyro bias that outlives the detection.
    pub mag_stuck_time_s: f64,
    /// An IMU repeating bit-identical samples this long while the magnetometer or barometer shows motion
    /// is stuck (s).
    pub imu_stuck_time_s: f64,
    /// A GPS position or magnetometer heading refused by the innovation gate this long without a fused
    /// one is rejected (s).
    pub reject_time_s: f64,

    /// Validity bounds (one standard deviation).
    pub valid_tilt_std_rad: f64,
    pub valid_yaw_std_rad: f64,
    pub valid_vel_std_mps: f64,
    pub valid_pos_std_m: f64,

    /// Convergence: attitude settled (tilt, yaw std and mean normalised horizontal GPS velocity innovation
    /// below these) for `converge_settle_s`, GPS aiding for `converge_gps_s`, position and velocity std below.
    pub converge_tilt_std_rad: f64,
    pub converge_yaw_std_rad: f64,
    pub converge_vel_nis_max: f64,
    pub converge_settle_s: f64,
    pub converge_gps_s: f64,
    pub converge_pos_std_m: f64,
    pub converge_vel_std_mps: f64,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            source: EstimatorSource::Fused,
            truth_origin: None,
            accel_noise_mps2: 0.35,
            gyro_noise_radps: 0.015,
            accel_bias_walk_mps2_per_sqrt_s: 1.0e-3,
            gyro_bias_walk_radps_per_sqrt_s: 1.0e-4,
            baro_offset_walk_m_per_sqrt_s: 0.01,
            init_pos_std_m: 1.0,
            init_vel_std_mps: 0.5,
            init_tilt_std_rad: 0.03,
            init_yaw_std_rad: 0.1,
            init_accel_bias_std_mps2: 0.2,
            init_gyro_bias_std_radps: 0.02,
            gps_pos_noise_m: 0.5,
            gps_hgt_noise_m: 0.8,
            gps_vel_noise_mps: 0.1,
            baro_noise_m: 0.15,
            mag_heading_noise_rad: 0.05,
            mag_declination_deg: 3.3,
            innovation_gate_sigma: 5.0,
            gps_delay_us: 0,
            latency_compensation: true,
            gps_min_satellites: 6,
            gps_max_eph_m: 3.0,
            gps_max_epv_m: 5.0,
            align_time_s: 0.25,
            align_pos_noise_m: 0.5,
            no_aid_timeout_s: 5.0,
            no_aid_pos_noise_m: 10.0,
            imu_timeout_s: 0.1,
            baro_timeout_s: 0.5,
            gps_timeout_s: 0.5,
            mag_timeout_s: 0.5,
            stuck_time_s: 1.0,
            mag_stuck_time_s: 0.2,
            imu_stuck_time_s: 0.2,
            reject_time_s: 0.5,
            valid_tilt_std_rad: 0.1,
            valid_yaw_std_rad: 0.5,
            valid_vel_std_mps: 1.0,
            valid_pos_std_m: 3.0,
            converge_tilt_std_rad: 0.03,
            converge_yaw_std_rad: 0.05,
            converge_vel_nis_max: 3.0,
            converge_settle_s: 2.0,
            converge_gps_s: 3.0,
            converge_pos_std_m: 0.5,
            converge_vel_std_mps: 0.2,
        }
    }
}

/// A configuration value out of range.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "estimator config: {} = {} must be finite and positive", self.field, self.value)
    }
}

impl std::error::Error for ConfigError {}

impl EstimatorConfig {
    /// Checks that every noise, bound and time is finite and positive (the declination finite).
    ///
    /// # Errors
    /// The first offending field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = [
            ("accel_noise_mps2", self.accel_noise_mps2),
            ("gyro_noise_radps", self.gyro_noise_radps),
            ("accel_bias_walk_mps2_per_sqrt_s", self.accel_bias_walk_mps2_per_sqrt_s),
            ("gyro_bias_walk_radps_per_sqrt_s", self.gyro_bias_walk_radps_per_sqrt_s),
            ("baro_offset_walk_m_per_sqrt_s", self.baro_offset_walk_m_per_sqrt_s),
            ("init_pos_std_m", self.init_pos_std_m),
            ("init_vel_std_mps", self.init_vel_std_mps),
            ("init_tilt_std_rad", self.init_tilt_std_rad),
            ("init_yaw_std_rad", self.init_yaw_std_rad),
            ("init_accel_bias_std_mps2", self.init_accel_bias_std_mps2),
            ("init_gyro_bias_std_radps", self.init_gyro_bias_std_radps),
            ("gps_pos_noise_m", self.gps_pos_noise_m),
            ("gps_hgt_noise_m", self.gps_hgt_noise_m),
            ("gps_vel_noise_mps", self.gps_vel_noise_mps),
            ("baro_noise_m", self.baro_noise_m),
            ("mag_heading_noise_rad", self.mag_heading_noise_rad),
            ("innovation_gate_sigma", self.innovation_gate_sigma),
            ("gps_max_eph_m", self.gps_max_eph_m),
            ("gps_max_epv_m", self.gps_max_epv_m),
            ("align_time_s", self.align_time_s),
            ("align_pos_noise_m", self.align_pos_noise_m),
            ("no_aid_timeout_s", self.no_aid_timeout_s),
            ("no_aid_pos_noise_m", self.no_aid_pos_noise_m),
            ("imu_timeout_s", self.imu_timeout_s),
            ("baro_timeout_s", self.baro_timeout_s),
            ("gps_timeout_s", self.gps_timeout_s),
            ("mag_timeout_s", self.mag_timeout_s),
            ("stuck_time_s", self.stuck_time_s),
            ("mag_stuck_time_s", self.mag_stuck_time_s),
            ("imu_stuck_time_s", self.imu_stuck_time_s),
            ("reject_time_s", self.reject_time_s),
            ("valid_tilt_std_rad", self.valid_tilt_std_rad),
            ("valid_yaw_std_rad", self.valid_yaw_std_rad),
            ("valid_vel_std_mps", self.valid_vel_std_mps),
            ("valid_pos_std_m", self.valid_pos_std_m),
            ("converge_tilt_std_rad", self.converge_tilt_std_rad),
            ("converge_yaw_std_rad", self.converge_yaw_std_rad),
            ("converge_vel_nis_max", self.converge_vel_nis_max),
            ("converge_settle_s", self.converge_settle_s),
            ("converge_gps_s", self.converge_gps_s),
            ("converge_pos_std_m", self.converge_pos_std_m),
            ("converge_vel_std_mps", self.converge_vel_std_mps),
        ];
        if let Some(&(field, value)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Err(ConfigError { field, value });
        }
        if !self.mag_declination_deg.is_finite() {
            return Err(ConfigError { field: "mag_declination_deg", value: self.mag_declination_deg });
        }
        Ok(())
    }
}

/// The fused filter's latest innovations (measurement minus the prediction it was compared with), fused
/// or refused by the gate; NaN until a measurement of that kind was compared, and always with the
/// `Truth` source. What PX4 logs as `estimator_innovations`. Equal when bit-identical (NaN included), so
/// that an estimator compares equal to its replay.
#[derive(Debug, Clone, Copy)]
pub struct Innovations {
    /// GPS velocity (m/s, NED).
    pub gps_vel_ned_mps: [f64; 3],
    /// GPS position (m, NED).
    pub gps_pos_ned_m: [f64; 3],
    /// Barometric height (m, up).
    pub baro_alt_m: f64,
    /// Magnetic heading (rad).
    pub heading_rad: f64,
    /// Whether the gate refused the latest of each (PX4's `reject_*` flags): GPS velocity, GPS position,
    /// barometric height, magnetic heading.
    pub gps_vel_rejected: bool,
    pub gps_pos_rejected: bool,
    pub baro_rejected: bool,
    pub heading_rejected: bool,
}

impl Innovations {
    fn bits(&self) -> [u64; 9] {
        let [vn, ve, vd] = self.gps_vel_ned_mps.map(f64::to_bits);
        let [pn, pe, pd] = self.gps_pos_ned_m.map(f64::to_bits);
        let rejected = [self.gps_vel_rejected, self.gps_pos_rejected, self.baro_rejected, self.heading_rejected]
            .iter()
            .fold(0_u64, |acc, &r| (acc << 1) | u64::from(r));
        [vn, ve, vd, pn, pe, pd, self.baro_alt_m.to_bits(), self.heading_rad.to_bits(), rejected]
    }
}

impl PartialEq for Innovations {
    fn eq(&self, other: &Self) -> bool {
        self.bits() == other.bits()
    }
}

impl Default for Innovations {
    fn default() -> Self {
        Self {
            gps_vel_ned_mps: [f64::NAN; 3],
            gps_pos_ned_m: [f64::NAN; 3],
            baro_alt_m: f64::NAN,
            heading_rad: f64::NAN,
            gps_vel_rejected: false,
            gps_pos_rejected: false,
            baro_rejected: false,
            heading_rejected: false,
        }
    }
}

/// The estimator: the source switch, the input sanitiser and the fused filter.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimator {
    config: EstimatorConfig,
    fusion: Fusion,
    truth_state: EstimatorState,
    rejected: u64,
    /// The last IMU sample the sanitiser let through, for the step check ([`imu_step_plausible`]).
    last_imu: Option<ImuSample>,
}

impl Estimator {
    /// A new estimator: aligning (fused) or waiting for truth.
    #[must_use]
    pub fn new(config: EstimatorConfig) -> Self {
        let fusion = Fusion::new(&config);
        Self { config, fusion, truth_state: EstimatorState::default(), rejected: 0, last_imu: None }
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }

    fn fused(&self) -> bool {
        self.config.source == EstimatorSource::Fused
    }

    /// An IMU sample: predicts the state to `imu.time_us`.
    pub fn update_imu(&mut self, imu: &ImuSample) {
        if !self.fused() {
            return;
        }
        // A reading within range can still be garbage: one that jumps from the last by more than a body
        // can move in one sample is refused too (and the next one, compared with it, as well).
        let stepped = self.last_imu.is_none_or(|last| imu_step_plausible(&last, imu));
        let plausible = imu_plausible(imu);
        if plausible {
            self.last_imu = Some(*imu);
        }
        if !plausible || !stepped || self.fusion.update_imu(imu).is_err() {
            self.rejected += 1;
            self.fusion.note_imu_refused();
        }
    }

    /// A magnetometer sample, taken at the latest IMU time.
    pub fn update_mag(&mut self, mag: &MagSample) {
        if !self.fused() {
            return;
        }
        if mag_plausible(mag) {
            self.fusion.update_mag(mag);
        } else {
            self.rejected += 1;
        }
    }

    /// A barometer sample, taken at the latest IMU time.
    pub fn update_baro(&mut self, baro: &BaroSample) {
        if !self.fused() {
            return;
        }
        if baro_plausible(baro) {
            self.fusion.update_baro(baro);
        } else {
            self.rejected += 1;
        }
    }

    /// A GPS fix, valid at `gps.time_us` (it may arrive later).
    pub fn update_gps(&mut self, gps: &GpsSample) {
        if !self.fused() {
            return;
        }
        if !gps_plausible(gps) || self.fusion.update_gps(gps).is_err() {
            self.rejected += 1;
        }
    }

    /// Ground truth: copied as the state with the `Truth` source (every flag set), ignored otherwise.
    pub fn update_truth(&mut self, truth: &TruthSample) {
        if self.fused() {
            return;
        }
        if !truth_plausible(truth) {
            self.rejected += 1;
            return;
        }
        let (roll_rad, pitch_rad, yaw_rad) = truth.q_ned_frd.euler_angles();
        self.truth_state = EstimatorState {
            time_us: truth.time_us,
            pos_ned_m: truth.pos_ned_m,
            vel_ned_mps: truth.vel_ned_mps,
            q_ned_frd: truth.q_ned_frd,
            euler_rad: Vector3::new(roll_rad, pitch_rad, yaw_rad),
            rate_frd_radps: truth.rate_frd_radps,
            specific_force_frd_mps2: truth.specific_force_frd_mps2,
            accel_bias_frd_mps2: Vector3::zeros(),
            gyro_bias_frd_radps: Vector3::zeros(),
            origin: self.config.truth_origin,
            flags: EstimatorFlags {
                attitude_valid: true,
                velocity_valid: true,
                position_valid: true,
                converged: true,
                gps_ok: true,
                baro_ok: true,
                mag_ok: true,
                health: SourceHealth::default(),
                // Every flag says "as healthy as can be" with the truth: so does the height's source.
                height_source: HeightSource::Baro,
            },
        };
    }

    /// Advances the estimator's clock to `now_us` without a sample, so that timeouts (and the flags) are
    /// seen even when every sensor has gone quiet. Fused source only.
    pub fn update_clock(&mut self, now_us: u64) {
        if self.fused() {
            self.fusion.update_clock(now_us);
        }
    }

    /// The estimate.
    #[must_use]
    pub fn state(&self) -> &EstimatorState {
        match self.config.source {
            EstimatorSource::Fused => self.fusion.state(),
            EstimatorSource::Truth => &self.truth_state,
        }
    }

    /// The fused filter's latest innovations (all NaN with the `Truth` source).
    #[must_use]
    pub fn innovations(&self) -> Innovations {
        match self.config.source {
            EstimatorSource::Fused => *self.fusion.innovations(),
            EstimatorSource::Truth => Innovations::default(),
        }
    }

    /// The changes of source health since the last call (none with the `Truth` source), oldest first; at
    /// most [`MAX_PENDING_EVENTS`] are kept (the oldest are dropped).
    pub fn take_events(&mut self) -> Vec<EstimatorEvent> {
        self.fusion.take_events()
    }

    /// Samples refused by the sanitiser since creation or the last reset.
    #[must_use]
    pub fn rejected_samples(&self) -> u64 {
        self.rejected
    }

    /// Measurements refused by the innovation gate since creation or the last reset.
    #[must_use]
    pub fn gated_measurements(&self) -> u64 {
        self.fusion.gated_measurements()
    }

    /// Back to the state of [`Estimator::new`] with the same settings (origin, biases and counters too).
    pub fn reset(&mut self) {
        *self = Self::new(self.config.clone());
    }
}
