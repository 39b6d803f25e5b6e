//! Test-only kinematic simulator (not a physics plant). In: a prescribed trajectory and a seed. Out, every
//! 2 ms of simulated time: the truth and consistent sensor samples — IMU and magnetometer at 500 Hz,
//! barometer at 50 Hz, GPS at 10 Hz (after an optional latency) — with white noise from a small
//! deterministic generator and constant IMU biases.
//!
//! The trajectory is smooth: speed, course and climb rate are sums of smoothstep ramps (continuous
//! acceleration), the yaw follows the course (coordinated: at hover a course ramp is a pure yaw turn), and
//! the attitude is the one a quadrotor needs for that acceleration (thrust along body -z, heading = yaw).
//! Body rates come from the attitude by a central difference, the specific force is `Rᵀ(a - g e3)`, and
//! the position integrates the analytic velocity by Simpson's rule.

use std::collections::VecDeque;
use std::f64::consts::PI;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::eskf::GRAVITY_MPS2;
use super::{BaroSample, GeoOrigin, GpsSample, ImuSample, MagSample, TruthSample};

/// The truth's NED origin (the plant's home).
pub const HOME: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };
/// Simulation step (µs): 500 Hz.
pub const STEP_US: u64 = 2_000;
/// Start position (m NED about `HOME`): hovering 5 m up.
pub const START_NED_M: Vector3<f64> = Vector3::new(0.0, 0.0, -5.0);
/// Constant sensor biases.
pub const ACCEL_BIAS_FRD_MPS2: Vector3<f64> = Vector3::new(0.1, -0.1, 0.15);
pub const GYRO_BIAS_FRD_RADPS: Vector3<f64> = Vector3::new(0.01, -0.01, 0.005);
/// White-noise standard deviations.
pub const ACCEL_NOISE_MPS2: f64 = 0.2;
pub const GYRO_NOISE_RADPS: f64 = 0.01;
pub const MAG_NOISE_GAUSS: f64 = 0.005;
pub const BARO_NOISE_M: f64 = 0.1;
pub const GPS_POS_NOISE_M: f64 = 0.3;
pub const GPS_VEL_NOISE_MPS: f64 = 0.05;
/// Earth field at home: declination 3.3 deg (the estimator's default), dip 63.6 deg, 0.48 G.
pub const DECLINATION_DEG: f64 = 3.3;
pub const INCLINATION_DEG: f64 = 63.6;
pub const FIELD_GAUSS: f64 = 0.48;

/// A 64-bit linear congruential generator (Knuth's MMIX constants) with Box-Muller normals.
#[derive(Debug, Clone)]
pub struct Lcg(u64);

impl Lcg {
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    /// Uniform in (0, 1].
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }

    pub fn normal3(&mut self, sigma: f64) -> Vector3<f64> {
        Vector3::new(self.normal(), self.normal(), self.normal()) * sigma
    }
}

/// `delta * smoothstep((t - start) / duration)`, the smoothstep `3x² - 2x³` clamped to [0, 1].
#[derive(Debug, Clone, Copy)]
struct Ramp {
    start_s: f64,
    duration_s: f64,
    delta: f64,
}

impl Ramp {
    const fn new(start_s: f64, duration_s: f64, delta: f64) -> Self {
        Self { start_s, duration_s, delta }
    }

    fn value(&self, t_s: f64) -> f64 {
        let x = ((t_s - self.start_s) / self.duration_s).clamp(0.0, 1.0);
        self.delta * x * x * (3.0 - 2.0 * x)
    }

    fn rate(&self, t_s: f64) -> f64 {
        let x = ((t_s - self.start_s) / self.duration_s).clamp(0.0, 1.0);
        self.delta * 6.0 * x * (1.0 - x) / self.duration_s
    }
}

/// Which trajectory to fly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// Hover at the start position, heading 0.3 rad, throughout.
    Hover,
    /// 0-3 s hover; 3-18 s translation at 1 m/s (from 5 s, full speed until 16 s) with a coordinated
    /// 90 deg turn at 5-9 s; 20-30 s a full yaw turn at hover; 30-34 s a 1.5 m climb; 34-46 s translation
    /// with a coordinated 180 deg turn at 38-44 s; hover afterwards.
    Manoeuvre,
}

const INITIAL_YAW_RAD: f64 = 0.3;
const MANOEUVRE_SPEED: [Ramp; 4] =
    [Ramp::new(3.0, 2.0, 1.0), Ramp::new(16.0, 2.0, -1.0), Ramp::new(34.0, 2.0, 1.0), Ramp::new(44.0, 2.0, -1.0)];
const MANOEUVRE_COURSE: [Ramp; 3] =
    [Ramp::new(5.0, 4.0, 0.5 * PI), Ramp::new(20.0, 10.0, -2.0 * PI), Ramp::new(38.0, 6.0, PI)];
const MANOEUVRE_CLIMB: [Ramp; 2] = [Ramp::new(30.0, 1.0, -0.5), Ramp::new(33.0, 1.0, 0.5)];

/// The truth at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics {
    pub vel_ned_mps: Vector3<f64>,
    pub accel_ned_mps2: Vector3<f64>,
    pub q_ned_frd: UnitQuaternion<f64>,
}

impl Profile {
    fn sum(ramps: &[Ramp], t_s: f64, f: fn(&Ramp, f64) -> f64) -> f64 {
        ramps.iter().map(|r| f(r, t_s)).sum()
    }

    /// (speed, its rate, course, its rate, climb velocity (down), its rate).
    fn channels(self, t_s: f64) -> [f64; 6] {
        match self {
            Profile::Hover => [0.0, 0.0, INITIAL_YAW_RAD, 0.0, 0.0, 0.0],
            Profile::Manoeuvre => [
                Self::sum(&MANOEUVRE_SPEED, t_s, Ramp::value),
                Self::sum(&MANOEUVRE_SPEED, t_s, Ramp::rate),
                INITIAL_YAW_RAD + Self::sum(&MANOEUVRE_COURSE, t_s, Ramp::value),
                Self::sum(&MANOEUVRE_COURSE, t_s, Ramp::rate),
                Self::sum(&MANOEUVRE_CLIMB, t_s, Ramp::value),
                Self::sum(&MANOEUVRE_CLIMB, t_s, Ramp::rate),
            ],
        }
    }

    fn velocity(self, t_s: f64) -> Vector3<f64> {
        let [s, _, chi, _, w, _] = self.channels(t_s);
        Vector3::new(s * chi.cos(), s * chi.sin(), w)
    }

    pub fn kinematics(self, t_s: f64) -> Kinematics {
        let [s, s_dot, chi, chi_dot, w, w_dot] = self.channels(t_s);
        let (sin_chi, cos_chi) = chi.sin_cos();
        let accel_ned_mps2 =
            Vector3::new(s_dot * cos_chi - s * chi_dot * sin_chi, s_dot * sin_chi + s * chi_dot * cos_chi, w_dot);
        // Thrust along body -z: body z is opposite the specific force; heading = course.
        let force_ned = accel_ned_mps2 - Vector3::new(0.0, 0.0, GRAVITY_MPS2);
        let z_b = -force_ned.normalize();
        let y_b = z_b.cross(&Vector3::new(cos_chi, sin_chi, 0.0)).normalize();
        let x_b = y_b.cross(&z_b);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_b, y_b, z_b]));
        Kinematics { vel_ned_mps: Vector3::new(s * cos_chi, s * sin_chi, w), accel_ned_mps2, q_ned_frd: r.into() }
    }

    /// Body rates by a central difference of the attitude (h = 0.1 ms).
    pub fn rate_frd_radps(self, t_s: f64) -> Vector3<f64> {
        const H_S: f64 = 1e-4;
        let q0 = self.kinematics(t_s - H_S).q_ned_frd;
        let q1 = self.kinematics(t_s + H_S).q_ned_frd;
        (q0.inverse() * q1).scaled_axis() / (2.0 * H_S)
    }
}

/// One step of samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub time_us: u64,
    pub truth: TruthSample,
    pub imu: ImuSample,
    pub mag: MagSample,
    pub baro: Option<BaroSample>,
    /// A GPS fix released (arrived) at this step.
    pub gps: Option<GpsSample>,
}

/// The simulator.
#[derive(Debug, Clone)]
pub struct Sim {
    profile: Profile,
    rng: Lcg,
    next_k: u64,
    pos_ned_m: Vector3<f64>,
    gps_queue: VecDeque<GpsSample>,
    /// Time from a fix being valid to it arriving (µs).
    pub gps_latency_us: u64,
    /// No fix (fix type 1) before this time (µs).
    pub gps_start_us: u64,
    /// No GPS messages at all in [start, end) (µs).
    pub gps_outage_us: Option<(u64, u64)>,
}

impl Sim {
    pub fn new(profile: Profile, seed: u64) -> Self {
        Self {
            profile,
            rng: Lcg::new(seed),
            next_k: 0,
            pos_ned_m: START_NED_M,
            gps_queue: VecDeque::new(),
            gps_latency_us: 0,
            gps_start_us: 0,
            gps_outage_us: None,
        }
    }

    fn field_ned_gauss() -> Vector3<f64> {
        let (dec, inc) = (DECLINATION_DEG.to_radians(), INCLINATION_DEG.to_radians());
        Vector3::new(inc.cos() * dec.cos(), inc.cos() * dec.sin(), inc.sin()) * FIELD_GAUSS
    }

    pub fn step(&mut self) -> Step {
        let k = self.next_k;
        self.next_k += 1;
        let time_us = k * STEP_US;
        let t_s = time_us as f64 * 1e-6;
        if k > 0 {
            let dt_s = STEP_US as f64 * 1e-6;
            let p = self.profile;
            let v = p.velocity(t_s - dt_s) + p.velocity(t_s - 0.5 * dt_s) * 4.0 + p.velocity(t_s);
            self.pos_ned_m += v * (dt_s / 6.0);
        }
        let kin = self.profile.kinematics(t_s);
        let rate_frd_radps = self.profile.rate_frd_radps(t_s);
        let force_frd_mps2 = kin.q_ned_frd.inverse() * (kin.accel_ned_mps2 - Vector3::new(0.0, 0.0, GRAVITY_MPS2));
        let truth = TruthSample {
            time_us,
            pos_ned_m: self.pos_ned_m,
            vel_ned_mps: kin.vel_ned_mps,
            q_ned_frd: kin.q_ned_frd,
            rate_frd_radps,
            specific_force_frd_mps2: force_frd_mps2,
        };

        // Noise is drawn in a fixed order every step, whatever is output, so scenarios differ only where
        // they differ.
        let accel_noise = self.rng.normal3(ACCEL_NOISE_MPS2);
        let gyro_noise = self.rng.normal3(GYRO_NOISE_RADPS);
        let mag_noise = self.rng.normal3(MAG_NOISE_GAUSS);
        let baro_noise = self.rng.normal() * BARO_NOISE_M;
        let gps_pos_noise = self.rng.normal3(GPS_POS_NOISE_M);
        let gps_vel_noise = self.rng.normal3(GPS_VEL_NOISE_MPS);

        let imu = ImuSample {
            time_us,
            accel_frd_mps2: force_frd_mps2 + ACCEL_BIAS_FRD_MPS2 + accel_noise,
            gyro_frd_radps: rate_frd_radps + GYRO_BIAS_FRD_RADPS + gyro_noise,
        };
        let mag = MagSample { field_frd_gauss: kin.q_ned_frd.inverse() * Self::field_ned_gauss() + mag_noise };
        let baro = k
            .is_multiple_of(10)
            .then(|| BaroSample { pressure_alt_m: HOME.alt_amsl_m - self.pos_ned_m.z + baro_noise });

        let in_outage = self.gps_outage_us.is_some_and(|(start, end)| (start..end).contains(&time_us));
        if k.is_multiple_of(50) && !in_outage {
            let (lat_deg, lon_deg, alt_amsl_m) = HOME.geodetic_from_ned(&(self.pos_ned_m + gps_pos_noise));
            self.gps_queue.push_back(GpsSample {
                time_us,
                lat_deg,
                lon_deg,
                alt_amsl_m,
                vel_ned_mps: kin.vel_ned_mps + gps_vel_noise,
                fix_type: if time_us >= self.gps_start_us { 3 } else { 1 },
                satellites: 10,
                eph_m: 0.5,
                epv_m: 0.8,
            });
        }
        let gps = if self.gps_queue.front().is_some_and(|g| g.time_us + self.gps_latency_us <= time_us) {
            self.gps_queue.pop_front()
        } else {
            None
        };
        Step { time_us, truth, imu, mag, baro, gps }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_the_manoeuvre_when_sampled_then_the_truth_is_self_consistent() {
        // The simulator must be right for the estimator tests to mean anything: integrate the truth's
        // specific force and rates and compare with its velocity and attitude.
        let mut sim = Sim::new(Profile::Manoeuvre, 1);
        let first = sim.step();
        let mut q = first.truth.q_ned_frd;
        let mut v = first.truth.vel_ned_mps;
        let mut prev = first.truth;
        let mut worst_att: f64 = 0.0;
        let mut worst_vel: f64 = 0.0;
        for _ in 0..35_000 {
            let s = sim.step();
            let dt = STEP_US as f64 * 1e-6;
            let w_mid = (prev.rate_frd_radps + s.truth.rate_frd_radps) * 0.5;
            let q_mid = q * UnitQuaternion::from_scaled_axis(w_mid * dt * 0.5);
            let f_mid = (prev.specific_force_frd_mps2 + s.truth.specific_force_frd_mps2) * 0.5;
            v += (q_mid * f_mid + Vector3::new(0.0, 0.0, GRAVITY_MPS2)) * dt;
            q = q_mid * UnitQuaternion::from_scaled_axis(w_mid * dt * 0.5);
            worst_att = worst_att.max(q.angle_to(&s.truth.q_ned_frd));
            worst_vel = worst_vel.max((v - s.truth.vel_ned_mps).norm());
            prev = s.truth;
        }
        assert!(worst_att < 1e-4, "attitude drift {worst_att}");
        assert!(worst_vel < 1e-3, "velocity drift {worst_vel}");
        // And it flew: back near the start, having turned.
        assert!(prev.pos_ned_m.z < -6.0, "climbed: {}", prev.pos_ned_m);
    }
}
