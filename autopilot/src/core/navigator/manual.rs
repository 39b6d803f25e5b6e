//! Flying by hand: the navigator's setpoint generator for each manual mode, as PX4's flight tasks
//! (ManualAltitude, ManualAcceleration) and the stabilized attitude path. In, per step: the manual mode,
//! the sticks ([`Sticks`]; none while manual control is lost: flown as centred), the step's dt (s), the
//! vehicle's estimate and whether it is landed ([`NavInput`]), the parameters ([`ManualFlightConfig`]).
//! Out: the [`Reference`] (None: motors idle on the ground).
//!
//! - **Stabilized** (and MANUAL): roll and pitch sticks to a tilt of up to `MPC_MAN_TILT_MAX` (the stick
//!   vector limited to the unit circle), yaw stick to a yaw rate of up to `MPC_MAN_Y_MAX` (integrated into
//!   the yaw setpoint), throttle stick to the collective (PX4's MPC_THR_CURVE 0: 0 -> `MPC_MANTHR_MIN`,
//!   0.5 -> `MPC_THR_HOVER`, 1 -> full, linear between).
//! - **Altitude**: attitude as Stabilized; the throttle stick, shaped by `MPC_HOLD_DZ` and `MPC_Z_MAN_EXPO`
//!   about its centre, to a climb (descent) rate of up to `MPC_Z_VEL_MAX_UP` (`_DN`); the vertical
//!   reference's velocity follows it jerk-limited (`MPC_ACC_UP_MAX` / `MPC_ACC_DOWN_MAX`, `MPC_JERK_MAX`)
//!   and its position integrates it, so the altitude is held where it stops.
//! - **Position**: pitch and roll sticks (shaped by `MPC_HOLD_DZ`, `MPC_XY_MAN_EXPO`) to a velocity in the
//!   heading frame of up to `MPC_VEL_MANUAL`; the horizontal reference's velocity follows it jerk-limited
//!   (`MPC_ACC_HOR_MAX`, `MPC_JERK_MAX`) and its position integrates it, so releasing the sticks brakes to
//!   a hold at the jerk-limited stopping point; vertical as Altitude.
//!
//! - **Acro**: roll, pitch and yaw sticks, shaped by `MC_ACRO_EXPO` (`MC_ACRO_EXPO_Y` for yaw; PX4's
//!   super-expo is not applied), to body rates of up to `MC_ACRO_R_MAX`, `MC_ACRO_P_MAX`, `MC_ACRO_Y_MAX`
//!   (pitch stick forward: nose down); the throttle stick is the collective, directly (0-1, as PX4's
//!   Acro); nothing levels the attitude. Only a controller with a rate loop flies it.
//!
//! On the ground (landed) the motors idle until the sticks ask to leave it: throttle above centre plus
//! the dead zone (Altitude, Position) or above 0.1 (Stabilized). The reference never goes more than
//! `land_below_ground_m` below the ground, so a descent on the ground does not wind the controller up.

use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::NavInput;
use super::leg::Motion3;
use crate::core::control::Reference;
use crate::core::intent::ManualMode;
use crate::core::manual::{Sticks, expo_deadzone};

/// The manual modes' parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ManualFlightConfig {
    /// Largest tilt the sticks ask for (deg; MPC_MAN_TILT_MAX).
    pub tilt_max_deg: f64,
    /// Largest yaw rate the yaw stick asks for (deg/s; MPC_MAN_Y_MAX).
    pub yaw_rate_max_degps: f64,
    /// Thrust at throttle stick 0 in Stabilized (0-1; MPC_MANTHR_MIN).
    pub thr_min: f64,
    /// Thrust at throttle stick centre in Stabilized: hover (0-1; MPC_THR_HOVER).
    pub thr_hover: f64,
    /// Horizontal speed at full stick in Position (m/s; MPC_VEL_MANUAL).
    pub vel_manual_mps: f64,
    /// Horizontal acceleration limit in Position (m/s²; MPC_ACC_HOR_MAX).
    pub acc_hor_max_mps2: f64,
    /// Jerk limit of the manual modes' velocity changes (m/s³; MPC_JERK_MAX).
    pub jerk_max_mps3: f64,
    /// Stick dead zone about centre (0-1; MPC_HOLD_DZ).
    pub hold_dz: f64,
    /// Expo of the roll and pitch sticks in Position (0-1; MPC_XY_MAN_EXPO).
    pub xy_expo: f64,
    /// Expo of the throttle stick in Altitude and Position (0-1; MPC_Z_MAN_EXPO).
    pub z_expo: f64,
    /// Expo of the yaw stick (0-1; MPC_YAW_EXPO).
    pub yaw_expo: f64,
    /// Acro: roll rate at full stick (deg/s; MC_ACRO_R_MAX).
    pub acro_roll_max_degps: f64,
    /// Acro: pitch rate at full stick (deg/s; MC_ACRO_P_MAX).
    pub acro_pitch_max_degps: f64,
    /// Acro: yaw rate at full stick (deg/s; MC_ACRO_Y_MAX).
    pub acro_yaw_max_degps: f64,
    /// Acro: expo of the roll and pitch sticks (0-1; MC_ACRO_EXPO).
    pub acro_expo: f64,
    /// Acro: expo of the yaw stick (0-1; MC_ACRO_EXPO_Y).
    pub acro_yaw_expo: f64,
}

impl Default for ManualFlightConfig {
    fn default() -> Self {
        Self {
            tilt_max_deg: 20.0,
            yaw_rate_max_degps: 60.0,
            thr_min: 0.08,
            thr_hover: 0.46,
            vel_manual_mps: 2.0,
            acc_hor_max_mps2: 2.0,
            jerk_max_mps3: 4.0,
            hold_dz: 0.1,
            xy_expo: 0.6,
            z_expo: 0.6,
            yaw_expo: 0.6,
            acro_roll_max_degps: 180.0,
            acro_pitch_max_degps: 180.0,
            acro_yaw_max_degps: 80.0,
            acro_expo: 0.69,
            acro_yaw_expo: 0.69,
        }
    }
}

impl ManualFlightConfig {
    /// The (field, value, rule) of the first value out of range.
    pub(super) fn invalid(&self) -> Option<(&'static str, f64, &'static str)> {
        let positive = [
            ("manual.tilt_max_deg", self.tilt_max_deg),
            ("manual.yaw_rate_max_degps", self.yaw_rate_max_degps),
            ("manual.vel_manual_mps", self.vel_manual_mps),
            ("manual.acc_hor_max_mps2", self.acc_hor_max_mps2),
            ("manual.jerk_max_mps3", self.jerk_max_mps3),
            ("manual.acro_roll_max_degps", self.acro_roll_max_degps),
            ("manual.acro_pitch_max_degps", self.acro_pitch_max_degps),
            ("manual.acro_yaw_max_degps", self.acro_yaw_max_degps),
        ];
        if let Some((f, v)) = positive.into_iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Some((f, v, "positive"));
        }
        if self.tilt_max_deg >= 90.0 {
            return Some(("manual.tilt_max_deg", self.tilt_max_deg, "below 90"));
        }
        let unit = [
            ("manual.thr_min", self.thr_min),
            ("manual.thr_hover", self.thr_hover),
            ("manual.hold_dz", self.hold_dz),
            ("manual.xy_expo", self.xy_expo),
            ("manual.z_expo", self.z_expo),
            ("manual.yaw_expo", self.yaw_expo),
            ("manual.acro_expo", self.acro_expo),
            ("manual.acro_yaw_expo", self.acro_yaw_expo),
        ];
        if let Some((f, v)) = unit.into_iter().find(|(_, v)| !(v.is_finite() && (0.0..1.0).contains(v))) {
            return Some((f, v, "in [0, 1)"));
        }
        if self.thr_min >= self.thr_hover {
            return Some(("manual.thr_min", self.thr_min, "below manual.thr_hover (MPC_THR_HOVER)"));
        }
        None
    }
}

/// The vertical limits the manual modes climb and descend with (m/s, m/s²; from the navigator's), and the
/// lowest the reference goes (NED down, m: `land_below_ground_m` under the ground).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct VerticalLimits {
    pub climb_mps: f64,
    pub descent_mps: f64,
    pub acc_up_mps2: f64,
    pub acc_down_mps2: f64,
    pub floor_d_m: f64,
}

/// The throttle stick above which Stabilized leaves the ground.
const STABILIZED_LIFTOFF_THROTTLE: f64 = 0.1;

/// The jerk-limited change of a velocity towards a target: the acceleration is steered towards the
/// largest that can still be brought to zero by the jerk limit, step by step, as the velocity reaches the
/// target (about `sqrt(2 j |e|)`, at most the acceleration limit), at most `jerk * dt` per step. Returns the new
/// acceleration and the jerk used. Vectors of any dimension (the horizontal plane, or the vertical).
fn slew<const D: usize>(
    vel: &nalgebra::SVector<f64, D>,
    acc: &nalgebra::SVector<f64, D>,
    target: &nalgebra::SVector<f64, D>,
    acc_max: f64,
    jerk_max: f64,
    dt_s: f64,
) -> (nalgebra::SVector<f64, D>, nalgebra::SVector<f64, D>) {
    // The error half a step on (the acceleration held meanwhile), so the discrete ramp does not overshoot.
    let e = target - vel - acc * (0.5 * dt_s);
    let e_norm = e.norm();
    // The acceleration `a` that the jerk limit brings to zero, one step at a time, over a velocity change
    // of `e`: a²/2j + a·dt/2 = e.
    let a_stop = jerk_max * ((dt_s * dt_s / 4.0 + 2.0 * e_norm / jerk_max).sqrt() - dt_s / 2.0);
    let want = if e_norm > 0.0 { e * (a_stop.min(acc_max) / e_norm) } else { e };
    let mut da = want - acc;
    let step = jerk_max * dt_s;
    if da.norm() > step {
        da *= step / da.norm();
    }
    let jerk = if dt_s > 0.0 { da / dt_s } else { da * 0.0 };
    (acc + da, jerk)
}

/// The manual flight under way: the reference's motion and the yaw setpoint.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ManualFlight {
    motion: Motion3,
    yaw_sp_rad: f64,
}

impl ManualFlight {
    /// Starts from `start` (the reference's motion, for continuity) with the yaw `yaw_rad`.
    pub fn new(start: Motion3, yaw_rad: f64) -> Self {
        Self { motion: start, yaw_sp_rad: yaw_rad }
    }

    /// The motion of the last step (the next leg starts from it).
    pub fn motion(&self) -> Motion3 {
        self.motion
    }

    /// The yaw setpoint (rad).
    pub fn yaw_sp_rad(&self) -> f64 {
        self.yaw_sp_rad
    }

    /// The reference for this step; None: idle on the ground. See the module docs.
    pub fn step(
        &mut self,
        mode: ManualMode,
        sticks: Option<Sticks>,
        input: &NavInput,
        dt_s: f64,
        cfg: &ManualFlightConfig,
        vertical: &VerticalLimits,
    ) -> Option<Reference> {
        let s = sticks.unwrap_or_default();
        let yaw_rate = expo_deadzone(s.yaw, cfg.yaw_expo, cfg.hold_dz) * cfg.yaw_rate_max_degps.to_radians();
        // Shaped throttle about centre: > 0 climbs.
        let climb = expo_deadzone(2.0 * s.throttle - 1.0, cfg.z_expo, cfg.hold_dz);
        let leave_ground = match mode {
            ManualMode::Stabilized | ManualMode::Acro => s.throttle > STABILIZED_LIFTOFF_THROTTLE,
            ManualMode::Altitude | ManualMode::Position => climb > 0.0,
        };
        if input.landed && !leave_ground {
            // Idle on the ground; the next flight starts from where the vehicle is, at rest.
            self.motion = Motion3::rest(input.pos_ned_m);
            if input.yaw_rad.is_finite() {
                self.yaw_sp_rad = input.yaw_rad;
            }
            return None;
        }
        if mode == ManualMode::Acro {
            // The next mode starts from the vehicle's motion and heading.
            self.motion = Motion3 {
                pos_ned_m: input.pos_ned_m,
                vel_ned_mps: input.vel_ned_mps,
                acc_ned_mps2: Vector3::zeros(),
                jerk_ned_mps3: Vector3::zeros(),
            };
            if input.yaw_rad.is_finite() {
                self.yaw_sp_rad = input.yaw_rad;
            }
            return Some(Reference::rates(acro_rates_radps(&s, cfg), s.throttle.clamp(0.0, 1.0), self.yaw_sp_rad));
        }
        self.yaw_sp_rad = wrap_pi(self.yaw_sp_rad + yaw_rate * dt_s);
        let tilt = tilt_rad(&s, cfg);
        let attitude = Vector3::new(tilt.x, tilt.y, self.yaw_sp_rad);
        if mode == ManualMode::Stabilized {
            // The next position-holding mode starts from the vehicle's motion.
            self.motion = Motion3 {
                pos_ned_m: input.pos_ned_m,
                vel_ned_mps: input.vel_ned_mps,
                acc_ned_mps2: Vector3::zeros(),
                jerk_ned_mps3: Vector3::zeros(),
            };
            let mut r = Reference::attitude(attitude, input.pos_ned_m.z);
            r.collective_frac = Some(thrust_curve(s.throttle, cfg));
            return Some(r);
        }
        // Vertical: the climb rate asked for (NED: up is negative).
        let vz_target = if climb >= 0.0 { -climb * vertical.climb_mps } else { -climb * vertical.descent_mps };
        let m = &mut self.motion;
        let acc_z_max = if vz_target < m.vel_ned_mps.z { vertical.acc_up_mps2 } else { vertical.acc_down_mps2 };
        let (az, jz) = slew(
            &nalgebra::Vector1::new(m.vel_ned_mps.z),
            &nalgebra::Vector1::new(m.acc_ned_mps2.z),
            &nalgebra::Vector1::new(vz_target),
            acc_z_max,
            cfg.jerk_max_mps3,
            dt_s,
        );
        let mut v_xy_target = None;
        let (acc_xy, jerk_xy) = if mode == ManualMode::Position {
            let (sy, cy) = self.yaw_sp_rad.sin_cos();
            let fwd = expo_deadzone(s.pitch, cfg.xy_expo, cfg.hold_dz);
            let right = expo_deadzone(s.roll, cfg.xy_expo, cfg.hold_dz);
            let mut body = Vector2::new(fwd, right);
            if body.norm() > 1.0 {
                body /= body.norm();
            }
            let v_target = Vector2::new(cy * body.x - sy * body.y, sy * body.x + cy * body.y) * cfg.vel_manual_mps;
            v_xy_target = Some(v_target);
            slew(&m.vel_ned_mps.xy(), &m.acc_ned_mps2.xy(), &v_target, cfg.acc_hor_max_mps2, cfg.jerk_max_mps3, dt_s)
        } else {
            // Altitude: the horizontal reference follows the vehicle (its loops are off).
            (Vector2::zeros(), Vector2::zeros())
        };
        let acc = Vector3::new(acc_xy.x, acc_xy.y, az.x);
        let vel_before = m.vel_ned_mps;
        m.vel_ned_mps += (m.acc_ned_mps2 + acc) * (0.5 * dt_s);
        m.pos_ned_m += (vel_before + m.vel_ned_mps) * (0.5 * dt_s);
        m.acc_ned_mps2 = acc;
        m.jerk_ned_mps3 = Vector3::new(jerk_xy.x, jerk_xy.y, jz.x);
        // Settled on the target velocity: exactly on it (a stop exactly at rest, no creep from the last
        // step's rounding). Within two steps' worth of jerk the slew would only chatter about it.
        let settle_v = 2.0 * cfg.jerk_max_mps3 * dt_s * dt_s;
        let settle_a = 2.0 * cfg.jerk_max_mps3 * dt_s;
        if (vz_target - m.vel_ned_mps.z).abs() <= settle_v && m.acc_ned_mps2.z.abs() <= settle_a {
            m.vel_ned_mps.z = vz_target;
            m.acc_ned_mps2.z = 0.0;
            m.jerk_ned_mps3.z = 0.0;
        }
        if let Some(v) = v_xy_target
            && (v - m.vel_ned_mps.xy()).norm() <= settle_v
            && m.acc_ned_mps2.xy().norm() <= settle_a
        {
            m.vel_ned_mps.x = v.x;
            m.vel_ned_mps.y = v.y;
            m.acc_ned_mps2.x = 0.0;
            m.acc_ned_mps2.y = 0.0;
            m.jerk_ned_mps3.x = 0.0;
            m.jerk_ned_mps3.y = 0.0;
        }
        if m.pos_ned_m.z > vertical.floor_d_m {
            m.pos_ned_m.z = vertical.floor_d_m;
            m.vel_ned_mps.z = m.vel_ned_mps.z.min(0.0);
            m.acc_ned_mps2.z = m.acc_ned_mps2.z.min(0.0);
        }
        if mode == ManualMode::Altitude {
            m.pos_ned_m.x = input.pos_ned_m.x;
            m.pos_ned_m.y = input.pos_ned_m.y;
            m.vel_ned_mps.x = input.vel_ned_mps.x;
            m.vel_ned_mps.y = input.vel_ned_mps.y;
            let mut r = Reference::attitude(attitude, m.pos_ned_m.z);
            r.vel_ned_mps.z = m.vel_ned_mps.z;
            r.acc_ned_mps2.z = m.acc_ned_mps2.z;
            return Some(r);
        }
        Some(Reference {
            vel_ned_mps: m.vel_ned_mps,
            acc_ned_mps2: m.acc_ned_mps2,
            jerk_ned_mps3: m.jerk_ned_mps3,
            ..Reference::position(m.pos_ned_m, self.yaw_sp_rad)
        })
    }
}

/// The roll and pitch (rad) the sticks ask for: the stick vector limited to the unit circle, times
/// `MPC_MAN_TILT_MAX` (roll right positive, pitch stick forward = nose down = negative pitch).
fn tilt_rad(s: &Sticks, cfg: &ManualFlightConfig) -> Vector2<f64> {
    let mut v = Vector2::new(s.roll, -s.pitch);
    if v.norm() > 1.0 {
        v /= v.norm();
    }
    v * cfg.tilt_max_deg.to_radians()
}

/// Acro's body rates (FRD, rad/s) of the sticks: each stick through its expo (no dead zone), times its
/// `MC_ACRO_*_MAX`; pitch stick forward (positive) is nose down (negative pitch rate).
#[must_use]
pub fn acro_rates_radps(s: &Sticks, cfg: &ManualFlightConfig) -> Vector3<f64> {
    Vector3::new(
        expo_deadzone(s.roll, cfg.acro_expo, 0.0) * cfg.acro_roll_max_degps.to_radians(),
        -expo_deadzone(s.pitch, cfg.acro_expo, 0.0) * cfg.acro_pitch_max_degps.to_radians(),
        expo_deadzone(s.yaw, cfg.acro_yaw_expo, 0.0) * cfg.acro_yaw_max_degps.to_radians(),
    )
}

/// PX4's MPC_THR_CURVE 0: throttle stick 0 -> MPC_MANTHR_MIN, 0.5 -> MPC_THR_HOVER, 1 -> 1, linear between.
#[must_use]
pub fn thrust_curve(throttle: f64, cfg: &ManualFlightConfig) -> f64 {
    let t = throttle.clamp(0.0, 1.0);
    if t <= 0.5 {
        cfg.thr_min + (cfg.thr_hover - cfg.thr_min) * t / 0.5
    } else {
        cfg.thr_hover + (1.0 - cfg.thr_hover) * (t - 0.5) / 0.5
    }
}

/// `a` in [-pi, pi] (unchanged when it is already; 0 when not a number).
fn wrap_pi(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if (-PI..=PI).contains(&a) {
        a
    } else if a.is_finite() {
        (a + PI).rem_euclid(TAU) - PI
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input(landed: bool) -> NavInput {
        NavInput {
            now_us: 0,
            pos_ned_m: Vector3::new(0.0, 0.0, -5.0),
            vel_ned_mps: Vector3::zeros(),
            yaw_rad: 0.0,
            origin: None,
            home_ned_m: Some(Vector3::zeros()),
            home_alt_amsl_m: None,
            landed,
            position_valid: true,
            takeoff_alt_m: 2.5,
            takeoff_acceptance_m: 0.1,
        }
    }

    const VERT: VerticalLimits =
        VerticalLimits { climb_mps: 1.0, descent_mps: 1.0, acc_up_mps2: 1.0, acc_down_mps2: 1.0, floor_d_m: 0.5 };

    #[test]
    fn the_hover_thrust_default_is_the_nominal_airframes_within_0_005() {
        use crate::core::control::Airframe;
        use crate::core::control::distributor::ActuatorLimits;
        let l = ActuatorLimits::default();
        let hover = (Airframe::default().hover_rotor_lift_n() - l.rotor_min_n) / (l.rotor_max_n - l.rotor_min_n);
        assert!((ManualFlightConfig::default().thr_hover - hover).abs() <= 0.005, "hover {hover}");
    }

    #[test]
    fn full_forward_stick_reaches_mpc_vel_manual_and_release_stops_at_the_jerk_limited_distance_within_1_percent() {
        let cfg = ManualFlightConfig::default();
        let mut f = ManualFlight::new(Motion3::rest(Vector3::new(0.0, 0.0, -5.0)), 0.0);
        let dt = 0.002;
        let full = Sticks { pitch: 1.0, ..Sticks::default() };
        for _ in 0..5000 {
            f.step(ManualMode::Position, Some(full), &input(false), dt, &cfg, &VERT);
        }
        assert!((f.motion().vel_ned_mps.x - cfg.vel_manual_mps).abs() < 1e-9);
        let x0 = f.motion().pos_ned_m.x;
        let mut last = x0;
        for _ in 0..5000 {
            let r = f.step(ManualMode::Position, Some(Sticks::default()), &input(false), dt, &cfg, &VERT).unwrap();
            assert!(r.pos_ned_m.x >= last - 1e-12, "the stop never comes back");
            last = r.pos_ned_m.x;
        }
        assert_eq!(f.motion().vel_ned_mps, Vector3::zeros(), "settled exactly at rest");
        use super::super::trajectory::{Limits, Motion1, Profile};
        let limits =
            Limits { vel_mps: cfg.vel_manual_mps, acc_mps2: cfg.acc_hor_max_mps2, jerk_mps3: cfg.jerk_max_mps3 };
        let d_opt =
            Profile::stop(Motion1 { pos_m: 0.0, vel_mps: cfg.vel_manual_mps, acc_mps2: 0.0 }, limits).target_m();
        let d = last - x0;
        assert!((d - d_opt).abs() <= 0.01 * d_opt, "stopped in {d} m, the time-optimal stop is {d_opt} m");
    }

    #[test]
    fn on_the_ground_the_motors_idle_until_the_throttle_asks_to_climb() {
        let cfg = ManualFlightConfig::default();
        let mut f = ManualFlight::new(Motion3::rest(Vector3::zeros()), 0.0);
        let centre = Sticks::default();
        for mode in [ManualMode::Position, ManualMode::Altitude] {
            assert_eq!(f.step(mode, Some(centre), &input(true), 0.002, &cfg, &VERT), None);
            let up = Sticks { throttle: 0.8, ..centre };
            let r = f.step(mode, Some(up), &input(true), 0.002, &cfg, &VERT).unwrap();
            assert!(r.acc_ned_mps2.z < 0.0, "climbing");
        }
        assert_eq!(
            f.step(ManualMode::Stabilized, Some(Sticks { throttle: 0.05, ..centre }), &input(true), 0.002, &cfg, &VERT),
            None
        );
    }

    #[test]
    fn stabilized_maps_half_roll_to_half_the_tilt_and_centre_throttle_to_hover() {
        let cfg = ManualFlightConfig::default();
        let mut f = ManualFlight::new(Motion3::rest(Vector3::zeros()), 0.3);
        let s = Sticks { roll: 0.5, pitch: 0.0, yaw: 0.0, throttle: 0.5 };
        let r = f.step(ManualMode::Stabilized, Some(s), &input(false), 0.002, &cfg, &VERT).unwrap();
        let att = r.attitude_rad.unwrap();
        assert!((att.x - 0.5 * cfg.tilt_max_deg.to_radians()).abs() < 1e-12);
        assert_eq!((att.y, att.z), (0.0, 0.3));
        assert_eq!(r.collective_frac, Some(cfg.thr_hover));
        assert_eq!(thrust_curve(0.0, &cfg), cfg.thr_min);
        assert_eq!(thrust_curve(1.0, &cfg), 1.0);
    }

    #[test]
    fn three_quarter_throttle_climbs_at_the_shaped_rate() {
        let cfg = ManualFlightConfig::default();
        let mut f = ManualFlight::new(Motion3::rest(Vector3::new(0.0, 0.0, -5.0)), 0.0);
        let s = Sticks { throttle: 0.75, ..Sticks::default() };
        for _ in 0..5000 {
            f.step(ManualMode::Altitude, Some(s), &input(false), 0.002, &cfg, &VERT);
        }
        let want = expo_deadzone(0.5, cfg.z_expo, cfg.hold_dz) * VERT.climb_mps;
        assert!((-f.motion().vel_ned_mps.z - want).abs() < 1e-9);
    }
}
