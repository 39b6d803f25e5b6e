//! The fused estimator's sensor policy around the [`Eskf`]: alignment, GPS origin and latency handling,
//! barometer offset, magnetometer heading, no-aiding fallback, sensor health and the validity /
//! convergence flags. In: sanitised samples (see `Estimator`); time is the IMU/GPS `time_us` (µs), samples
//! without a time stamp (mag, baro) are taken at the latest time seen. Out: an [`EstimatorState`] after
//! every sample. Rate: the IMU rate; the other sensors at their own rates. The GPS's fusion is in `gps`,
//! the magnetometer's heading fusion in `mag`. Each source's health (lost, stuck, rejected; see `health`)
//! is judged here at every sample, and a faulted source is not fused: a stuck GPS, barometer or
//! magnetometer's samples are skipped, a rejected GPS does not reset the state to itself.

use nalgebra::{UnitQuaternion, Vector3};

use super::eskf::{ErrVec, Eskf, Nominal, Outcome, ProcessNoise, ScalarObs, idx};
use super::health::{
    AIDING_MOTION, EstimatorEvent, HeightSource, IMU_MOTION, IMU_REFUSED_CLEAR, IMU_REFUSED_FLAG, IMU_REFUSED_WINDOW,
    IMU_ROTATION, IMU_STUCK_MIN_REPEATS, MAX_PENDING_EVENTS, STUCK_MIN_REPEATS, Source, SourceFault, SourceHealth,
    StuckDetector,
};
use super::history::History;
use super::{BaroSample, EstimatorConfig, EstimatorFlags, EstimatorState, GeoOrigin, ImuSample, Innovations};

mod gps;
mod mag;

/// Period of the no-aiding pseudo-measurement (µs of vehicle time).
const FAKE_POS_PERIOD_US: u64 = 100_000;
/// Largest variances kept (the filter stays numerically sane through long sensor outages).
const MAX_POS_VAR_M2: f64 = 1.0e6;
const MAX_VEL_VAR_M2PS2: f64 = 1.0e4;
const MAX_ATT_VAR_RAD2: f64 = 1.0;
const MAX_BARO_VAR_M2: f64 = 1.0e6;

/// Seconds (config) to microseconds; negative and non-finite map to 0.
fn us(seconds: f64) -> u64 {
    if seconds > 0.0 { (seconds * 1e6).round() as u64 } else { 0 }
}

/// Sums of the samples seen while the vehicle is assumed still, for the initial attitude.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Alignment {
    start_us: u64,
    accel_sum_frd_mps2: Vector3<f64>,
    accel_count: u32,
    mag_sum_frd_gauss: Vector3<f64>,
    mag_count: u32,
}

/// Either aligning (no attitude yet) or running the filter.
#[derive(Debug, Clone, PartialEq)]
enum Stage {
    Aligning(Option<Alignment>),
    Running(Box<Eskf>),
}

/// The fused estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct Fusion {
    config: EstimatorConfig,
    noise: ProcessNoise,
    stage: Stage,
    history: History,
    origin: Option<GeoOrigin>,
    /// `tan(inclination)` of the earth field, measured when the heading was aligned to the magnetometer.
    field_tan_incl: f64,
    yaw_aligned: bool,
    /// Latest time seen (µs).
    now_us: Option<u64>,
    last_imu_us: Option<u64>,
    last_imu: Option<ImuSample>,
    last_gps_fused_us: Option<u64>,
    last_baro_fused_us: Option<u64>,
    last_mag_fused_us: Option<u64>,
    gps_aiding_since_us: Option<u64>,
    mag_rejected_since_us: Option<u64>,
    last_vel_nis_us: Option<u64>,
    vel_nis_lp: f64,
    attitude_settled_since_us: Option<u64>,
    /// Where the no-aiding pseudo-measurement holds the horizontal position, while it is active.
    fake_pos_hold_ne_m: Option<(f64, f64)>,
    last_fake_pos_us: Option<u64>,
    /// Measurements rejected by the innovation gate.
    gated: u64,
    /// The latest innovation of each measurement, fused or gated.
    innovations: Innovations,
    state: EstimatorState,
    /// When each source last delivered a usable sample (µs), for the lost check.
    last_gps_rx_us: Option<u64>,
    last_baro_rx_us: Option<u64>,
    last_mag_rx_us: Option<u64>,
    /// First of the GPS positions refused by the gate since the last fused one.
    gps_rejected_since_us: Option<u64>,
    /// Stuck detectors: GPS (position, velocity), barometer and magnetometer witnessed by the IMU; the
    /// IMU (specific force, rates) witnessed by the magnetometer and barometer.
    gps_stuck: StuckDetector<6, 6>,
    baro_stuck: StuckDetector<1, 6>,
    mag_stuck: StuckDetector<3, 6>,
    /// The accelerometer and the gyro are judged apart: one can freeze while the other lives.
    accel_stuck: StuckDetector<3, 4>,
    gyro_stuck: StuckDetector<3, 4>,
    /// Latest magnetometer field (gauss) and barometric altitude (m).
    last_mag_gauss: Option<[f64; 3]>,
    last_baro_m: Option<f64>,
    /// Share of recent IMU samples the sanitiser refused (moving average), and whether it flagged.
    imu_refused_ratio: f64,
    imu_refused: bool,
    /// The health last announced, and the announcements not yet drained.
    health: SourceHealth,
    events: Vec<EstimatorEvent>,
}

/// Why a sample was refused after sanitising (the caller counts these as rejected).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// IMU time not after the previous IMU time.
    NonMonotonicTime,
    /// GPS valid before the history begins: it cannot be compared with the state of its time.
    TooOld,
}

impl Fusion {
    pub fn new(config: &EstimatorConfig) -> Self {
        let noise = ProcessNoise {
            accel_mps2: config.accel_noise_mps2,
            gyro_radps: config.gyro_noise_radps,
            accel_bias_walk: config.accel_bias_walk_mps2_per_sqrt_s,
            gyro_bias_walk: config.gyro_bias_walk_radps_per_sqrt_s,
            baro_offset_walk: config.baro_offset_walk_m_per_sqrt_s,
        };
        Self {
            config: config.clone(),
            noise,
            stage: Stage::Aligning(None),
            history: History::default(),
            origin: None,
            field_tan_incl: 0.0,
            yaw_aligned: false,
            now_us: None,
            last_imu_us: None,
            last_imu: None,
            last_gps_fused_us: None,
            last_baro_fused_us: None,
            last_mag_fused_us: None,
            gps_aiding_since_us: None,
            mag_rejected_since_us: None,
            last_vel_nis_us: None,
            vel_nis_lp: 0.0,
            attitude_settled_since_us: None,
            fake_pos_hold_ne_m: None,
            last_fake_pos_us: None,
            gated: 0,
            innovations: Innovations::default(),
            state: EstimatorState::default(),
            last_gps_rx_us: None,
            last_baro_rx_us: None,
            last_mag_rx_us: None,
            gps_rejected_since_us: None,
            gps_stuck: StuckDetector::default(),
            baro_stuck: StuckDetector::default(),
            mag_stuck: StuckDetector::default(),
            accel_stuck: StuckDetector::default(),
            gyro_stuck: StuckDetector::default(),
            last_mag_gauss: None,
            last_baro_m: None,
            imu_refused_ratio: 0.0,
            imu_refused: false,
            health: SourceHealth::default(),
            events: Vec::new(),
        }
    }

    /// The health changes not yet drained, oldest first.
    pub fn take_events(&mut self) -> Vec<EstimatorEvent> {
        std::mem::take(&mut self.events)
    }

    /// The IMU's latest reading, as the witness of the other sources' stuck detectors.
    fn imu_witness(&self) -> [f64; 6] {
        self.last_imu.map_or([f64::NAN; 6], |imu| {
            let (a, w) = (imu.accel_frd_mps2, imu.gyro_frd_radps);
            [a.x, a.y, a.z, w.x, w.y, w.z]
        })
    }

    /// The magnetometer's and barometer's latest readings, as the IMU stuck detector's witness.
    fn aiding_witness(&self) -> [f64; 4] {
        let [x, y, z] = self.last_mag_gauss.unwrap_or([f64::NAN; 3]);
        [x, y, z, self.last_baro_m.unwrap_or(f64::NAN)]
    }

    /// An IMU sample was refused by the sanitiser (or for its time): counts towards "rejected".
    pub fn note_imu_refused(&mut self) {
        self.note_imu_outcome(true);
        self.refresh();
    }

    fn note_imu_outcome(&mut self, refused: bool) {
        let target = if refused { 1.0 } else { 0.0 };
        self.imu_refused_ratio += (target - self.imu_refused_ratio) / IMU_REFUSED_WINDOW;
        if self.imu_refused_ratio > IMU_REFUSED_FLAG {
            self.imu_refused = true;
        } else if self.imu_refused_ratio < IMU_REFUSED_CLEAR {
            self.imu_refused = false;
        }
    }

    pub fn state(&self) -> &EstimatorState {
        &self.state
    }

    /// The latest innovation of each measurement (NaN until one was compared).
    pub fn innovations(&self) -> &Innovations {
        &self.innovations
    }

    pub fn gated_measurements(&self) -> u64 {
        self.gated
    }

    fn advance(&mut self, time_us: u64) {
        self.now_us = Some(self.now_us.map_or(time_us, |now| now.max(time_us)));
    }

    fn age_us(&self, then_us: Option<u64>) -> Option<u64> {
        match (self.now_us, then_us) {
            (Some(now), Some(then)) => Some(now.saturating_sub(then)),
            _ => None,
        }
    }

    fn fresh(&self, then_us: Option<u64>, timeout_s: f64) -> bool {
        self.age_us(then_us).is_some_and(|age| age <= us(timeout_s))
    }

    fn imu_ok(&self) -> bool {
        self.fresh(self.last_imu_us, self.config.imu_timeout_s)
    }

    /// A GPS position was fused within the timeout.
    fn gps_fresh(&self) -> bool {
        self.fresh(self.last_gps_fused_us, self.config.gps_timeout_s)
    }

    fn baro_fresh(&self) -> bool {
        self.fresh(self.last_baro_fused_us, self.config.baro_timeout_s)
    }

    pub(super) fn mag_fresh(&self) -> bool {
        self.fresh(self.last_mag_fused_us, self.config.mag_timeout_s)
    }

    /// A source that delivered a sample once and has been silent beyond `timeout_s`.
    fn lost(&self, last_rx_us: Option<u64>, timeout_s: f64) -> bool {
        last_rx_us.is_some() && !self.fresh(last_rx_us, timeout_s)
    }

    /// Advances the clock without a sample (timeouts only).
    pub fn update_clock(&mut self, now_us: u64) {
        self.advance(now_us);
        self.refresh();
    }

    // ---------------------------------------------------------------------------------------------
    // IMU: alignment, prediction, no-aiding fallback
    // ---------------------------------------------------------------------------------------------

    pub fn update_imu(&mut self, imu: &ImuSample) -> Result<(), Refused> {
        if self.last_imu_us.is_some_and(|last| imu.time_us <= last) {
            return Err(Refused::NonMonotonicTime);
        }
        let gap_us = self.last_imu_us.map(|last| imu.time_us - last);
        self.advance(imu.time_us);
        self.last_imu_us = Some(imu.time_us);
        self.last_imu = Some(*imu);
        self.note_imu_outcome(false);
        let (a, w) = (imu.accel_frd_mps2, imu.gyro_frd_radps);
        let imu_values = [a.x, a.y, a.z, w.x, w.y, w.z];
        let witness = self.aiding_witness();
        let imu_stuck_us = us(self.config.imu_stuck_time_s);
        self.accel_stuck.observe([a.x, a.y, a.z], imu.time_us, witness, IMU_STUCK_MIN_REPEATS, imu_stuck_us);
        self.gyro_stuck.observe([w.x, w.y, w.z], imu.time_us, witness, IMU_STUCK_MIN_REPEATS, imu_stuck_us);
        self.gps_stuck.witness(imu_values, &IMU_MOTION);
        self.baro_stuck.witness(imu_values, &IMU_MOTION);
        self.mag_stuck.witness(imu_values, &IMU_ROTATION);
        let imu_timeout_us = us(self.config.imu_timeout_s);

        match &mut self.stage {
            Stage::Aligning(alignment) => {
                let restart = gap_us.is_some_and(|gap| gap > imu_timeout_us);
                let a = match alignment {
                    Some(a) if !restart => a,
                    _ => alignment.insert(Alignment {
                        start_us: imu.time_us,
                        accel_sum_frd_mps2: Vector3::zeros(),
                        accel_count: 0,
                        mag_sum_frd_gauss: Vector3::zeros(),
                        mag_count: 0,
                    }),
                };
                a.accel_sum_frd_mps2 += imu.accel_frd_mps2;
                a.accel_count += 1;
                if imu.time_us - a.start_us >= us(self.config.align_time_s) {
                    let a = *a;
                    self.finish_alignment(&a);
                }
            }
            Stage::Running(f) => {
                let gap_us = gap_us.unwrap_or(0);
                let dt_s = gap_us as f64 * 1e-6;
                if gap_us > imu_timeout_us {
                    // The IMU was lost: coast (constant velocity and attitude) and let the covariance grow.
                    let hover_frd = f.x.q_ned_frd.inverse() * Vector3::new(0.0, 0.0, -super::eskf::GRAVITY_MPS2);
                    let (gyro, accel) = (f.x.gyro_bias_frd_radps, hover_frd + f.x.accel_bias_frd_mps2);
                    f.predict(dt_s, &gyro, &accel, &self.noise);
                } else {
                    f.predict(dt_s, &imu.gyro_frd_radps, &imu.accel_frd_mps2, &self.noise);
                }
                for i in 0..3 {
                    f.cap_variance(idx::POS + i, MAX_POS_VAR_M2);
                    f.cap_variance(idx::VEL + i, MAX_VEL_VAR_M2PS2);
                    f.cap_variance(idx::ATT + i, MAX_ATT_VAR_RAD2);
                    f.cap_variance(idx::ACC_BIAS + i, self.config.init_accel_bias_std_mps2.powi(2));
                    f.cap_variance(idx::GYRO_BIAS + i, self.config.init_gyro_bias_std_radps.powi(2));
                }
                f.cap_variance(idx::BARO, MAX_BARO_VAR_M2);
                self.history.push(imu.time_us, &f.x.pos_ned_m, &f.x.vel_ned_mps);
                self.fuse_fake_position();
            }
        }
        self.refresh();
        Ok(())
    }

    /// Roll and pitch from the mean specific force (the vehicle is assumed still while aligning), yaw
    /// from the mean magnetic field when there is one.
    fn finish_alignment(&mut self, a: &Alignment) {
        let mean_force_frd = a.accel_sum_frd_mps2 / f64::from(a.accel_count);
        let norm = mean_force_frd.norm();
        let g = super::eskf::GRAVITY_MPS2;
        if !(norm > 0.5 * g && norm < 1.5 * g) {
            // Not still (or in free fall): start again.
            self.stage = Stage::Aligning(None);
            return;
        }
        let down_frd = -mean_force_frd / norm;
        let roll_rad = down_frd.y.atan2(down_frd.z);
        let pitch_rad = (-down_frd.x).atan2(down_frd.y.hypot(down_frd.z));
        let mut q = UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, 0.0);
        let mut yaw_var = std::f64::consts::PI.powi(2);
        if a.mag_count > 0 {
            let mean_mag_frd = a.mag_sum_frd_gauss / f64::from(a.mag_count);
            if let Some(yaw_rad) = self.mag_heading_rad(&q, &mean_mag_frd) {
                q = UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, yaw_rad);
                self.learn_inclination(&q, &mean_mag_frd);
                self.yaw_aligned = true;
                self.last_mag_fused_us = self.now_us;
                yaw_var = self.config.init_yaw_std_rad.powi(2);
            }
        }
        let x = Nominal {
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: q,
            accel_bias_frd_mps2: Vector3::zeros(),
            gyro_bias_frd_radps: Vector3::zeros(),
            baro_offset_m: 0.0,
        };
        let c = &self.config;
        let mut var = ErrVec::zeros();
        for i in 0..3 {
            var[idx::POS + i] = c.init_pos_std_m.powi(2);
            var[idx::VEL + i] = c.init_vel_std_mps.powi(2);
            var[idx::ATT + i] = c.init_tilt_std_rad.powi(2);
            var[idx::ACC_BIAS + i] = c.init_accel_bias_std_mps2.powi(2);
            var[idx::GYRO_BIAS + i] = c.init_gyro_bias_std_radps.powi(2);
        }
        var[idx::ATT + 2] = yaw_var;
        var[idx::BARO] = MAX_BARO_VAR_M2;
        self.stage = Stage::Running(Box::new(Eskf::new(x, &var)));
        self.history.clear();
        self.history.push(self.last_imu_us.unwrap_or(a.start_us), &x.pos_ned_m, &x.vel_ned_mps);
    }

    /// Holds the horizontal position while there is no horizontal aiding: before the first GPS fix (the
    /// vehicle is assumed on the ground, so tightly), and after `no_aid_timeout_s` without GPS in flight
    /// (loosely: it bounds the covariance and keeps the attitude observable without claiming a position).
    fn fuse_fake_position(&mut self) {
        let now = self.now_us.unwrap_or(0);
        let std_m = if self.gps_fresh() {
            None
        } else if self.origin.is_none() {
            Some(self.config.align_pos_noise_m)
        } else if self.last_gps_fused_us.is_none_or(|t| now.saturating_sub(t) > us(self.config.no_aid_timeout_s)) {
            Some(self.config.no_aid_pos_noise_m)
        } else {
            None
        };
        let Some(std_m) = std_m else {
            self.fake_pos_hold_ne_m = None;
            return;
        };
        if self.last_fake_pos_us.is_some_and(|t| now.saturating_sub(t) < FAKE_POS_PERIOD_US) {
            return;
        }
        let Stage::Running(f) = &mut self.stage else { return };
        self.last_fake_pos_us = Some(now);
        let (hold_n, hold_e) = *self.fake_pos_hold_ne_m.get_or_insert((f.x.pos_ned_m.x, f.x.pos_ned_m.y));
        let obs = [
            ScalarObs::direct(idx::POS, hold_n - f.x.pos_ned_m.x, std_m * std_m),
            ScalarObs::direct(idx::POS + 1, hold_e - f.x.pos_ned_m.y, std_m * std_m),
        ];
        if let Outcome::Fused { correction, .. } = f.fuse(&obs, f64::INFINITY) {
            Self::note_correction(&mut self.history, &correction);
        }
    }

    fn note_correction(history: &mut History, dx: &ErrVec) {
        history
            .add_correction(&Vector3::from(dx.fixed_rows::<3>(idx::POS)), &Vector3::from(dx.fixed_rows::<3>(idx::VEL)));
    }

    // ---------------------------------------------------------------------------------------------
    // Barometer: height with an estimated offset
    // ---------------------------------------------------------------------------------------------

    pub fn update_baro(&mut self, baro: &BaroSample) {
        let now = self.now_us.unwrap_or(0);
        self.last_baro_rx_us = Some(now);
        self.last_baro_m = Some(baro.pressure_alt_m);
        let (witness, stuck_us) = (self.imu_witness(), us(self.config.stuck_time_s));
        let stuck = self.baro_stuck.observe([baro.pressure_alt_m], now, witness, STUCK_MIN_REPEATS, stuck_us);
        let aiding = self.aiding_witness();
        self.accel_stuck.witness(aiding, &AIDING_MOTION);
        self.gyro_stuck.witness(aiding, &AIDING_MOTION);
        if stuck {
            // Not fused: the height is held on GPS altitude (fused with every fix) and the IMU.
            self.refresh();
            return;
        }
        let baro_was_ok = self.baro_fresh();
        let Stage::Running(f) = &mut self.stage else { return };
        let r = self.config.baro_noise_m.powi(2);
        if !baro_was_ok {
            // First sample, or back after an outage: the offset is whatever makes the baro agree with the
            // current height, `offset = z + pos_d`, so it inherits pos_d's correlations plus the noise.
            f.x.baro_offset_m = baro.pressure_alt_m + f.x.pos_ned_m.z;
            let row = f.p.row(idx::POS + 2).clone_owned();
            f.p.row_mut(idx::BARO).copy_from(&row);
            f.p.column_mut(idx::BARO).copy_from(&row.transpose());
            f.p[(idx::BARO, idx::BARO)] = f.p[(idx::POS + 2, idx::POS + 2)] + r;
            self.last_baro_fused_us = Some(now);
        } else {
            let mut h = ErrVec::zeros();
            h[idx::POS + 2] = -1.0;
            h[idx::BARO] = 1.0;
            let residual = baro.pressure_alt_m - (f.x.baro_offset_m - f.x.pos_ned_m.z);
            self.innovations.baro_alt_m = residual;
            let outcome = f.fuse(&[ScalarObs { h, residual, variance: r }], self.config.innovation_gate_sigma);
            self.innovations.baro_rejected = matches!(outcome, Outcome::Rejected { .. });
            match outcome {
                Outcome::Fused { correction, .. } => {
                    Self::note_correction(&mut self.history, &correction);
                    self.last_baro_fused_us = Some(now);
                }
                Outcome::Rejected { .. } => self.gated += 1,
            }
        }
        self.refresh();
    }

    // ---------------------------------------------------------------------------------------------
    // Flags and output
    // ---------------------------------------------------------------------------------------------

    /// Each source's fault now: lost before stuck before rejected. A lost source's stuck and rejection
    /// records are forgotten (its return is a fresh start).
    fn judge_health(&mut self) -> SourceHealth {
        let c = &self.config;
        let now = self.now_us.unwrap_or(0);
        let held = |since: Option<u64>| since.is_some_and(|t| now.saturating_sub(t) >= us(c.reject_time_s));
        let gps = if self.lost(self.last_gps_rx_us, c.gps_timeout_s) {
            Some(SourceFault::Lost)
        } else if self.gps_stuck.stuck() {
            Some(SourceFault::Stuck)
        } else if held(self.gps_rejected_since_us) {
            Some(SourceFault::Rejected)
        } else {
            None
        };
        let baro = if self.lost(self.last_baro_rx_us, c.baro_timeout_s) {
            Some(SourceFault::Lost)
        } else if self.baro_stuck.stuck() {
            Some(SourceFault::Stuck)
        } else {
            None
        };
        let mag = if self.lost(self.last_mag_rx_us, c.mag_timeout_s) {
            Some(SourceFault::Lost)
        } else if self.mag_stuck.stuck() {
            Some(SourceFault::Stuck)
        } else if held(self.mag_rejected_since_us) {
            Some(SourceFault::Rejected)
        } else {
            None
        };
        let imu = if self.last_imu_us.is_some() && !self.imu_ok() {
            Some(SourceFault::Lost)
        } else if self.accel_stuck.stuck() || self.gyro_stuck.stuck() {
            Some(SourceFault::Stuck)
        } else if self.imu_refused {
            Some(SourceFault::Rejected)
        } else {
            None
        };
        if gps == Some(SourceFault::Lost) {
            self.gps_stuck.clear();
            self.gps_rejected_since_us = None;
        }
        if baro == Some(SourceFault::Lost) {
            self.baro_stuck.clear();
        }
        if mag == Some(SourceFault::Lost) {
            self.mag_stuck.clear();
        }
        SourceHealth { gps, baro, mag, imu }
    }

    /// Queues an event for every source whose fault changed since the last announcement.
    fn announce(&mut self, health: SourceHealth, height_source: HeightSource) {
        for source in Source::ALL {
            let (before, now) = (self.health.of(source), health.of(source));
            if before == now {
                continue;
            }
            if self.events.len() >= MAX_PENDING_EVENTS {
                self.events.remove(0);
            }
            self.events.push(match now {
                Some(fault) => EstimatorEvent::Fault { source, fault, height_source },
                None => EstimatorEvent::Regained { source },
            });
        }
        self.health = health;
    }

    /// Recomputes the health timers, the flags and the published state.
    fn refresh(&mut self) {
        let now = self.now_us.unwrap_or(0);
        let health = self.judge_health();
        let imu_ok = self.imu_ok();
        let gps_ok = self.gps_fresh() && health.gps.is_none();
        let baro_ok = self.baro_fresh() && health.baro.is_none();
        let mag_ok = self.mag_fresh() && health.mag.is_none();
        let running = matches!(self.stage, Stage::Running(_));
        let height_source = match (running, baro_ok, gps_ok) {
            (true, true, _) => HeightSource::Baro,
            (true, false, true) => HeightSource::Gps,
            _ => HeightSource::None,
        };
        self.announce(health, height_source);
        if gps_ok {
            // Aiding (re)started: at a reset to the fix, or when a rejected GPS came back within the gate.
            self.gps_aiding_since_us.get_or_insert(now);
        } else {
            self.gps_aiding_since_us = None;
        }
        let Stage::Running(f) = &self.stage else {
            self.attitude_settled_since_us = None;
            self.state = EstimatorState {
                time_us: now,
                origin: self.origin,
                flags: EstimatorFlags { gps_ok, baro_ok, mag_ok, health, height_source, ..EstimatorFlags::default() },
                ..EstimatorState::default()
            };
            return;
        };
        let c = &self.config;
        let tilt_std_rad = f.std(idx::ATT).max(f.std(idx::ATT + 1));
        let yaw_std_rad = f.std(idx::ATT + 2);
        let pos_std_m = (0..3).map(|i| f.std(idx::POS + i)).fold(0.0, f64::max);
        let vel_std_mps = (0..3).map(|i| f.std(idx::VEL + i)).fold(0.0, f64::max);

        let attitude_valid =
            imu_ok && self.yaw_aligned && tilt_std_rad <= c.valid_tilt_std_rad && yaw_std_rad <= c.valid_yaw_std_rad;
        // A faulted IMU (stuck, garbage) integrates a wrong velocity and position however small their
        // covariance: both invalid at once, so the position failsafe lands on what attitude there is.
        let velocity_valid = attitude_valid && gps_ok && health.imu.is_none() && vel_std_mps <= c.valid_vel_std_mps;
        let position_valid = velocity_valid && self.origin.is_some() && pos_std_m <= c.valid_pos_std_m;

        let settled = attitude_valid
            && gps_ok
            && tilt_std_rad <= c.converge_tilt_std_rad
            && yaw_std_rad <= c.converge_yaw_std_rad
            && self.vel_nis_lp <= c.converge_vel_nis_max;
        self.attitude_settled_since_us =
            if settled { Some(self.attitude_settled_since_us.unwrap_or(now)) } else { None };
        let held = |since: Option<u64>, seconds: f64| since.is_some_and(|t| now.saturating_sub(t) >= us(seconds));
        let converged = position_valid
            && health.all_healthy()
            && held(self.attitude_settled_since_us, c.converge_settle_s)
            && held(self.gps_aiding_since_us, c.converge_gps_s)
            && pos_std_m <= c.converge_pos_std_m
            && vel_std_mps <= c.converge_vel_std_mps;

        let x = &f.x;
        let (rate_frd_radps, specific_force_frd_mps2) =
            self.last_imu.map_or((Vector3::zeros(), Vector3::zeros()), |imu| {
                (imu.gyro_frd_radps - x.gyro_bias_frd_radps, imu.accel_frd_mps2 - x.accel_bias_frd_mps2)
            });
        let (roll_rad, pitch_rad, yaw_rad) = x.q_ned_frd.euler_angles();
        self.state = EstimatorState {
            time_us: now,
            pos_ned_m: x.pos_ned_m,
            vel_ned_mps: x.vel_ned_mps,
            q_ned_frd: x.q_ned_frd,
            euler_rad: Vector3::new(roll_rad, pitch_rad, yaw_rad),
            rate_frd_radps,
            specific_force_frd_mps2,
            accel_bias_frd_mps2: x.accel_bias_frd_mps2,
            gyro_bias_frd_radps: x.gyro_bias_frd_radps,
            origin: self.origin,
            flags: EstimatorFlags {
                attitude_valid,
                velocity_valid,
                position_valid,
                converged,
                gps_ok,
                baro_ok,
                mag_ok,
                health,
                height_source,
            },
        };
    }
}
