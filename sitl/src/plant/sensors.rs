//! Sensors (spec (b) "Sensors"): in, the plant's [`Truth`] each time the host samples (every control tick,
//! 2 ms in the paper runs); out, an IMU sample (specific force m/s² and rates rad/s, FRD), a magnetometer
//! sample (gauss, FRD), a barometer sample (hPa, pressure altitude m AMSL, °C), and, at the GPS rate
//! (default 10 Hz) after its latency (default 0), a GPS sample (WGS-84 degrees, m AMSL, m/s NED).
//! Also the paper's "hardware" state noise ([`StateNoise`]) on the truth-fed state.
//!
//! - Accelerometer: f = Rᵀ(v̇ - g e3), (0, 0, -g) at rest; v̇ from the equations of motion at the current
//!   state (including the ground reaction when resting).
//! - Magnetometer: a constant earth field at home (declination, inclination, intensity), rotated into FRD.
//! - Barometer: ISA troposphere, p = 1013.25 (1 - 0.0065 h/288.15)^5.25588 hPa, T = 15 - 0.0065 h °C, with
//!   h the altitude AMSL = home altitude - D (the noise is added to h, and p and T follow from it).
//! - GPS: position through a flat-earth NED <-> geodetic map about home with WGS-84 radii (see
//!   [`geodetic_from_ned`]); samples are captured on a fixed grid of the GPS period from t = 0 and
//!   released from a delay line after the latency.
//! - Each three-axis channel (and the barometer) has white noise σ and a bias random walk
//!   (b += σ_walk·sqrt(Δt)·n per sample, Δt the time since the previous sample) and an initial bias; all
//!   zero by default (noise-free paper runs). Every channel draws from its own random stream, so switching
//!   one noise on changes nothing else.

use std::collections::VecDeque;

use autopilot::core::control::frames::wrap_pi;
use autopilot::core::estimator::GeoOrigin;
pub use autopilot::core::estimator::GpsSample;
pub use autopilot::core::plant_link::HilBaroFields as BaroSample;
use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::Deserialize;

use super::airframe::{finite, non_negative, positive};
use super::faults::SensorFaults;
use super::{PlantError, Truth, stream, stream_rng};

/// ISA sea-level pressure (hPa).
pub const ISA_P0_HPA: f64 = 1013.25;
/// ISA sea-level temperature (K).
pub const ISA_T0_K: f64 = 288.15;
/// ISA tropospheric lapse rate (K/m).
pub const ISA_LAPSE_KPM: f64 = 0.0065;
/// ISA pressure exponent g0·M/(R·L) = 9.80665·0.0289644/(8.3144598·0.0065).
pub const ISA_EXPONENT: f64 = 5.255_88;

/// The geodetic origin of the NED frame (where D = 0 is `alt_amsl_m`). Default: PX4's SITL home.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HomeConfig {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_amsl_m: f64,
}

impl Default for HomeConfig {
    fn default() -> Self {
        Self { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 }
    }
}

impl HomeConfig {
    /// The home as the core's geodetic origin (`autopilot::core::estimator::GeoOrigin`), whose map and
    /// WGS-84 radii the plant's GPS and SIM_STATE use.
    #[must_use]
    pub fn origin(&self) -> GeoOrigin {
        GeoOrigin { lat_deg: self.lat_deg, lon_deg: self.lon_deg, alt_amsl_m: self.alt_amsl_m }
    }
}

/// The earth's magnetic field at home. Defaults are approximate WMM values for the default home; set
/// them for another home.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EarthFieldConfig {
    /// Declination, east of true north positive (deg).
    pub declination_deg: f64,
    /// Inclination (dip), downward positive (deg).
    pub inclination_deg: f64,
    /// Total intensity (gauss).
    pub intensity_gauss: f64,
}

impl Default for EarthFieldConfig {
    fn default() -> Self {
        Self { declination_deg: 3.3, inclination_deg: 63.6, intensity_gauss: 0.48 }
    }
}

impl EarthFieldConfig {
    /// The field vector in NED (gauss).
    #[must_use]
    pub fn field_ned_gauss(&self) -> Vector3<f64> {
        let (dec, inc) = (self.declination_deg.to_radians(), self.inclination_deg.to_radians());
        Vector3::new(inc.cos() * dec.cos(), inc.cos() * dec.sin(), inc.sin()) * self.intensity_gauss
    }
}

/// Noise of a three-axis channel, in the unit of that channel (accelerometer m/s², gyro rad/s,
/// magnetometer gauss, GPS position m, GPS velocity m/s).
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Vec3NoiseConfig {
    /// White noise σ per axis.
    pub white_sigma: f64,
    /// Bias random-walk intensity per axis (unit/sqrt(s)).
    pub bias_walk_sigma_per_sqrt_s: f64,
    /// Bias at t = 0.
    pub initial_bias: [f64; 3],
}

/// Noise of the barometer, on the altitude (m).
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BaroNoiseConfig {
    /// White noise σ (m).
    pub white_sigma_m: f64,
    /// Bias random-walk intensity (m/sqrt(s)).
    pub bias_walk_sigma_m_per_sqrt_s: f64,
    /// Bias at t = 0 (m).
    pub initial_bias_m: f64,
}

/// The GPS receiver.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GpsConfig {
    /// Output rate (Hz).
    pub rate_hz: f64,
    /// Delay from measurement to output (s); 0 for the paper runs.
    pub latency_s: f64,
    /// Reported fix type (3 = 3D fix).
    pub fix_type: u8,
    /// Reported number of satellites.
    pub satellites_visible: u8,
    /// Reported horizontal accuracy (m).
    pub eph_m: f64,
    /// Reported vertical accuracy (m).
    pub epv_m: f64,
    /// Noise on the NED position (m).
    pub position: Vec3NoiseConfig,
    /// Noise on the NED velocity (m/s).
    pub velocity: Vec3NoiseConfig,
}

impl Default for GpsConfig {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            latency_s: 0.0,
            fix_type: 3,
            satellites_visible: 10,
            eph_m: 0.5,
            epv_m: 0.8,
            position: Vec3NoiseConfig::default(),
            velocity: Vec3NoiseConfig::default(),
        }
    }
}

/// The `[sensors]` table. Default: noise-free, 10 Hz GPS without latency, PX4's default home.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    pub home: HomeConfig,
    pub earth_field: EarthFieldConfig,
    /// Accelerometer noise (m/s²).
    pub accel: Vec3NoiseConfig,
    /// Gyro noise (rad/s).
    pub gyro: Vec3NoiseConfig,
    /// Magnetometer noise (gauss).
    pub mag: Vec3NoiseConfig,
    pub baro: BaroNoiseConfig,
    pub gps: GpsConfig,
}

impl SensorConfig {
    /// Modest white noise on every sensor, for SITL flights where the fused estimator should have work
    /// to do: gyro 0.005 rad/s, accelerometer 0.05 m/s², magnetometer 0.002 G, barometer 0.05 m, GPS
    /// 0.1 m and 0.02 m/s. No bias, no latency.
    #[must_use]
    pub fn modest_noise() -> Self {
        let mut s = Self::default();
        s.gyro.white_sigma = 0.005;
        s.accel.white_sigma = 0.05;
        s.mag.white_sigma = 0.002;
        s.baro.white_sigma_m = 0.05;
        s.gps.position.white_sigma = 0.1;
        s.gps.velocity.white_sigma = 0.02;
        s
    }

    /// Check every value.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for non-finite values, negative σ, latitude outside ±89°, a GPS rate
    /// not > 0 or above 1 kHz, or a negative latency.
    pub fn validate(&self) -> Result<(), PlantError> {
        finite("sensors.home.lat_deg", self.home.lat_deg)?;
        if self.home.lat_deg.abs() > 89.0 {
            return Err(PlantError::InvalidValue {
                name: "sensors.home.lat_deg",
                value: self.home.lat_deg.to_string(),
                reason: "the flat-earth GPS map needs |latitude| <= 89 deg",
            });
        }
        finite("sensors.home.lon_deg", self.home.lon_deg)?;
        finite("sensors.home.alt_amsl_m", self.home.alt_amsl_m)?;
        finite("sensors.earth_field.declination_deg", self.earth_field.declination_deg)?;
        finite("sensors.earth_field.inclination_deg", self.earth_field.inclination_deg)?;
        non_negative("sensors.earth_field.intensity_gauss", self.earth_field.intensity_gauss)?;
        validate_vec3("sensors.accel", &self.accel)?;
        validate_vec3("sensors.gyro", &self.gyro)?;
        validate_vec3("sensors.mag", &self.mag)?;
        non_negative("sensors.baro.white_sigma_m", self.baro.white_sigma_m)?;
        non_negative("sensors.baro.bias_walk_sigma_m_per_sqrt_s", self.baro.bias_walk_sigma_m_per_sqrt_s)?;
        finite("sensors.baro.initial_bias_m", self.baro.initial_bias_m)?;
        positive("sensors.gps.rate_hz", self.gps.rate_hz)?;
        if self.gps.rate_hz > 1000.0 {
            return Err(PlantError::InvalidValue {
                name: "sensors.gps.rate_hz",
                value: self.gps.rate_hz.to_string(),
                reason: "must be <= 1000 Hz",
            });
        }
        non_negative("sensors.gps.latency_s", self.gps.latency_s)?;
        non_negative("sensors.gps.eph_m", self.gps.eph_m)?;
        non_negative("sensors.gps.epv_m", self.gps.epv_m)?;
        validate_vec3("sensors.gps.position", &self.gps.position)?;
        validate_vec3("sensors.gps.velocity", &self.gps.velocity)?;
        Ok(())
    }
}

fn validate_vec3(channel: &'static str, c: &Vec3NoiseConfig) -> Result<(), PlantError> {
    let values = [c.white_sigma, c.bias_walk_sigma_per_sqrt_s, c.initial_bias[0], c.initial_bias[1], c.initial_bias[2]];
    for v in values {
        finite(channel, v)?;
    }
    non_negative(channel, c.white_sigma)?;
    non_negative(channel, c.bias_walk_sigma_per_sqrt_s)
}

/// A geodetic position (WGS-84 degrees, altitude above mean sea level in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geodetic {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_amsl_m: f64,
}

/// Flat-earth NED -> geodetic about home: the core's map ([`GeoOrigin::geodetic_from_ned`], the WGS-84
/// meridian and transverse radii at lat0, a longitude past ±180 wrapped), inverted by
/// [`ned_from_geodetic`] to rounding. Against a true tangent plane it departs as d²/R (at 1 km the plane is
/// 8 cm above the ellipsoid, and a combined 1 km N + 1 km E offset moves by about 0.2 m at mid-latitudes):
/// fine for a SITL field of a few km.
#[must_use]
pub fn geodetic_from_ned(home: &HomeConfig, pos_ned_m: &Vector3<f64>) -> Geodetic {
    let (lat_deg, lon_deg, alt_amsl_m) = home.origin().geodetic_from_ned(pos_ned_m);
    Geodetic { lat_deg, lon_deg, alt_amsl_m }
}

/// The inverse of [`geodetic_from_ned`]: the core's [`GeoOrigin::ned_from_geodetic`] about home.
#[must_use]
pub fn ned_from_geodetic(home: &HomeConfig, geodetic: &Geodetic) -> Vector3<f64> {
    home.origin().ned_from_geodetic(geodetic.lat_deg, geodetic.lon_deg, geodetic.alt_amsl_m)
}

/// Altitude range (m AMSL) of the ISA troposphere model; outside it the altitude is clamped (the formula
/// has no real value above 44 km).
pub const ISA_ALT_RANGE_M: (f64, f64) = (-5000.0, 11_000.0);

/// ISA static pressure (hPa) at `alt_amsl_m` (troposphere; the altitude is clamped to
/// [`ISA_ALT_RANGE_M`]).
#[must_use]
pub fn isa_pressure_hpa(alt_amsl_m: f64) -> f64 {
    let h = alt_amsl_m.clamp(ISA_ALT_RANGE_M.0, ISA_ALT_RANGE_M.1);
    ISA_P0_HPA * (1.0 - ISA_LAPSE_KPM * h / ISA_T0_K).powf(ISA_EXPONENT)
}

/// ISA pressure altitude (m AMSL) of `pressure_hpa`; the inverse of [`isa_pressure_hpa`].
#[must_use]
pub fn isa_altitude_m(pressure_hpa: f64) -> f64 {
    ISA_T0_K / ISA_LAPSE_KPM * (1.0 - (pressure_hpa / ISA_P0_HPA).powf(1.0 / ISA_EXPONENT))
}

/// ISA temperature (°C) at `alt_amsl_m`.
#[must_use]
pub fn isa_temperature_degc(alt_amsl_m: f64) -> f64 {
    15.0 - ISA_LAPSE_KPM * alt_amsl_m
}

/// One sample of every sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSample {
    /// Plant time of the IMU, magnetometer and barometer samples (µs).
    pub time_us: u64,
    /// Specific force (m/s², FRD).
    pub accel_frd_mps2: Vector3<f64>,
    /// Body rates (rad/s, FRD).
    pub gyro_frd_radps: Vector3<f64>,
    /// Magnetic field (gauss, FRD); `None` while the magnetometer is off ([`super::faults`]).
    pub mag_frd_gauss: Option<Vector3<f64>>,
    /// `None` while the barometer is off ([`super::faults`]).
    pub baro: Option<BaroSample>,
    /// A GPS sample when one is released at this time.
    pub gps: Option<GpsSample>,
}

/// A three-axis noise channel: bias random walk + white noise, each from its own stream.
#[derive(Debug, Clone)]
struct Channel3 {
    white_sigma: f64,
    walk_sigma: f64,
    bias: Vector3<f64>,
    white_rng: ChaCha8Rng,
    walk_rng: ChaCha8Rng,
}

fn normal3(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    let n: [f64; 3] = std::array::from_fn(|_| rng.sample(StandardNormal));
    Vector3::from(n)
}

impl Channel3 {
    fn new(config: &Vec3NoiseConfig, seed: u64, white_stream: u64, walk_stream: u64) -> Self {
        Self {
            white_sigma: config.white_sigma,
            walk_sigma: config.bias_walk_sigma_per_sqrt_s,
            bias: Vector3::from(config.initial_bias),
            white_rng: stream_rng(seed, white_stream),
            walk_rng: stream_rng(seed, walk_stream),
        }
    }

    fn measure(&mut self, truth: &Vector3<f64>, dt_s: f64) -> Vector3<f64> {
        if self.walk_sigma > 0.0 && dt_s > 0.0 {
            self.bias += normal3(&mut self.walk_rng) * (self.walk_sigma * dt_s.sqrt());
        }
        let mut out = truth + self.bias;
        if self.white_sigma > 0.0 {
            out += normal3(&mut self.white_rng) * self.white_sigma;
        }
        out
    }
}

/// The barometer's altitude noise channel.
#[derive(Debug, Clone)]
struct Channel1 {
    white_sigma: f64,
    walk_sigma: f64,
    bias: f64,
    white_rng: ChaCha8Rng,
    walk_rng: ChaCha8Rng,
}

impl Channel1 {
    fn measure(&mut self, truth: f64, dt_s: f64) -> f64 {
        if self.walk_sigma > 0.0 && dt_s > 0.0 {
            let n: f64 = self.walk_rng.sample(StandardNormal);
            self.bias += n * self.walk_sigma * dt_s.sqrt();
        }
        let mut out = truth + self.bias;
        if self.white_sigma > 0.0 {
            let n: f64 = self.white_rng.sample(StandardNormal);
            out += n * self.white_sigma;
        }
        out
    }
}

/// The sensor suite: noise state, GPS schedule and delay line.
#[derive(Debug, Clone)]
pub struct Sensors {
    config: SensorConfig,
    field_ned_gauss: Vector3<f64>,
    accel: Channel3,
    gyro: Channel3,
    mag: Channel3,
    baro: Channel1,
    gps_position: Channel3,
    gps_velocity: Channel3,
    gps_period_us: u64,
    gps_latency_us: u64,
    gps_next_capture_us: u64,
    gps_last_capture_us: Option<u64>,
    gps_delay_line: VecDeque<GpsSample>,
    last_sample_us: Option<u64>,
    /// The faults applied to every sample.
    faults: SensorFaults,
}

impl Sensors {
    /// The sensor suite; its noise streams derive from the plant `seed`.
    ///
    /// # Errors
    /// As [`SensorConfig::validate`].
    pub fn new(config: &SensorConfig, seed: u64) -> Result<Self, PlantError> {
        config.validate()?;
        Ok(Self {
            config: *config,
            field_ned_gauss: config.earth_field.field_ned_gauss(),
            accel: Channel3::new(&config.accel, seed, stream::ACCEL_WHITE, stream::ACCEL_WALK),
            gyro: Channel3::new(&config.gyro, seed, stream::GYRO_WHITE, stream::GYRO_WALK),
            mag: Channel3::new(&config.mag, seed, stream::MAG_WHITE, stream::MAG_WALK),
            baro: Channel1 {
                white_sigma: config.baro.white_sigma_m,
                walk_sigma: config.baro.bias_walk_sigma_m_per_sqrt_s,
                bias: config.baro.initial_bias_m,
                white_rng: stream_rng(seed, stream::BARO_WHITE),
                walk_rng: stream_rng(seed, stream::BARO_WALK),
            },
            gps_position: Channel3::new(&config.gps.position, seed, stream::GPS_POS_WHITE, stream::GPS_POS_WALK),
            gps_velocity: Channel3::new(&config.gps.velocity, seed, stream::GPS_VEL_WHITE, stream::GPS_VEL_WALK),
            gps_period_us: ((1e6 / config.gps.rate_hz).round() as u64).max(1),
            gps_latency_us: (config.gps.latency_s * 1e6).round() as u64,
            gps_next_capture_us: 0,
            gps_last_capture_us: None,
            gps_delay_line: VecDeque::new(),
            last_sample_us: None,
            faults: SensorFaults::new(seed),
        })
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &SensorConfig {
        &self.config
    }

    /// The sensor faults ([`super::faults`]).
    #[must_use]
    pub fn faults(&self) -> &SensorFaults {
        &self.faults
    }

    /// The sensor faults, to fail or clear a sensor from the next sample on.
    pub fn faults_mut(&mut self) -> &mut SensorFaults {
        &mut self.faults
    }

    /// Sample every sensor from `truth` at `truth.time_us`, with the sensor faults applied. A GPS
    /// measurement is captured at the first call at or after each point of the GPS grid (k·period from
    /// t = 0) and released `latency_s` after its capture; if several are released by one call (sparse
    /// sampling), the newest is returned.
    pub fn sample(&mut self, truth: &Truth) -> SensorSample {
        let clean = self.sample_clean(truth);
        self.faults.apply(&clean, &self.config.home.origin())
    }

    /// [`Sensors::sample`] without the faults (the noise streams and the GPS schedule advance the same).
    fn sample_clean(&mut self, truth: &Truth) -> SensorSample {
        let now_us = truth.time_us;
        let dt_s = self.last_sample_us.map_or(0.0, |last| now_us.saturating_sub(last) as f64 * 1e-6);
        self.last_sample_us = Some(now_us);

        let accel_frd_mps2 = self.accel.measure(&truth.specific_force_frd_mps2, dt_s);
        let gyro_frd_radps = self.gyro.measure(&truth.rate_frd_radps, dt_s);
        let field_frd = truth.q_ned_frd.inverse_transform_vector(&self.field_ned_gauss);
        let mag_frd_gauss = self.mag.measure(&field_frd, dt_s);

        let alt_amsl_m = self.config.home.alt_amsl_m - truth.pos_ned_m.z;
        let pressure_alt_m = self.baro.measure(alt_amsl_m, dt_s);
        let baro = BaroSample {
            pressure_hpa: isa_pressure_hpa(pressure_alt_m),
            pressure_alt_m,
            temperature_degc: isa_temperature_degc(alt_amsl_m),
        };

        if now_us >= self.gps_next_capture_us {
            let capture = self.capture_gps(truth);
            self.gps_delay_line.push_back(capture);
            // Next grid point strictly after now (skips missed periods if sampled sparsely).
            self.gps_next_capture_us = (now_us / self.gps_period_us + 1) * self.gps_period_us;
        }
        let mut gps = None;
        while let Some(front) = self.gps_delay_line.front() {
            if front.time_us + self.gps_latency_us <= now_us {
                gps = self.gps_delay_line.pop_front();
            } else {
                break;
            }
        }

        SensorSample {
            time_us: now_us,
            accel_frd_mps2,
            gyro_frd_radps,
            mag_frd_gauss: Some(mag_frd_gauss),
            baro: Some(baro),
            gps,
        }
    }

    fn capture_gps(&mut self, truth: &Truth) -> GpsSample {
        let dt_s = self.gps_last_capture_us.map_or(0.0, |last| truth.time_us.saturating_sub(last) as f64 * 1e-6);
        self.gps_last_capture_us = Some(truth.time_us);
        let pos_ned_m = self.gps_position.measure(&truth.pos_ned_m, dt_s);
        let vel_ned_mps = self.gps_velocity.measure(&truth.vel_ned_mps, dt_s);
        let geodetic = geodetic_from_ned(&self.config.home, &pos_ned_m);
        GpsSample {
            time_us: truth.time_us,
            lat_deg: geodetic.lat_deg,
            lon_deg: geodetic.lon_deg,
            alt_amsl_m: geodetic.alt_amsl_m,
            vel_ned_mps,
            eph_m: self.config.gps.eph_m,
            epv_m: self.config.gps.epv_m,
            fix_type: self.config.gps.fix_type,
            satellites: self.config.gps.satellites_visible,
        }
    }
}

/// White noise σ of the paper's "hardware" runs on the truth-fed state (spec (b) "Sensors").
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StateNoise {
    /// On each NED position axis (m).
    pub pos_sigma_m: f64,
    /// On each NED velocity axis (m/s).
    pub vel_sigma_mps: f64,
    /// On each Euler angle φ, θ, ψ (rad).
    pub att_sigma_rad: f64,
    /// On each body rate (rad/s).
    pub gyro_sigma_radps: f64,
    /// On each specific-force axis (m/s²).
    pub accel_sigma_mps2: f64,
}

impl StateNoise {
    /// The paper's hardware noise: 0.02 m, 0.05 m/s, 0.005 rad, 0.01 rad/s, 0.2 m/s².
    #[must_use]
    pub fn paper() -> Self {
        Self {
            pos_sigma_m: 0.02,
            vel_sigma_mps: 0.05,
            att_sigma_rad: 0.005,
            gyro_sigma_radps: 0.01,
            accel_sigma_mps2: 0.2,
        }
    }

    /// No noise.
    #[must_use]
    pub fn none() -> Self {
        Self { pos_sigma_m: 0.0, vel_sigma_mps: 0.0, att_sigma_rad: 0.0, gyro_sigma_radps: 0.0, accel_sigma_mps2: 0.0 }
    }

    /// Every σ multiplied by `scale` (>= 0; 0 is no noise and draws nothing, 1 is `self` exactly).
    #[must_use]
    pub fn scaled(self, scale: f64) -> Self {
        Self {
            pos_sigma_m: self.pos_sigma_m * scale,
            vel_sigma_mps: self.vel_sigma_mps * scale,
            att_sigma_rad: self.att_sigma_rad * scale,
            gyro_sigma_radps: self.gyro_sigma_radps * scale,
            accel_sigma_mps2: self.accel_sigma_mps2 * scale,
        }
    }
}

impl Default for StateNoise {
    fn default() -> Self {
        Self::none()
    }
}

/// The truth-fed state of the paper's runs, with [`StateNoise`] added.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoisyState {
    /// Plant time (µs).
    pub time_us: u64,
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    /// ZYX (φ, θ, ψ) (rad), ψ wrapped to (-π, π].
    pub euler_rad: Vector3<f64>,
    pub rate_frd_radps: Vector3<f64>,
    pub specific_force_frd_mps2: Vector3<f64>,
}

/// Add `noise` to `truth`, drawing (only for non-zero σ) from `rng`, in the order position, velocity,
/// attitude, rates, specific force.
pub fn noisy_state(truth: &Truth, noise: &StateNoise, rng: &mut ChaCha8Rng) -> NoisyState {
    let mut add = |x: Vector3<f64>, sigma: f64| {
        if sigma > 0.0 { x + normal3(rng) * sigma } else { x }
    };
    let pos_ned_m = add(truth.pos_ned_m, noise.pos_sigma_m);
    let vel_ned_mps = add(truth.vel_ned_mps, noise.vel_sigma_mps);
    let mut euler_rad = add(truth.euler_rad, noise.att_sigma_rad);
    let rate_frd_radps = add(truth.rate_frd_radps, noise.gyro_sigma_radps);
    let specific_force_frd_mps2 = add(truth.specific_force_frd_mps2, noise.accel_sigma_mps2);
    if euler_rad.z.abs() > std::f64::consts::PI {
        euler_rad.z = wrap_pi(euler_rad.z);
    }
    NoisyState { time_us: truth.time_us, pos_ned_m, vel_ned_mps, euler_rad, rate_frd_radps, specific_force_frd_mps2 }
}

#[cfg(test)]
mod tests {
    use super::super::{InitialState, Plant, PlantConfig};
    use super::*;
    use crate::plant::airframe::Airframe;

    fn std_dev(x: &[f64]) -> f64 {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    }

    fn hover_plant(config: PlantConfig, d_m: f64) -> Plant {
        let initial = InitialState { pos_ned_m: Vector3::new(0.0, 0.0, d_m), ..InitialState::default() };
        Plant::new(config, &initial, 1).unwrap()
    }

    #[test]
    fn given_a_vehicle_at_rest_on_the_ground_when_sampling_then_the_accelerometer_reads_minus_g() {
        let mut plant = hover_plant(PlantConfig::default(), 0.0);
        for _ in 0..500 {
            plant.step([1000.0; 4], 2000);
        }
        let s = plant.sample_sensors();
        assert!(plant.truth().on_ground);
        assert!((s.accel_frd_mps2 - Vector3::new(0.0, 0.0, -9.81)).norm() < 1e-12, "{s:?}");
        assert_eq!(s.gyro_frd_radps, Vector3::zeros());
    }

    #[test]
    fn given_a_hovering_vehicle_when_sampling_then_the_accelerometer_reads_minus_g() {
        let mut plant = hover_plant(PlantConfig::default(), -5.0);
        let pwm = Airframe::nominal().hover_pwm_us();
        for _ in 0..500 {
            plant.step([pwm; 4], 2000);
        }
        let s = plant.sample_sensors();
        assert!(!plant.truth().on_ground);
        assert!((s.accel_frd_mps2 - Vector3::new(0.0, 0.0, -9.81)).norm() < 1e-9, "{s:?}");
    }

    #[test]
    fn given_a_climb_when_sampling_then_baro_altitude_follows_minus_d() {
        let mut plant = hover_plant(PlantConfig::default(), 0.0);
        let home_alt = plant.config().sensors.home.alt_amsl_m;
        let mut checked = 0;
        for k in 0..2000 {
            plant.step([1900.0; 4], 2000);
            let s = plant.sample_sensors();
            let d = plant.truth().pos_ned_m.z;
            let baro = s.baro.expect("baro");
            assert!((baro.pressure_alt_m - home_alt + d).abs() < 1e-9);
            assert!((isa_altitude_m(baro.pressure_hpa) - baro.pressure_alt_m).abs() < 1e-6);
            if k % 100 == 0 {
                checked += 1;
            }
        }
        assert!(plant.truth().pos_ned_m.z < -2.0 && checked == 20);
        // ISA anchor values.
        assert!((isa_pressure_hpa(0.0) - 1013.25).abs() < 1e-12);
        assert!((isa_pressure_hpa(1000.0) - 898.75).abs() < 0.01);
        assert!((isa_temperature_degc(1000.0) - 8.5).abs() < 1e-12);
        // Far outside the troposphere the pressure stays finite (clamped), never NaN.
        assert_eq!(isa_pressure_hpa(1.0e6), isa_pressure_hpa(11_000.0));
        assert!(isa_pressure_hpa(1.0e6).is_finite() && isa_pressure_hpa(-1.0e6).is_finite());
    }

    #[test]
    fn given_ned_offsets_up_to_1_km_when_mapped_to_geodetic_and_back_then_they_round_trip_within_1_cm() {
        let home = HomeConfig::default();
        for &(n, e, d) in &[(1000.0, 0.0, 0.0), (0.0, 1000.0, -50.0), (-707.1, 707.1, 3.0), (-1000.0, -1000.0, -120.0)]
        {
            let p = Vector3::new(n, e, d);
            let g = geodetic_from_ned(&home, &p);
            assert!((ned_from_geodetic(&home, &g) - p).norm() < 0.01);
        }
        // Independent anchor: the standard series for the length of a degree on WGS-84,
        // 111132.92 - 559.82 cos 2φ + 1.175 cos 4φ - 0.0023 cos 6φ (latitude) and
        // 111412.84 cos φ - 93.5 cos 3φ + 0.118 cos 5φ (longitude), at several latitudes.
        for lat_deg in [0.0_f64, 30.0, 45.0, 47.4, 60.0] {
            let home = HomeConfig { lat_deg, lon_deg: 0.0, alt_amsl_m: 0.0 };
            let phi = lat_deg.to_radians();
            let m_per_deg_lat =
                111_132.92 - 559.82 * (2.0 * phi).cos() + 1.175 * (4.0 * phi).cos() - 0.0023 * (6.0 * phi).cos();
            let m_per_deg_lon = 111_412.84 * phi.cos() - 93.5 * (3.0 * phi).cos() + 0.118 * (5.0 * phi).cos();
            let g = geodetic_from_ned(&home, &Vector3::new(1000.0, 1000.0, 0.0));
            let north_m = (g.lat_deg - lat_deg) * m_per_deg_lat;
            let east_m = g.lon_deg * m_per_deg_lon;
            assert!((north_m - 1000.0).abs() < 0.01, "{lat_deg}: {north_m}");
            assert!((east_m - 1000.0).abs() < 0.01, "{lat_deg}: {east_m}");
        }
    }

    #[test]
    fn given_gps_at_10_hz_without_latency_when_sampled_every_2_ms_then_ten_fixes_per_second_arrive_fresh() {
        let mut plant = hover_plant(PlantConfig::default(), -5.0);
        let mut times = Vec::new();
        for _ in 0..500 {
            let s = plant.sample_sensors();
            if let Some(gps) = s.gps {
                assert_eq!(gps.time_us, s.time_us);
                assert_eq!(gps.fix_type, 3);
                times.push(gps.time_us);
            }
            plant.step([1500.0; 4], 2000);
        }
        assert_eq!(times, (0..10).map(|k| k * 100_000).collect::<Vec<u64>>());
    }

    #[test]
    fn given_gps_latency_when_sampled_then_fixes_arrive_late_carrying_the_old_position() {
        let mut config = PlantConfig::default();
        config.sensors.gps.latency_s = 0.1;
        config.sensors.gps.rate_hz = 5.0;
        let mut plant = hover_plant(config, -5.0);
        let home = plant.config().sensors.home;
        let mut history = Vec::new();
        let mut arrivals = Vec::new();
        for _ in 0..1000 {
            history.push((plant.time_us(), plant.truth().pos_ned_m));
            let s = plant.sample_sensors();
            if let Some(gps) = s.gps {
                arrivals.push((s.time_us, gps));
            }
            plant.step([1900.0, 1900.0, 1900.0, 1880.0], 2000);
        }
        assert_eq!(arrivals.len(), 10);
        for (k, (arrived_us, gps)) in arrivals.iter().enumerate() {
            assert_eq!(gps.time_us, k as u64 * 200_000);
            assert_eq!(*arrived_us, gps.time_us + 100_000);
            let truth = history.iter().find(|(t, _)| *t == gps.time_us).unwrap().1;
            let measured = ned_from_geodetic(
                &home,
                &Geodetic { lat_deg: gps.lat_deg, lon_deg: gps.lon_deg, alt_amsl_m: gps.alt_amsl_m },
            );
            assert!((measured - truth).norm() < 1e-6);
        }
        // The vehicle moved, so a stale fix is distinguishable from a fresh one.
        assert!((history[999].1 - history[0].1).norm() > 1.0);
    }

    #[test]
    fn given_default_config_when_sampling_then_every_sensor_is_noise_free() {
        let mut plant = hover_plant(PlantConfig::default(), -5.0);
        let pwm = Airframe::nominal().hover_pwm_us();
        for _ in 0..100 {
            plant.step([pwm, pwm + 50.0, pwm, pwm - 50.0], 2000);
            let truth = plant.truth();
            let s = plant.sample_sensors();
            assert_eq!(s.accel_frd_mps2, truth.specific_force_frd_mps2);
            assert_eq!(s.gyro_frd_radps, truth.rate_frd_radps);
            let field = EarthFieldConfig::default().field_ned_gauss();
            assert!((s.mag_frd_gauss.expect("mag") - truth.q_ned_frd.inverse_transform_vector(&field)).norm() < 1e-15);
            let noisy = plant.sample_state(&StateNoise::none());
            assert_eq!(noisy.pos_ned_m, truth.pos_ned_m);
            assert_eq!(noisy.euler_rad, truth.euler_rad);
        }
    }

    #[test]
    fn given_a_level_vehicle_heading_north_when_sampling_the_magnetometer_then_it_reads_the_earth_field() {
        let mut plant = hover_plant(PlantConfig::default(), -5.0);
        let field = EarthFieldConfig::default().field_ned_gauss();
        assert!((plant.sample_sensors().mag_frd_gauss.expect("mag") - field).norm() < 1e-15);
        assert!((field.norm() - 0.48).abs() < 1e-12 && field.z > 0.0);
        // Yawed 90° right (facing east), magnetic north is to the vehicle's left: -y body.
        let initial = InitialState {
            pos_ned_m: Vector3::new(0.0, 0.0, -5.0),
            euler_rad: Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            ..InitialState::default()
        };
        let mut yawed = Plant::new(PlantConfig::default(), &initial, 1).unwrap();
        let m = yawed.sample_sensors().mag_frd_gauss.expect("mag");
        assert!((m - Vector3::new(field.y, -field.x, field.z)).norm() < 1e-12, "{m:?}");
    }

    #[test]
    fn given_configured_noise_when_sampled_many_times_then_each_sigma_is_within_10_percent() {
        let mut config = PlantConfig::default();
        config.sensors.accel.white_sigma = 0.2;
        config.sensors.gyro.white_sigma = 0.01;
        config.sensors.mag.white_sigma = 0.005;
        config.sensors.baro.white_sigma_m = 0.3;
        let mut plant = hover_plant(config, -5.0);
        let truth = plant.truth();
        let n = 20_000;
        let mut acc = Vec::with_capacity(n);
        let mut gyro = Vec::with_capacity(n);
        let mut mag = Vec::with_capacity(n);
        let mut baro = Vec::with_capacity(n);
        let mut state_acc = Vec::with_capacity(n);
        let mut state_att = Vec::with_capacity(n);
        for _ in 0..n {
            let s = plant.sample_sensors();
            acc.push(s.accel_frd_mps2.x);
            gyro.push(s.gyro_frd_radps.y);
            mag.push(s.mag_frd_gauss.expect("mag").z);
            baro.push(s.baro.expect("baro").pressure_alt_m);
            let st = plant.sample_state(&StateNoise::paper());
            state_acc.push(st.specific_force_frd_mps2.z - truth.specific_force_frd_mps2.z);
            state_att.push(st.euler_rad.x);
        }
        for (name, x, sigma) in [
            ("accel", &acc, 0.2),
            ("gyro", &gyro, 0.01),
            ("mag", &mag, 0.005),
            ("baro", &baro, 0.3),
            ("state accel", &state_acc, 0.2),
            ("state attitude", &state_att, 0.005),
        ] {
            let s = std_dev(x);
            assert!((s / sigma - 1.0).abs() < 0.1, "{name}: {s}");
        }
    }

    #[test]
    fn given_gyro_noise_switched_on_when_sampling_then_the_accelerometer_stream_is_unchanged() {
        let run = |gyro_sigma: f64| {
            let mut config = PlantConfig::default();
            config.sensors.accel.white_sigma = 0.2;
            config.sensors.gyro.white_sigma = gyro_sigma;
            let mut plant = hover_plant(config, -5.0);
            (0..100).map(|_| plant.sample_sensors().accel_frd_mps2).collect::<Vec<_>>()
        };
        assert_eq!(run(0.0), run(0.01));
    }

    #[test]
    fn given_a_bias_random_walk_when_sampled_long_then_the_bias_spread_grows_as_sqrt_time() {
        // 400 independent suites (seeds), 10 s of 20 ms samples each: bias std = σ_w·sqrt(10 s).
        let walk = 0.01;
        let plant = hover_plant(PlantConfig::default(), -5.0);
        let mut truth = plant.truth();
        let mut finals = Vec::new();
        for seed in 0..400 {
            let mut config = SensorConfig::default();
            config.gyro.bias_walk_sigma_per_sqrt_s = walk;
            let mut sensors = Sensors::new(&config, seed).unwrap();
            let mut last = Vector3::zeros();
            for k in 0..=500 {
                truth.time_us = k * 20_000;
                last = sensors.sample(&truth).gyro_frd_radps;
            }
            finals.push(last.x);
        }
        let s = std_dev(&finals);
        assert!((s / (walk * 10.0_f64.sqrt()) - 1.0).abs() < 0.15, "{s}");
    }

    #[test]
    fn given_invalid_sensor_values_when_validating_then_they_are_refused() {
        let mut c = SensorConfig::default();
        c.gps.rate_hz = 0.0;
        assert!(c.validate().unwrap_err().to_string().contains("sensors.gps.rate_hz"));
        let mut c = SensorConfig::default();
        c.accel.white_sigma = -1.0;
        assert!(c.validate().unwrap_err().to_string().contains("sensors.accel"));
        let mut c = SensorConfig::default();
        c.gps.latency_s = f64::NAN;
        assert!(c.validate().unwrap_err().to_string().contains("latency"));
        SensorConfig::default().validate().unwrap();
    }
}
