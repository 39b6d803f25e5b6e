//! Sensor faults the plant injects into its samples, as PX4's failure injection and ArduPilot's SIM_*_FAIL
//! parameters rehearse them: in, the clean [`SensorSample`] of each tick and the fault of each sensor (the
//! SIM_ parameters SIM_GPS_FAIL, SIM_BARO_FAIL, SIM_MAG_FAIL, SIM_ACC_FAIL, SIM_GYRO_FAIL, set through the
//! SIM_ port or a forwarded MAV_CMD_INJECT_FAILURE); out, the sample the board reports.
//!
//! The faults, numbered as MAVLink's `FAILURE_TYPE` ([`Fault`]):
//! - **off** (GPS, baro, mag): the sensor is absent from the sample (no `HIL_GPS`; `HIL_SENSOR` without the
//!   sensor's `fields_updated` bits);
//! - **stuck** (every sensor): the sensor repeats the last value it gave before the fault, bit for bit, with
//!   fresh time stamps (a stuck GPS repeats its last fix at its own rate, each with the new fix's time);
//! - **garbage** (accelerometer, gyro): each axis uniform at random within the sensor's plausible range
//!   ([`ACCEL_GARBAGE_MPS2`] = ±16 g, [`GYRO_GARBAGE_RADPS`] = ±35 rad/s), from the plant seed's own
//!   streams [`super::stream::ACCEL_GARBAGE`] and [`super::stream::GYRO_GARBAGE`] (drawn only while the
//!   fault is on), so a rerun is identical;
//! - **wrong** (GPS): the fix's position offset by SIM_GPS_JUMP_N/E (m, north and east, through the GPS's
//!   own map about home), velocity and accuracy unchanged: a position jump.
//!
//! The sensors are sampled whatever the faults (their noise streams and the GPS schedule advance as
//! without faults), so clearing a fault gives back exactly the sample the sensor would have given. IMU off
//! is not simulated: the IMU sample is the lockstep tick. A fault a sensor does not have is refused with a
//! reason ([`FaultError`]), and nothing changes.

use autopilot::core::estimator::GeoOrigin;
use mavlink::dialects::common::FailureType;
use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::sensors::{BaroSample, GpsSample, SensorSample};
use super::{stream, stream_rng};

/// Half-range of an accelerometer reading garbage, per axis (m/s²): 16 g, the full scale of a typical
/// MEMS accelerometer.
pub const ACCEL_GARBAGE_MPS2: f64 = 16.0 * 9.806_65;
/// Half-range of a gyro reading garbage, per axis (rad/s): about 2000 deg/s, a typical full scale.
pub const GYRO_GARBAGE_RADPS: f64 = 35.0;

/// A sensor's fault, numbered as MAVLink's `FAILURE_TYPE` (0 OK .. 4 WRONG).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Fault {
    /// Working (FAILURE_TYPE_OK, 0).
    #[default]
    Ok,
    /// Absent (FAILURE_TYPE_OFF, 1).
    Off,
    /// Repeats its last value (FAILURE_TYPE_STUCK, 2).
    Stuck,
    /// Random readings in its range (FAILURE_TYPE_GARBAGE, 3).
    Garbage,
    /// Plausible but wrong readings (FAILURE_TYPE_WRONG, 4): the GPS's position jump.
    Wrong,
}

impl Fault {
    /// Every fault, in `FAILURE_TYPE` order.
    pub const ALL: [Self; 5] = [Self::Ok, Self::Off, Self::Stuck, Self::Garbage, Self::Wrong];

    /// The fault of a MAVLink `FAILURE_TYPE` (OK .. WRONG); `None` for any other (SLOW, DELAYED,
    /// INTERMITTENT and DRIFT are not simulated).
    #[must_use]
    pub fn from_mavlink(failure_type: FailureType) -> Option<Self> {
        match failure_type {
            FailureType::FAILURE_TYPE_OK => Some(Self::Ok),
            FailureType::FAILURE_TYPE_OFF => Some(Self::Off),
            FailureType::FAILURE_TYPE_STUCK => Some(Self::Stuck),
            FailureType::FAILURE_TYPE_GARBAGE => Some(Self::Garbage),
            FailureType::FAILURE_TYPE_WRONG => Some(Self::Wrong),
            _ => None,
        }
    }

    /// Its MAVLink `FAILURE_TYPE`.
    #[must_use]
    pub fn mavlink(self) -> FailureType {
        match self {
            Self::Ok => FailureType::FAILURE_TYPE_OK,
            Self::Off => FailureType::FAILURE_TYPE_OFF,
            Self::Stuck => FailureType::FAILURE_TYPE_STUCK,
            Self::Garbage => FailureType::FAILURE_TYPE_GARBAGE,
            Self::Wrong => FailureType::FAILURE_TYPE_WRONG,
        }
    }

    /// The fault of a MAVLink `FAILURE_TYPE` number (0..4, as a SIM_*_FAIL parameter holds it); `None` for
    /// any other.
    #[must_use]
    pub fn from_failure_type(value: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.mavlink() as u32 == value)
    }

    /// Its MAVLink `FAILURE_TYPE` number.
    #[must_use]
    pub fn failure_type(self) -> u8 {
        self.mavlink() as u8
    }

    /// Lowercase name, for texts ("ok", "off", "stuck", "garbage", "wrong").
    #[must_use]
    pub fn word(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Off => "off",
            Self::Stuck => "stuck",
            Self::Garbage => "garbage",
            Self::Wrong => "wrong",
        }
    }
}

/// A sensor the plant can fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sensor {
    Gps,
    Baro,
    Mag,
    Accel,
    Gyro,
}

impl Sensor {
    /// Every sensor, in SIM_ parameter order.
    pub const ALL: [Self; 5] = [Self::Gps, Self::Baro, Self::Mag, Self::Accel, Self::Gyro];

    /// The name used in texts ("GPS", "baro", "mag", "accel", "gyro").
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Gps => "GPS",
            Self::Baro => "baro",
            Self::Mag => "mag",
            Self::Accel => "accel",
            Self::Gyro => "gyro",
        }
    }

    /// The faults this sensor has (OK first).
    #[must_use]
    pub fn faults(self) -> &'static [Fault] {
        match self {
            Self::Gps => &[Fault::Ok, Fault::Off, Fault::Stuck, Fault::Wrong],
            Self::Baro | Self::Mag => &[Fault::Ok, Fault::Off, Fault::Stuck],
            Self::Accel | Self::Gyro => &[Fault::Ok, Fault::Stuck, Fault::Garbage],
        }
    }
}

/// A fault refused: the sensor does not have it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{sensor} has no {fault} failure (it has: {known})", sensor = .sensor.name(), fault = .fault.word())]
pub struct FaultError {
    pub sensor: Sensor,
    pub fault: Fault,
    /// The faults it has, as "0 ok, 1 off, ...".
    pub known: String,
}

/// The faults of every sensor and what a stuck sensor repeats. See the module docs.
#[derive(Debug, Clone)]
pub struct SensorFaults {
    gps: Fault,
    baro: Fault,
    mag: Fault,
    accel: Fault,
    gyro: Fault,
    /// The wrong GPS's offset (m, north and east).
    gps_jump_ne_m: [f64; 2],
    /// The last clean value of each sensor (what a sensor that sticks now repeats).
    last_accel: Option<Vector3<f64>>,
    last_gyro: Option<Vector3<f64>>,
    last_mag: Option<Vector3<f64>>,
    last_baro: Option<BaroSample>,
    last_gps: Option<GpsSample>,
    /// What each stuck sensor repeats (taken at its first sample after it stuck).
    held_accel: Option<Vector3<f64>>,
    held_gyro: Option<Vector3<f64>>,
    held_mag: Option<Vector3<f64>>,
    held_baro: Option<BaroSample>,
    held_gps: Option<GpsSample>,
    accel_garbage_rng: ChaCha8Rng,
    gyro_garbage_rng: ChaCha8Rng,
}

/// The default jump of a wrong GPS (m, north and east): 50 m north, as the SIM_GPS_JUMP_N/E defaults.
pub const DEFAULT_GPS_JUMP_NE_M: [f64; 2] = [50.0, 0.0];

impl SensorFaults {
    /// No faults; garbage from the streams of plant seed `seed`.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self {
            gps: Fault::Ok,
            baro: Fault::Ok,
            mag: Fault::Ok,
            accel: Fault::Ok,
            gyro: Fault::Ok,
            gps_jump_ne_m: DEFAULT_GPS_JUMP_NE_M,
            last_accel: None,
            last_gyro: None,
            last_mag: None,
            last_baro: None,
            last_gps: None,
            held_accel: None,
            held_gyro: None,
            held_mag: None,
            held_baro: None,
            held_gps: None,
            accel_garbage_rng: stream_rng(seed, stream::ACCEL_GARBAGE),
            gyro_garbage_rng: stream_rng(seed, stream::GYRO_GARBAGE),
        }
    }

    /// The fault of `sensor` now.
    #[must_use]
    pub fn fault(&self, sensor: Sensor) -> Fault {
        match sensor {
            Sensor::Gps => self.gps,
            Sensor::Baro => self.baro,
            Sensor::Mag => self.mag,
            Sensor::Accel => self.accel,
            Sensor::Gyro => self.gyro,
        }
    }

    /// Whether every sensor works.
    #[must_use]
    pub fn all_ok(&self) -> bool {
        Sensor::ALL.iter().all(|s| self.fault(*s) == Fault::Ok)
    }

    /// Fail `sensor` with `fault` from the next sample on (`Fault::Ok` clears it). A stuck sensor repeats
    /// the last value it gave before this call; setting the fault it already has changes nothing (a stuck
    /// sensor stays stuck on the same value).
    ///
    /// # Errors
    /// [`FaultError`] when the sensor does not have `fault`; nothing changes then.
    pub fn set(&mut self, sensor: Sensor, fault: Fault) -> Result<(), FaultError> {
        if !sensor.faults().contains(&fault) {
            let known =
                sensor.faults().iter().map(|f| format!("{} {}", f.failure_type(), f.word())).collect::<Vec<_>>();
            return Err(FaultError { sensor, fault, known: known.join(", ") });
        }
        if self.fault(sensor) == fault {
            return Ok(());
        }
        match sensor {
            Sensor::Gps => (self.gps, self.held_gps) = (fault, None),
            Sensor::Baro => (self.baro, self.held_baro) = (fault, None),
            Sensor::Mag => (self.mag, self.held_mag) = (fault, None),
            Sensor::Accel => (self.accel, self.held_accel) = (fault, None),
            Sensor::Gyro => (self.gyro, self.held_gyro) = (fault, None),
        }
        Ok(())
    }

    /// The wrong GPS's offset (m, north and east).
    #[must_use]
    pub fn gps_jump_ne_m(&self) -> [f64; 2] {
        self.gps_jump_ne_m
    }

    /// Set the wrong GPS's offset (m, north and east; non-finite values are taken as 0).
    pub fn set_gps_jump_ne_m(&mut self, jump_ne_m: [f64; 2]) {
        self.gps_jump_ne_m = jump_ne_m.map(|x| if x.is_finite() { x } else { 0.0 });
    }

    /// The sample the board reports for the clean sample `clean` (GPS positions mapped about `home`).
    pub fn apply(&mut self, clean: &SensorSample, home: &GeoOrigin) -> SensorSample {
        let mut out = *clean;
        out.accel_frd_mps2 = match self.accel {
            Fault::Stuck => *self.held_accel.get_or_insert(self.last_accel.unwrap_or(clean.accel_frd_mps2)),
            Fault::Garbage => uniform3(&mut self.accel_garbage_rng, ACCEL_GARBAGE_MPS2),
            _ => clean.accel_frd_mps2,
        };
        out.gyro_frd_radps = match self.gyro {
            Fault::Stuck => *self.held_gyro.get_or_insert(self.last_gyro.unwrap_or(clean.gyro_frd_radps)),
            Fault::Garbage => uniform3(&mut self.gyro_garbage_rng, GYRO_GARBAGE_RADPS),
            _ => clean.gyro_frd_radps,
        };
        out.mag_frd_gauss = match self.mag {
            Fault::Off => None,
            Fault::Stuck => clean.mag_frd_gauss.map(|m| *self.held_mag.get_or_insert(self.last_mag.unwrap_or(m))),
            _ => clean.mag_frd_gauss,
        };
        out.baro = match self.baro {
            Fault::Off => None,
            Fault::Stuck => clean.baro.map(|b| *self.held_baro.get_or_insert(self.last_baro.unwrap_or(b))),
            _ => clean.baro,
        };
        out.gps = match (self.gps, clean.gps) {
            (_, None) | (Fault::Off, _) => None,
            (Fault::Stuck, Some(fix)) => {
                let held = *self.held_gps.get_or_insert(self.last_gps.unwrap_or(fix));
                Some(GpsSample { time_us: fix.time_us, ..held })
            }
            (Fault::Wrong, Some(fix)) => Some(jumped(&fix, self.gps_jump_ne_m, home)),
            (_, Some(fix)) => Some(fix),
        };
        self.last_accel = Some(clean.accel_frd_mps2);
        self.last_gyro = Some(clean.gyro_frd_radps);
        self.last_mag = clean.mag_frd_gauss.or(self.last_mag);
        self.last_baro = clean.baro.or(self.last_baro);
        self.last_gps = clean.gps.or(self.last_gps);
        out
    }
}

/// Each axis uniform in [-half, half].
fn uniform3(rng: &mut ChaCha8Rng, half: f64) -> Vector3<f64> {
    Vector3::from_fn(|_, _| rng.random_range(-half..=half))
}

/// `fix` with its position moved by `jump_ne_m` (m north, east) through the map about `home`.
fn jumped(fix: &GpsSample, jump_ne_m: [f64; 2], home: &GeoOrigin) -> GpsSample {
    let ned = home.ned_from_geodetic(fix.lat_deg, fix.lon_deg, fix.alt_amsl_m)
        + Vector3::new(jump_ne_m[0], jump_ne_m[1], 0.0);
    let (lat_deg, lon_deg, alt_amsl_m) = home.geodetic_from_ned(&ned);
    GpsSample { lat_deg, lon_deg, alt_amsl_m, ..*fix }
}

/// Impairments of the plant link's sensor datagrams to the autopilot (SIM_LINK_DELAY,
/// SIM_LINK_LOSS), applied by the plant link (see `link` for how they keep the lockstep going): the
/// added delay, and the chance that a datagram is lost, drawn once per plant step while it is above 0 from
/// the plant seed's own stream [`super::stream::LINK_LOSS`].
#[derive(Debug, Clone)]
pub struct LinkFaults {
    delay_us: u64,
    loss_pct: f64,
    rng: ChaCha8Rng,
}

impl LinkFaults {
    /// No delay, no loss; losses drawn from the stream of plant seed `seed`.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self { delay_us: 0, loss_pct: 0.0, rng: stream_rng(seed, stream::LINK_LOSS) }
    }

    /// The added delay (µs).
    #[must_use]
    pub fn delay_us(&self) -> u64 {
        self.delay_us
    }

    /// Set the added delay (µs) from the next plant step.
    pub fn set_delay_us(&mut self, delay_us: u64) {
        self.delay_us = delay_us;
    }

    /// The chance that a sensor datagram is lost (%).
    #[must_use]
    pub fn loss_pct(&self) -> f64 {
        self.loss_pct
    }

    /// Set the chance of loss (%, clamped to 0..100; not finite: 0) from the next plant step.
    pub fn set_loss_pct(&mut self, loss_pct: f64) {
        self.loss_pct = if loss_pct.is_finite() { loss_pct.clamp(0.0, 100.0) } else { 0.0 };
    }

    /// Neither delay nor loss.
    #[must_use]
    pub fn is_clear(&self) -> bool {
        self.delay_us == 0 && self.loss_pct <= 0.0
    }

    /// Whether this step's datagram is lost: one draw per call while the loss is above 0, none otherwise.
    pub fn draw_lost(&mut self) -> bool {
        self.loss_pct > 0.0 && self.rng.random::<f64>() * 100.0 < self.loss_pct
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::plant::Plant;
    use crate::plant::testing::run;

    fn home() -> GeoOrigin {
        crate::plant::sensors::HomeConfig::default().origin()
    }

    #[test]
    fn given_no_fault_then_the_samples_are_the_clean_ones() {
        let clean = run(300, |_, _| {});
        assert!(clean.iter().all(|s| s.mag_frd_gauss.is_some() && s.baro.is_some()));
        assert_eq!(clean.iter().filter(|s| s.gps.is_some()).count(), 6, "10 Hz over 0.6 s");
    }

    #[test]
    fn given_gps_off_then_no_fix_is_released_until_it_is_cleared_and_then_the_fixes_are_the_clean_ones() {
        let clean = run(500, |_, _| {});
        let set = |k: usize, plant: &mut Plant| match k {
            150 => plant.sensor_faults_mut().set(Sensor::Gps, Fault::Off).expect("GPS off"),
            350 => plant.sensor_faults_mut().set(Sensor::Gps, Fault::Ok).expect("GPS ok"),
            _ => {}
        };
        let faulty = run(500, set);
        for (k, (f, c)) in faulty.iter().zip(&clean).enumerate() {
            if (150..350).contains(&k) {
                assert_eq!(f.gps, None, "no fix at sample {k}");
                assert_eq!(SensorSample { gps: None, ..*f }, SensorSample { gps: None, ..*c }, "the rest unchanged");
            } else {
                assert_eq!(f, c, "sample {k} as without the fault");
            }
        }
        assert_eq!(faulty.iter().filter(|s| s.gps.is_some()).count(), 6, "fixes at 0, .., 0.2 and 0.7, .., 0.9 s");
    }

    #[test]
    fn given_gps_stuck_then_every_fix_repeats_the_last_one_with_its_own_time() {
        let clean = run(500, |_, _| {});
        let faulty = run(500, |k, plant| {
            if k == 160 {
                plant.sensor_faults_mut().set(Sensor::Gps, Fault::Stuck).expect("stuck");
            }
        });
        let last_before = clean[150].gps.expect("the fix at 0.3 s");
        let stuck: Vec<GpsSample> = faulty[160..].iter().filter_map(|s| s.gps).collect();
        let times: Vec<u64> = (4..10).map(|k| k * 100_000).collect();
        assert_eq!(stuck.iter().map(|f| f.time_us).collect::<Vec<_>>(), times, "10 Hz on: 0.4 .. 0.9 s");
        for (fix, &t_us) in stuck.iter().zip(&times) {
            assert_eq!(*fix, GpsSample { time_us: t_us, ..last_before }, "the 0.3 s fix, bit for bit, new time");
        }
        // The vehicle moved meanwhile, so a repeated fix is distinguishable from a fresh one.
        let fresh = clean[400].gps.expect("fix");
        assert!((fresh.lat_deg - last_before.lat_deg).abs() > 1e-6, "{fresh:?}");
    }

    #[test]
    fn given_gps_wrong_then_each_fix_is_moved_by_the_jump_and_nothing_else() {
        let clean = run(300, |_, _| {});
        let faulty = run(300, |k, plant| match k {
            0 => plant.sensor_faults_mut().set(Sensor::Gps, Fault::Wrong).expect("wrong"),
            100 => plant.sensor_faults_mut().set_gps_jump_ne_m([-20.0, 30.0]),
            _ => {}
        });
        let home = home();
        let mut checked = 0;
        for (k, (f, c)) in faulty.iter().zip(&clean).enumerate() {
            let (Some(f), Some(c)) = (f.gps, c.gps) else {
                assert_eq!(f.gps.is_some(), c.gps.is_some());
                continue;
            };
            let want = if k < 100 { Vector3::new(50.0, 0.0, 0.0) } else { Vector3::new(-20.0, 30.0, 0.0) };
            let jump = home.ned_from_geodetic(f.lat_deg, f.lon_deg, f.alt_amsl_m)
                - home.ned_from_geodetic(c.lat_deg, c.lon_deg, c.alt_amsl_m);
            assert!((jump - want).norm() < 1e-6, "sample {k}: jumped {jump:?}, want {want:?}");
            assert_eq!(
                (f.time_us, f.vel_ned_mps, f.eph_m, f.fix_type),
                (c.time_us, c.vel_ned_mps, c.eph_m, c.fix_type)
            );
            checked += 1;
        }
        assert_eq!(checked, 6);
    }

    #[test]
    fn given_imu_mag_and_baro_stuck_then_each_repeats_its_last_value_bit_for_bit_with_fresh_times() {
        let faulty = run(200, |k, plant| {
            if k == 100 {
                for sensor in [Sensor::Accel, Sensor::Gyro, Sensor::Mag, Sensor::Baro] {
                    plant.sensor_faults_mut().set(sensor, Fault::Stuck).expect("stuck");
                }
            }
        });
        let before = faulty[99];
        for (k, s) in faulty.iter().enumerate().skip(100) {
            assert_eq!(s.time_us, k as u64 * 2000, "a fresh time stamp");
            assert_eq!(s.accel_frd_mps2, before.accel_frd_mps2);
            assert_eq!(s.gyro_frd_radps, before.gyro_frd_radps);
            assert_eq!(s.mag_frd_gauss, before.mag_frd_gauss);
            assert_eq!(s.baro, before.baro);
        }
        // Without the fault the noisy readings differ from sample to sample.
        let clean = run(200, |_, _| {});
        assert_ne!(clean[150].accel_frd_mps2, clean[99].accel_frd_mps2);
        assert_ne!(clean[150].baro, clean[99].baro);
    }

    #[test]
    fn given_accel_and_gyro_garbage_then_each_axis_is_uniform_within_its_range_and_reruns_are_identical() {
        let n = 20_000;
        let garbage = |k: usize, plant: &mut Plant| {
            if k == 0 {
                plant.sensor_faults_mut().set(Sensor::Accel, Fault::Garbage).expect("accel garbage");
                plant.sensor_faults_mut().set(Sensor::Gyro, Fault::Garbage).expect("gyro garbage");
            }
        };
        let samples = run(n, garbage);
        for (name, half, axis) in [
            ("accel", ACCEL_GARBAGE_MPS2, samples.iter().map(|s| s.accel_frd_mps2.y).collect::<Vec<_>>()),
            ("gyro", GYRO_GARBAGE_RADPS, samples.iter().map(|s| s.gyro_frd_radps.z).collect::<Vec<_>>()),
        ] {
            assert!(axis.iter().all(|x| x.abs() <= half), "{name} within ±{half}");
            let mean = axis.iter().sum::<f64>() / n as f64;
            let sd = (axis.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
            // Uniform on [-h, h]: mean 0, standard deviation h/sqrt(3).
            assert!(mean.abs() < 0.03 * half, "{name} mean {mean}");
            assert!((sd / (half / 3.0_f64.sqrt()) - 1.0).abs() < 0.03, "{name} sd {sd}");
            assert!(axis.iter().any(|x| x.abs() > 0.99 * half), "{name} spans its range");
        }
        assert_eq!(run(n, garbage), samples, "the same seed draws the same garbage");
        // The garbage has its own streams: every other sensor reads as without the fault.
        let clean = run(n, |_, _| {});
        for (f, c) in samples.iter().zip(&clean) {
            assert_eq!((f.mag_frd_gauss, f.baro, f.gps), (c.mag_frd_gauss, c.baro, c.gps));
        }
    }

    #[test]
    fn given_a_fault_cleared_then_the_sensors_read_exactly_as_if_it_never_happened() {
        let clean = run(400, |_, _| {});
        let faulty = run(400, |k, plant| {
            let faults = plant.sensor_faults_mut();
            let (fault_imu, fault_other) = match k {
                50 => (Fault::Garbage, Fault::Stuck),
                120 => (Fault::Stuck, Fault::Off),
                200 => (Fault::Ok, Fault::Ok),
                _ => return,
            };
            for sensor in [Sensor::Accel, Sensor::Gyro] {
                faults.set(sensor, fault_imu).expect("imu fault");
            }
            for sensor in [Sensor::Gps, Sensor::Baro, Sensor::Mag] {
                faults.set(sensor, fault_other).expect("fault");
            }
        });
        assert_ne!(faulty[50..200], clean[50..200]);
        assert_eq!(faulty[200..], clean[200..], "from the clear on, the clean samples");
    }

    #[test]
    fn given_a_fault_a_sensor_does_not_have_then_it_is_refused_naming_the_ones_it_has_and_nothing_changes() {
        let mut faults = SensorFaults::new(1);
        faults.set(Sensor::Accel, Fault::Stuck).expect("stuck");
        let err = faults.set(Sensor::Accel, Fault::Off).expect_err("IMU off is not simulated");
        assert_eq!(err.to_string(), "accel has no off failure (it has: 0 ok, 2 stuck, 3 garbage)");
        assert_eq!(faults.fault(Sensor::Accel), Fault::Stuck);
        let err = faults.set(Sensor::Gps, Fault::Garbage).expect_err("no GPS garbage");
        assert_eq!(err.to_string(), "GPS has no garbage failure (it has: 0 ok, 1 off, 2 stuck, 4 wrong)");
        assert!(faults.set(Sensor::Baro, Fault::Wrong).is_err() && faults.set(Sensor::Gyro, Fault::Off).is_err());
        assert_eq!(faults.fault(Sensor::Gps), Fault::Ok);
        for n in 0..=4 {
            assert_eq!(Fault::from_failure_type(n).map(Fault::failure_type), Some(n as u8));
        }
        assert_eq!(Fault::from_failure_type(5), None, "SLOW is not simulated");
    }

    #[test]
    fn given_link_loss_then_the_draws_are_the_seeds_and_none_are_drawn_without_loss() {
        let draws = |seed: u64| {
            let mut link = LinkFaults::new(seed);
            let none: Vec<bool> = (0..100).map(|_| link.draw_lost()).collect();
            link.set_loss_pct(25.0);
            let some: Vec<bool> = (0..10_000).map(|_| link.draw_lost()).collect();
            (none, some)
        };
        let (none, some) = draws(3);
        assert!(none.iter().all(|lost| !lost), "no loss, no draw");
        let lost = some.iter().filter(|l| **l).count();
        assert!((2300..=2700).contains(&lost), "{lost} of 10000 at 25 %");
        assert_eq!(draws(3).1, some, "the same seed loses the same datagrams");
        assert_ne!(draws(4).1, some);
        let mut link = LinkFaults::new(1);
        link.set_loss_pct(f64::NAN);
        assert!(link.is_clear());
    }
}
