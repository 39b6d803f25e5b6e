//! The actuator side shared by every controller: the paper's lift curve (Eq 10), the forward mixer
//! (Eq 27 in FRD), the prioritising channel distributor (Eqs 26-27, spec A.4 step 8), the thrust-vector
//! limiter and attitude extraction (spec A.4 step 4) and the tilt-compensated collective (step 5).
//!
//! In: a desired thrust-force vector (N, NED) or a collective thrust (N) and body moments (N·m, FRD).
//! Out: limited thrust and the desired attitude (rad, ZYX), or rotor lifts (N) and PWM commands (µs,
//! 1000-2000), rotors numbered as in the paper (1 right, 2 rear, 3 front, 4 left), plus saturation
//! reports for the adaptation freeze (MRAC) and integrator freeze (PID). Rate: every inner tick
//! (distributor, collective) and every position tick (limiter, attitude extraction).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::Airframe;

/// The motors' lowest PWM command (µs); a radio channel's range is another, wider one.
pub const MOTOR_PWM_MIN_US: f64 = 1000.0;
/// The motors' highest PWM command (µs).
pub const MOTOR_PWM_MAX_US: f64 = 2000.0;
/// Rotor lift at `MOTOR_PWM_MIN_US`, the exact upper-branch inverse of Eq 10 (the spec rounds it to 11.277 N).
pub const ROTOR_LIFT_MIN_N: f64 = 11.277_060_877_149_857;
/// Rotor lift at `MOTOR_PWM_MAX_US`, the exact upper-branch inverse of Eq 10 (the spec rounds it to 14.477 N).
pub const ROTOR_LIFT_MAX_N: f64 = 14.476_943_047_337_304;

/// Eq 10: PWM (µs) that produces the rotor lift `lift_n` (N): `1105 - 260 F + 22.23 F²`.
#[must_use]
pub fn pwm_from_lift_us(lift_n: f64) -> f64 {
    1105.0 - 260.0 * lift_n + 22.23 * lift_n * lift_n
}

/// The exact upper-branch inverse of Eq 10 (spec (b)): lift (N) at PWM `pwm_us`, which is clamped to
/// 1000-2000 µs first. Eq 26's 261 / 30135.6 are the paper's misprint of 260 / 30656.6.
#[must_use]
pub fn lift_from_pwm_n(pwm_us: f64) -> f64 {
    let p = pwm_us.clamp(MOTOR_PWM_MIN_US, MOTOR_PWM_MAX_US);
    (260.0 + (88.92 * p - 30656.6).sqrt()) / 44.46
}

/// Rotor and thrust limits shared by all controllers (spec A.4 steps 4, 5, 8; pitfalls).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ActuatorLimits {
    /// Lowest rotor lift `F_min` (N), at 1000 µs.
    pub rotor_min_n: f64,
    /// Highest rotor lift `F_max` (N), at 2000 µs.
    pub rotor_max_n: f64,
    /// Lowest vertical thrust `T_lo = 1.01 · 4 F_min` (N) the limiter allows.
    pub thrust_lo_n: f64,
    /// Highest vertical thrust `T_hi = 0.97 · 4 F_max` (N) the limiter allows.
    pub thrust_hi_n: f64,
    /// Largest tilt of the thrust vector (rad).
    pub tilt_max_rad: f64,
    /// Floor on `cos phi cos theta` in the collective `T = U / cos phi cos theta`.
    pub cos_tilt_floor: f64,
}

impl Default for ActuatorLimits {
    fn default() -> Self {
        Self {
            rotor_min_n: ROTOR_LIFT_MIN_N,
            rotor_max_n: ROTOR_LIFT_MAX_N,
            thrust_lo_n: 1.01 * 4.0 * ROTOR_LIFT_MIN_N,
            thrust_hi_n: 0.97 * 4.0 * ROTOR_LIFT_MAX_N,
            tilt_max_rad: 0.5,
            cos_tilt_floor: 0.5,
        }
    }
}

impl ActuatorLimits {
    /// The collective thrust (N) of a normalized thrust `frac` (PX4's SET_ATTITUDE_TARGET.thrust): 0 is
    /// every rotor at `F_min` (1000 µs on the lift curve, Eq 10), 1 every rotor at `F_max` (2000 µs),
    /// linear between; `frac` is clamped to 0-1.
    #[must_use]
    pub fn collective_from_frac_n(&self, frac: f64) -> f64 {
        4.0 * (self.rotor_min_n + frac.clamp(0.0, 1.0) * (self.rotor_max_n - self.rotor_min_n))
    }
}

/// Forward mixer (Eq 27 in FRD): rotor lifts (N) -> (collective thrust T (N), moments (N·m, FRD)).
/// `T = ΣF`, `Mx = l(F4 - F1)`, `My = l(F3 - F2)`, `Mz = λ(F2 + F3 - F1 - F4)`.
#[must_use]
pub fn mix_forward(forces_n: &[f64; 4], airframe: &Airframe) -> (f64, Vector3<f64>) {
    let [f1, f2, f3, f4] = *forces_n;
    let l = airframe.arm_m;
    let lambda = airframe.yaw_moment_m;
    (f1 + f2 + f3 + f4, Vector3::new(l * (f4 - f1), l * (f3 - f2), lambda * (f2 + f3 - f1 - f4)))
}

/// What the distributor had to give up (spec A.4 step 8), per axis.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MixerSaturation {
    /// The achieved roll moment differs from the demand (roll/pitch part scaled or clipped).
    pub roll: bool,
    /// The achieved pitch moment differs from the demand (roll/pitch part scaled or clipped).
    pub pitch: bool,
    /// The yaw part was scaled (`k < 1`).
    pub yaw: bool,
    /// The collective was shifted (`c != T/4`).
    pub collective: bool,
    /// Factor applied to the roll/pitch part (1 when it fitted).
    pub roll_pitch_scale: f64,
    /// Yaw factor `k` in `[0, 1]`.
    pub yaw_factor: f64,
}

impl MixerSaturation {
    /// Which axes (roll, pitch, yaw) the baselines treat as saturated when they freeze adaptation (CA)
    /// or integrators (PID). `include_roll_pitch = false` reproduces the reference prototype: with its
    /// roll and pitch freezes never acting, every CA and PID metric of the spec's attitude table
    /// matches to its printed digit, and with them acting none of the initial roll/pitch rows does
    /// (CA mismatch settles in 4.9 s instead of 1.10 s; PID nominal pitch in 2.05 s instead of 0.61 s).
    #[must_use]
    pub fn freeze_axes(&self, include_roll_pitch: bool) -> [bool; 3] {
        [include_roll_pitch && self.roll, include_roll_pitch && self.pitch, self.yaw]
    }
}

/// Distributor output: rotor lifts, PWM commands and the saturation report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distribution {
    pub forces_n: [f64; 4],
    pub pwm_us: [f64; 4],
    pub saturation: MixerSaturation,
}

/// The channel distributor (Eqs 26-27, spec A.4 step 8) with priority roll/pitch > collective > yaw.
///
/// Splits `(T, M)` into a roll/pitch part `rp = (-Mx, -My, +My, +Mx)/(2l)` and a yaw part
/// `yw = (-Mz, +Mz, +Mz, -Mz)/(4λ)`; scales `rp` down if its spread exceeds `F_max - F_min`; clips the
/// collective `c = T/4` to `[F_min - min rp, F_max - max rp]`; takes the largest yaw factor `k` in
/// `[0, 1]` that keeps every rotor inside the limits; clips; and maps through Eq 10.
#[must_use]
pub fn distribute(
    thrust_n: f64,
    moment_frd_nm: &Vector3<f64>,
    airframe: &Airframe,
    limits: &ActuatorLimits,
) -> Distribution {
    let (f_min, f_max) = (limits.rotor_min_n, limits.rotor_max_n);
    let half_arm = 2.0 * airframe.arm_m;
    let (mx, my, mz) = (moment_frd_nm.x, moment_frd_nm.y, moment_frd_nm.z);
    let mut rp = [-mx / half_arm, -my / half_arm, my / half_arm, mx / half_arm];
    let y = mz / (4.0 * airframe.yaw_moment_m);
    let yw = [-y, y, y, -y];

    let rp_max = rp.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let rp_min = rp.iter().copied().fold(f64::INFINITY, f64::min);
    let spread = rp_max - rp_min;
    let mut roll_pitch_scale = 1.0;
    if spread > f_max - f_min {
        roll_pitch_scale = (f_max - f_min) / spread;
        for r in &mut rp {
            *r *= roll_pitch_scale;
        }
    }
    let rp_max = rp.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let rp_min = rp.iter().copied().fold(f64::INFINITY, f64::min);

    let c_wanted = thrust_n / 4.0;
    // Lower bound first so that, if rounding ever crossed the bounds, the upper one wins (no panic).
    let c = c_wanted.max(f_min - rp_min).min(f_max - rp_max);

    let mut k: f64 = 1.0;
    for (r, w) in rp.iter().zip(yw.iter()) {
        let base = c + r;
        if *w > 0.0 {
            k = k.min((f_max - base) / w);
        } else if *w < 0.0 {
            k = k.min((f_min - base) / w);
        }
    }
    let k = k.clamp(0.0, 1.0);

    let mut forces_n = [0.0; 4];
    let mut pwm_us = [0.0; 4];
    for i in 0..4 {
        forces_n[i] = (c + rp[i] + k * yw[i]).clamp(f_min, f_max);
        pwm_us[i] = pwm_from_lift_us(forces_n[i]).clamp(MOTOR_PWM_MIN_US, MOTOR_PWM_MAX_US);
    }

    let (_, achieved) = mix_forward(&forces_n, airframe);
    let differs = |got: f64, want: f64| (got - want).abs() > 1e-9 * (1.0 + want.abs());
    let saturation = MixerSaturation {
        roll: differs(achieved.x, mx),
        pitch: differs(achieved.y, my),
        yaw: k < 1.0,
        collective: c != c_wanted,
        roll_pitch_scale,
        yaw_factor: k,
    };
    Distribution { forces_n, pwm_us, saturation }
}

/// The thrust-force vector after the shared limiter (spec A.4 step 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitedThrust {
    /// The limited thrust-force vector (N, NED): `(u_N, u_E, -U)`.
    pub force_ned_n: Vector3<f64>,
    /// Vertical thrust `U` (N, upward positive).
    pub vertical_n: f64,
    /// `-u_D` was outside `[T_lo, T_hi]` and clipped.
    pub vertical_clamped: bool,
    /// The horizontal part exceeded `h_max` and was scaled down.
    pub horizontal_limited: bool,
}

/// The thrust-vector limiter (spec A.4 step 4), vertical priority: `U = clip(-u_D, T_lo, T_hi)`, then
/// the horizontal part is scaled down to `h_max = min(U tan(tilt_max), sqrt(T_hi² - U²))`.
#[must_use]
pub fn limit_thrust_vector(u_ned_n: &Vector3<f64>, limits: &ActuatorLimits) -> LimitedThrust {
    let demand_up = -u_ned_n.z;
    let vertical_n = demand_up.clamp(limits.thrust_lo_n, limits.thrust_hi_n);
    let vertical_clamped = vertical_n != demand_up;
    let h_max = (vertical_n * limits.tilt_max_rad.tan())
        .min((limits.thrust_hi_n * limits.thrust_hi_n - vertical_n * vertical_n).max(0.0).sqrt());
    let h_norm = u_ned_n.x.hypot(u_ned_n.y);
    let (mut h_n, mut h_e) = (u_ned_n.x, u_ned_n.y);
    let horizontal_limited = h_norm > h_max;
    if horizontal_limited {
        let s = h_max / h_norm;
        h_n *= s;
        h_e *= s;
    }
    LimitedThrust { force_ned_n: Vector3::new(h_n, h_e, -vertical_n), vertical_n, vertical_clamped, horizontal_limited }
}

/// Desired attitude (phi, theta, psi) from a limited thrust-force vector (spec A.4 step 4):
/// `b3 = (-u_N, -u_E, U)/‖·‖`, `b2 = normalize(b3 × (cos psi_ref, sin psi_ref, 0))`, `b1 = b2 × b3`;
/// `phi = atan2(b2_z, b3_z)`, `theta = -asin(b1_z)`, `psi = atan2(b1_y, b1_x)`.
#[must_use]
pub fn attitude_from_thrust(thrust: &LimitedThrust, yaw_ref_rad: f64) -> Vector3<f64> {
    let u = &thrust.force_ned_n;
    let b3 = Vector3::new(-u.x, -u.y, thrust.vertical_n).normalize();
    let (s, c) = yaw_ref_rad.sin_cos();
    let b2 = b3.cross(&Vector3::new(c, s, 0.0)).normalize();
    let b1 = b2.cross(&b3);
    Vector3::new(b2.z.atan2(b3.z), -b1.z.clamp(-1.0, 1.0).asin(), b1.y.atan2(b1.x))
}

/// Collective thrust (spec A.4 step 5, Eq 20 z row): `T = U / max(cos phi cos theta, floor)` (N).
#[must_use]
pub fn collective_thrust_n(vertical_n: f64, euler_rad: &Vector3<f64>, limits: &ActuatorLimits) -> f64 {
    vertical_n / (euler_rad.x.cos() * euler_rad.y.cos()).max(limits.cos_tilt_floor)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn airframe() -> Airframe {
        Airframe::default()
    }

    #[test]
    fn given_eq10_when_evaluated_at_limits_and_hover_then_matches_spec_values() {
        assert!((pwm_from_lift_us(11.277) - 1000.0).abs() < 0.05);
        assert!((pwm_from_lift_us(14.477) - 2000.0).abs() < 0.05);
        let hover = pwm_from_lift_us(5.2 * 9.81 / 4.0);
        assert!((hover - 1404.7).abs() < 0.2, "hover PWM {hover}");
        assert!((lift_from_pwm_n(1000.0) - 11.277).abs() < 1e-3);
        assert!((lift_from_pwm_n(2000.0) - 14.477).abs() < 1e-3);
        assert!((lift_from_pwm_n(MOTOR_PWM_MIN_US) - ROTOR_LIFT_MIN_N).abs() < 1e-12);
        assert!((lift_from_pwm_n(MOTOR_PWM_MAX_US) - ROTOR_LIFT_MAX_N).abs() < 1e-12);
        for p in [1000.0, 1234.5, 1404.7, 1999.0] {
            assert!((pwm_from_lift_us(lift_from_pwm_n(p)) - p).abs() < 1e-9);
        }
    }

    #[test]
    fn given_unsaturated_demand_when_distributed_and_mixed_forward_then_round_trip_exact() {
        let a = airframe();
        let limits = ActuatorLimits::default();
        for (t, m) in
            [(51.012, Vector3::new(0.1, -0.2, 0.05)), (50.0, Vector3::new(-0.3, 0.25, -0.03)), (53.0, Vector3::zeros())]
        {
            let d = distribute(t, &m, &a, &limits);
            let (t2, m2) = mix_forward(&d.forces_n, &a);
            assert!((t2 - t).abs() < 1e-9, "T {t} -> {t2}");
            assert!((m2 - m).abs().max() < 1e-9, "M {m} -> {m2}");
            let s = d.saturation;
            assert!(!s.roll && !s.pitch && !s.yaw && !s.collective, "{s:?}");
            for (f, p) in d.forces_n.iter().zip(d.pwm_us.iter()) {
                assert!((pwm_from_lift_us(*f) - p).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn given_large_yaw_demand_when_distributed_then_yaw_scaled_and_roll_pitch_collective_kept() {
        let a = airframe();
        let limits = ActuatorLimits::default();
        let m = Vector3::new(0.2, -0.1, 0.5);
        let d = distribute(51.012, &m, &a, &limits);
        let (t2, m2) = mix_forward(&d.forces_n, &a);
        assert!((t2 - 51.012).abs() < 1e-9);
        assert!((m2.x - 0.2).abs() < 1e-9 && (m2.y + 0.1).abs() < 1e-9);
        assert!(m2.z > 0.0 && m2.z < 0.5);
        let s = d.saturation;
        assert!(s.yaw && !s.roll && !s.pitch && !s.collective, "{s:?}");
        assert!(s.yaw_factor > 0.0 && s.yaw_factor < 1.0);
        // The binding rotor is at a limit.
        assert!(
            d.forces_n.iter().any(|f| (f - limits.rotor_max_n).abs() < 1e-9 || (f - limits.rotor_min_n).abs() < 1e-9)
        );
    }

    #[test]
    fn given_high_collective_roll_and_yaw_when_distributed_then_collective_shifted_roll_kept_yaw_scaled() {
        let a = airframe();
        let limits = ActuatorLimits::default();
        let m = Vector3::new(0.3, 0.0, 0.2);
        let d = distribute(57.5, &m, &a, &limits);
        let (t2, m2) = mix_forward(&d.forces_n, &a);
        assert!((m2.x - 0.3).abs() < 1e-9, "roll must be kept: {m2}");
        assert!(t2 < 57.5 - 1e-6, "collective must give way: {t2}");
        let s = d.saturation;
        assert!(s.collective && s.yaw && !s.roll && !s.pitch, "{s:?}");
        assert!(s.yaw_factor > 0.0 && s.yaw_factor < 1.0, "{s:?}");
        assert!((m2.z - s.yaw_factor * 0.2).abs() < 1e-9);
        // The collective sits as high as the kept roll allows: the highest rotor is at F_max.
        assert!((t2 / 4.0 - (limits.rotor_max_n - 0.3 / 0.48)).abs() < 1e-9, "{t2}");
    }

    #[test]
    fn given_roll_pitch_beyond_authority_when_distributed_then_scaled_with_both_flags() {
        let a = airframe();
        let limits = ActuatorLimits::default();
        let m = Vector3::new(-0.6083, 1.0579, -0.0496);
        let d = distribute(63.1, &m, &a, &limits);
        let (_, m2) = mix_forward(&d.forces_n, &a);
        let s = d.saturation;
        assert!(s.roll && s.pitch && s.collective && s.yaw, "{s:?}");
        assert!(s.roll_pitch_scale < 1.0);
        // Direction of the roll/pitch moment is kept.
        assert!((m2.x / m2.y - m.x / m.y).abs() < 1e-9);
        assert!((d.forces_n[1] - limits.rotor_min_n).abs() < 1e-12);
        assert!((d.forces_n[2] - limits.rotor_max_n).abs() < 1e-12);
        assert!((d.pwm_us[1] - 1000.0).abs() < 1e-9 && (d.pwm_us[2] - 2000.0).abs() < 1e-9);
        // Golden first tick of the paper attitude scenario (spec golden CSVs, t = 0).
        let m0 = Vector3::new(-0.608_324_3, 1.057_895_2, -0.049_566);
        let g = distribute(63.111, &m0, &a, &limits);
        assert!(g.pwm_us[0] > 1749.0 && g.pwm_us[0] < 1750.0, "{:?}", g.pwm_us);
        assert!(g.pwm_us[3] > 1174.0 && g.pwm_us[3] < 1175.0, "{:?}", g.pwm_us);
    }

    #[test]
    fn given_pitch_only_saturation_when_distributed_then_only_pitch_flagged() {
        let a = airframe();
        let limits = ActuatorLimits::default();
        let d = distribute(51.012, &Vector3::new(0.0, 1.2, 0.0), &a, &limits);
        assert!(d.saturation.pitch && !d.saturation.roll, "{:?}", d.saturation);
    }

    #[test]
    fn given_pure_north_demand_when_limited_and_extracted_then_negative_pitch() {
        let limits = ActuatorLimits::default();
        let lt = limit_thrust_vector(&Vector3::new(5.0, 0.0, -51.012), &limits);
        assert!(!lt.vertical_clamped && !lt.horizontal_limited);
        let eta = attitude_from_thrust(&lt, 0.0);
        assert!(eta.y < -0.05, "pitch {}", eta.y);
        assert!(eta.x.abs() < 1e-12 && eta.z.abs() < 1e-12, "{eta}");
        assert!((eta.y + (5.0_f64 / 51.012).atan()).abs() < 1e-12);
    }

    #[test]
    fn given_pure_east_demand_when_extracted_then_positive_roll() {
        let limits = ActuatorLimits::default();
        let lt = limit_thrust_vector(&Vector3::new(0.0, 5.0, -51.012), &limits);
        let eta = attitude_from_thrust(&lt, 0.0);
        assert!(eta.x > 0.05, "roll {}", eta.x);
        assert!(eta.y.abs() < 1e-12 && eta.z.abs() < 1e-12, "{eta}");
    }

    #[test]
    fn given_yaw_reference_when_extracted_then_yaw_passes_through_and_tilt_is_rotated() {
        let limits = ActuatorLimits::default();
        for psi in [0.7, -2.5, 3.0] {
            let lt = limit_thrust_vector(&Vector3::new(0.0, 0.0, -51.012), &limits);
            let eta = attitude_from_thrust(&lt, psi);
            assert!((eta.z - psi).abs() < 1e-12 && eta.x.abs() < 1e-12 && eta.y.abs() < 1e-12);
        }
        // North demand with yaw 90°: the vehicle faces east, so it must roll left (negative) to go north.
        let lt = limit_thrust_vector(&Vector3::new(5.0, 0.0, -51.012), &limits);
        let eta = attitude_from_thrust(&lt, std::f64::consts::FRAC_PI_2);
        assert!(eta.x < -0.05 && eta.y.abs() < 1e-9, "{eta}");
    }

    #[test]
    fn given_excessive_demand_when_limited_then_vertical_clamped_and_horizontal_scaled() {
        let limits = ActuatorLimits::default();
        let lt = limit_thrust_vector(&Vector3::new(30.0, -30.0, -70.0), &limits);
        assert!(lt.vertical_clamped && lt.horizontal_limited);
        assert_eq!(lt.vertical_n, limits.thrust_hi_n);
        // At T_hi, sqrt(T_hi² - U²) = 0: no horizontal force left (vertical priority).
        assert!(lt.force_ned_n.x.abs() < 1e-9 && lt.force_ned_n.y.abs() < 1e-9);

        let lt = limit_thrust_vector(&Vector3::new(40.0, 0.0, -51.0), &limits);
        assert!(!lt.vertical_clamped && lt.horizontal_limited);
        let h_max = (51.0 * 0.5_f64.tan()).min((limits.thrust_hi_n.powi(2) - 51.0 * 51.0).sqrt());
        assert!((lt.force_ned_n.x - h_max).abs() < 1e-9);
        let eta = attitude_from_thrust(&lt, 0.0);
        assert!(eta.y >= -0.5 - 1e-9, "tilt limit: {eta}");

        let lt = limit_thrust_vector(&Vector3::new(0.0, 0.0, -20.0), &limits);
        assert!(lt.vertical_clamped && lt.vertical_n == limits.thrust_lo_n);
    }

    #[test]
    fn given_tilt_when_collective_computed_then_divided_by_cosines_with_floor() {
        let limits = ActuatorLimits::default();
        let t = collective_thrust_n(51.012, &Vector3::new(0.4, -0.5, 1.0), &limits);
        assert!((t - 51.012 / (0.4_f64.cos() * 0.5_f64.cos())).abs() < 1e-12);
        let t = collective_thrust_n(51.012, &Vector3::new(1.4, 0.0, 0.0), &limits);
        assert!((t - 102.024).abs() < 1e-12);
    }

    #[test]
    fn given_golden_constants_when_derived_then_thrust_limits_match_spec_rounding() {
        let limits = ActuatorLimits::default();
        assert!((limits.thrust_lo_n - 45.56).abs() < 5e-3);
        assert!((limits.thrust_hi_n - 56.17).abs() < 5e-3);
        // Golden translation scenario, t = 0: full climb at T_hi gives 1837.572949 µs on every rotor.
        let p = pwm_from_lift_us(limits.thrust_hi_n / 4.0);
        assert!((p - 1_837.572_949).abs() < 1e-5, "{p}");
    }
}
