//! The geometric tracking controller on SE(3) (`se3`): Lee, Leok and McClamroch, "Geometric tracking
//! control of a quadrotor UAV on SE(3)", CDC 2010, with the integral terms of Goodarzi, Lee and Lee,
//! "Geometric nonlinear PID control of a quadrotor UAV on SE(3)", ECC 2013. The first guest controller:
//! written only against the `pub` items of `crate::core::control`.
//!
//! In: a [`ControlInput`] and a [`Reference`] once per inner tick. Out: four rotor PWM commands (µs),
//! through the shared channel distributor (Eqs 26-27 of the ACO paper) and lift curve (its Eq 10).
//! Frames: NED earth with `e3` down, as the 2010 paper's own (`m ẍ = m g e3 - f R e3`), FRD body.
//!
//! **Position loop** (every `inner_hz / position_hz`-th tick, per [`LoopClock`], like the cascades: the
//! thrust vector moves no faster than the attitude can follow it, and the plant's position changes little
//! in 10 ms): `ex = x - xd`, `ev = v - vd` (Eqs 6-7), the thrust-force vector
//! `u = m̄ (-kx ex - kv ev - aI + ẍd - g e3)` (the bracket of Eqs 12 and 15, with the gains per unit mass:
//! `kx` in 1/s², `kv` in 1/s), written `kv (v_c - ev)` with `v_c = -(kx/kv) ex` so that the thrust left
//! above the weight bounds it: a descent in `v_c` no faster than `√(2 b a_up |ex,z|)`, a horizontal speed
//! no faster than `√(2 b a_h |ex,h|)` and the horizontal feedback at most `a_h` (`a_up = T_hi/m̄ - g - aI,z`,
//! `a_h = √(T_hi² - W²)/m̄` the acceleration that holds the weight `W`, `b` = [`BRAKE_FRAC`]); the
//! linear law is unchanged near the point. Then through the shared thrust-vector limiter (vertical priority, tilt at most
//! `limits.tilt_max_rad`), then `b3d = -u/‖u‖` (Eq 12), `b1d` from the reference yaw,
//! `Rd = [b2d × b3d, b2d, b3d]` with `b2d = b3d × b1d / ‖·‖` (Eq 13). `aI` is the position integral
//! (ECC 2013): `aI += kI ex Δt`, each axis saturated at `pos_int_max_mps2`, and integrating only while its
//! error is within `pos_int_zone_m` and the limiter did not cut that axis in the direction the error
//! pushes (their `eI = ∫(ev + c1 ex)` is taken as `∫ex`: its `∫ev` part would keep a step's size as a bias).
//!
//! **Ωd and Ω̇d**: `Ωd` is the angular velocity of `Rd` for `u̇ = m̄ j_d`, the reference's jerk
//! (feed-forward only: the feedback part of `u̇` would differentiate measured velocity and acceleration),
//! `Ω̂d = Rdᵀ Ṙd` with `ḃ3d = -(I - b3d b3dᵀ) u̇ / ‖u‖` and the heading held. `Ω̇d` is taken as 0 (the
//! reference carries no snap; differentiating `Ωd` would add noise for a term that is small here).
//!
//! **Attitude and rate loop** (every tick): the paper's attitude error dynamics with the moment law acting
//! directly, no separate rate cascade: `eR = ½ (Rdᵀ R - Rᵀ Rd)^∨` (Eq 10), `eΩ = Ω - Rᵀ Rd Ωd` (Eq 11),
//! `M = J (-kR eR - kΩ eΩ - αI) + Ω × JΩ - J (Ω̂ RᵀRd Ωd - RᵀRd Ω̇d)` (Eq 16, gains per unit inertia: `kR`
//! in 1/s², `kΩ` in 1/s, roll/pitch and yaw apart), `αI` the attitude integral (ECC 2013):
//! `αI += kIR eR Δt` (yaw's `kIR` scaled by `kR,yaw/kR`: the same integral time on every axis), saturated at `att_int_max_radps2` per axis and integrating only while that axis's
//! `|eR|` is within `att_int_zone_rad` (their `∫(eΩ + c2 eR)` taken as `∫eR`). The collective is
//! `f = -u · R e3` (Eq 15), the thrust vector projected on the body axis.
//!
//! **Every reference form**: attitude-only (`attitude_rad`): N and E off (their integrals cleared), `Rd`
//! from the reference's Euler angles, the D loop holds `pos_ned_m.z` with a tilt-compensated collective;
//! direct thrust (`collective_frac`): [`commanded_collective_n`]; the rate level alone
//! ([`Reference::is_rates_only`]): `eR = 0` (`Rd = R`), `Ωd` the reference rates shaped for the `kΩ`
//! loop (`control::rate_level`, as ACO's and PID's), the collective
//! `collective_frac` (hover when None), no integration; attitude with rates: the rates are `Ωd`.
//!
//! **Near the thrust ceiling** up to three quarters of the vertical demand above the weight the vehicle
//! holds yields to the horizontal one before the shared limiter runs (`yield_vertical_excess`); below the
//! weight, for a large climb demand, and while descending (braking towards the ground), the vertical keeps
//! its priority.
//!
//! **Equation numbers** are those of the CDC 2010 proceedings as implementations commonly cite them (eR 10,
//! eΩ 11, f 15, M 16; the position errors, `b3d` and `Rd` in the order of its Section IV); the arXiv
//! version (1003.2005) numbers differ. They were not checked against a copy of the paper here.
//!
//! Not finite inputs: hover PWM on the first tick, then the last good command, no state moved
//! ([`HeldOutput`]). [`Se3Controller::reconfigure`] takes new gains, limits and model and keeps the
//! integrators, projected onto the new bounds.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::control::distributor::{ActuatorLimits, LimitedThrust, limit_thrust_vector};
use crate::core::control::frames::rotation_ned_frd;
use crate::core::control::rate_level::RateShaper;
use crate::core::control::registry::{ControllerType, TunableGain};
use crate::core::control::{
    Airframe, ConfigError, ControlInput, Controller, ControllerConfig, ControllerKind, HeldOutput, LoopClock,
    LoopRates, Reference, commanded_collective_n, inputs_finite,
};
use crate::core::params::ParamDef;

pub mod geometry;
mod params;

use geometry::{attitude_error, desired_frame, euler_of, hat, rate_error};

/// The fraction of the upward acceleration left above the weight (`T_hi / m̄ - g - aI,z`) that a
/// descent keeps for braking: the heavy plant hovers at 95 % of `T_hi`, and a linear PD would descend
/// faster than it can stop (`v ≤ √(2 · this · margin · |ex,z|)`).
const BRAKE_FRAC: f64 = 0.15;

/// The table of `se3` in a `[controller]` block and in `[vehicle.control]`.
pub const TABLE: &str = "se3";

/// The default gains, shared by [`Se3Config::default`] and the parameter table.
pub(crate) mod defaults {
    pub const KX_PER_S2: f64 = 4.0;
    pub const KV_PER_S: f64 = 3.5;
    pub const KI_POS_PER_S3: f64 = 2.0;
    pub const POS_INT_MAX_MPS2: f64 = 3.0;
    pub const POS_INT_ZONE_M: f64 = 0.3;
    pub const KR_PER_S2: f64 = 45.0;
    pub const KW_PER_S: f64 = 10.0;
    pub const KR_YAW_PER_S2: f64 = 10.0;
    pub const KW_YAW_PER_S: f64 = 6.0;
    pub const KI_ATT_PER_S3: f64 = 5.0;
    pub const ATT_INT_MAX_RADPS2: f64 = 5.0;
    pub const ATT_INT_ZONE_RAD: f64 = 0.05;
    pub const TILT_MAX_RAD: f64 = 0.5;
}

/// The `se3` table: gains per unit mass (position) and per unit inertia (attitude), the integrals and
/// their bounds, the nominal model and the actuator limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Se3Config {
    /// Nominal model m̄, J = diag(Ī), l, λ, g.
    pub airframe: Airframe,
    /// Rotor and thrust limits; `tilt_max_rad` bounds the thrust vector's tilt.
    pub limits: ActuatorLimits,
    /// Position gain kx / m̄ (1/s²).
    pub kx_per_s2: f64,
    /// Velocity gain kv / m̄ (1/s).
    pub kv_per_s: f64,
    /// Position integral gain (1/s³): the integral term grows by this times ex (m) per second.
    pub ki_pos_per_s3: f64,
    /// Bound on each position integral term (m/s²).
    pub pos_int_max_mps2: f64,
    /// An axis's position integral runs only while its error is within this (m): a step or a climb does
    /// not wind it up, a steady offset (mass, wind) is taken up.
    pub pos_int_zone_m: f64,
    /// Attitude gain kR / Ī on roll and pitch (1/s²).
    pub kr_per_s2: f64,
    /// Rate gain kΩ / Ī on roll and pitch (1/s).
    pub kw_per_s: f64,
    /// Attitude gain kR / Īz on yaw (1/s²).
    pub kr_yaw_per_s2: f64,
    /// Rate gain kΩ / Īz on yaw (1/s).
    pub kw_yaw_per_s: f64,
    /// Attitude integral gain (1/s³): the integral term grows by this times eR (rad) per second.
    pub ki_att_per_s3: f64,
    /// Bound on each attitude integral term (rad/s²).
    pub att_int_max_radps2: f64,
    /// An axis's attitude integral runs only while its eR is within this (rad): an attitude step, or a yaw
    /// the distributor saturates, does not wind it up.
    pub att_int_zone_rad: f64,
}

impl Default for Se3Config {
    fn default() -> Self {
        use defaults::*;
        Self {
            airframe: Airframe::default(),
            limits: ActuatorLimits { tilt_max_rad: TILT_MAX_RAD, ..ActuatorLimits::default() },
            kx_per_s2: KX_PER_S2,
            kv_per_s: KV_PER_S,
            ki_pos_per_s3: KI_POS_PER_S3,
            pos_int_max_mps2: POS_INT_MAX_MPS2,
            pos_int_zone_m: POS_INT_ZONE_M,
            kr_per_s2: KR_PER_S2,
            kw_per_s: KW_PER_S,
            kr_yaw_per_s2: KR_YAW_PER_S2,
            kw_yaw_per_s: KW_YAW_PER_S,
            ki_att_per_s3: KI_ATT_PER_S3,
            att_int_max_radps2: ATT_INT_MAX_RADPS2,
            att_int_zone_rad: ATT_INT_ZONE_RAD,
        }
    }
}

impl Se3Config {
    /// Every gain finite and positive (integral gains and bounds: >= 0), the model positive, the tilt
    /// limit in (0, π/2).
    ///
    /// # Errors
    /// A [`ConfigError`] naming the field.
    pub fn check(&self) -> Result<(), ConfigError> {
        let a = &self.airframe;
        let [ix, iy, iz] = a.inertia_kgm2;
        for (field, value) in [
            ("mass_kg", a.mass_kg),
            ("inertia_kgm2", ix.min(iy).min(iz)),
            ("arm_m", a.arm_m),
            ("yaw_moment_m", a.yaw_moment_m),
            ("gravity_mps2", a.gravity_mps2),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError::NotPositive { name: "se3.airframe", field, value });
            }
        }
        for (field, value) in [
            ("kx_per_s2", self.kx_per_s2),
            ("kv_per_s", self.kv_per_s),
            ("kr_per_s2", self.kr_per_s2),
            ("kw_per_s", self.kw_per_s),
            ("kr_yaw_per_s2", self.kr_yaw_per_s2),
            ("kw_yaw_per_s", self.kw_yaw_per_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError::NotPositive { name: TABLE, field, value });
            }
        }
        for (field, value) in [
            ("ki_pos_per_s3", self.ki_pos_per_s3),
            ("pos_int_max_mps2", self.pos_int_max_mps2),
            ("ki_att_per_s3", self.ki_att_per_s3),
            ("att_int_max_radps2", self.att_int_max_radps2),
            ("pos_int_zone_m", self.pos_int_zone_m),
            ("att_int_zone_rad", self.att_int_zone_rad),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConfigError::Negative { name: TABLE, field, value });
            }
        }
        let tilt = self.limits.tilt_max_rad;
        if !(tilt.is_finite() && tilt > 0.0 && tilt < std::f64::consts::FRAC_PI_2) {
            return Err(ConfigError::NotPositive {
                name: "se3.limits",
                field: "tilt_max_rad (below pi/2)",
                value: tilt,
            });
        }
        Ok(())
    }
}

/// The geometric controller.
#[derive(Debug, Clone)]
pub struct Se3Controller {
    cfg: Se3Config,
    clock: LoopClock,
    /// Position integral term `aI` (m/s², NED).
    pos_int_mps2: Vector3<f64>,
    /// Attitude integral term `αI` (rad/s², FRD).
    att_int_radps2: Vector3<f64>,
    /// The limited thrust-force vector of the last position tick (N, NED).
    last_limit: Option<LimitedThrust>,
    /// `Rd` and `Ωd` of the last position tick.
    rd: Matrix3<f64>,
    omega_d_radps: Vector3<f64>,
    /// The rate level's request shaped for the `kΩ` loop (the shared lead-lag and missed angle).
    rate_shaper: RateShaper,
    /// What the last tick computed, for telemetry.
    e_r_rad: Vector3<f64>,
    e_w_radps: Vector3<f64>,
    collective_n: f64,
    moment_cmd_nm: Vector3<f64>,
    held: HeldOutput,
}

impl Se3Controller {
    /// At hover with empty integrators, running at `rates`.
    #[must_use]
    pub fn new(config: &Se3Config, rates: LoopRates) -> Self {
        Self {
            clock: LoopClock::new(rates),
            pos_int_mps2: Vector3::zeros(),
            att_int_radps2: Vector3::zeros(),
            last_limit: None,
            rd: Matrix3::identity(),
            omega_d_radps: Vector3::zeros(),
            rate_shaper: RateShaper::default(),
            e_r_rad: Vector3::zeros(),
            e_w_radps: Vector3::zeros(),
            collective_n: config.airframe.mass_kg * config.airframe.gravity_mps2,
            moment_cmd_nm: Vector3::zeros(),
            held: HeldOutput::hover(&config.airframe),
            cfg: config.clone(),
        }
    }

    /// Take `config` from the next tick on, keeping both integrals, each projected onto the new bound.
    pub fn reconfigure(&mut self, config: &Se3Config) {
        self.cfg = config.clone();
        let (p, a) = (self.cfg.pos_int_max_mps2, self.cfg.att_int_max_radps2);
        // max/min rather than clamp: no panic on a non-finite or negative bound.
        self.pos_int_mps2 = self.pos_int_mps2.map(|x| x.max(-p).min(p));
        self.att_int_radps2 = self.att_int_radps2.map(|x| x.max(-a).min(a));
    }

    /// The position integral term (m/s², NED).
    #[must_use]
    pub fn position_integral_mps2(&self) -> Vector3<f64> {
        self.pos_int_mps2
    }

    /// The attitude integral term (rad/s², FRD).
    #[must_use]
    pub fn attitude_integral_radps2(&self) -> Vector3<f64> {
        self.att_int_radps2
    }

    /// The position loop: errors (Eqs 6-7), the thrust-force vector (Eqs 12, 15) through the limiter, the
    /// integral, `Rd` and `Ωd` (Eqs 12-13).
    fn step_position_loop(&mut self, input: &ControlInput, reference: &Reference) {
        let c = &self.cfg;
        let (m, g) = (c.airframe.mass_kg, c.airframe.gravity_mps2);
        let attitude_only = reference.attitude_rad.is_some();
        let mut ex = input.pos_ned_m - reference.pos_ned_m;
        let mut ev = input.vel_ned_mps - reference.vel_ned_mps;
        let mut acc_ff = reference.acc_ned_mps2;
        let mut jerk = reference.jerk_ned_mps3;
        if !jerk.iter().all(|j| j.is_finite()) {
            jerk = Vector3::zeros();
        }
        if attitude_only {
            for v in [&mut ex, &mut ev, &mut acc_ff, &mut jerk, &mut self.pos_int_mps2] {
                v.x = 0.0;
                v.y = 0.0;
            }
        }
        // `-kx ex - kv ev` as `kv (v_c - ev)` with `v_c = -(kx/kv) ex`, and a descent in `v_c` no faster
        // than the thrust left above the weight can stop within the remaining error.
        let mut v_c = -(c.kx_per_s2 / c.kv_per_s) * ex;
        let weight_n = m * (g + self.pos_int_mps2.z);
        let brake_mps2 = BRAKE_FRAC * (c.limits.thrust_hi_n - weight_n).max(0.0) / m;
        v_c.z = v_c.z.min((2.0 * brake_mps2 * ex.z.abs()).sqrt());
        let brake_h_mps2 = BRAKE_FRAC * (c.limits.thrust_hi_n.powi(2) - weight_n.powi(2)).max(0.0).sqrt() / m;
        let (v_h, v_h_max) = (v_c.x.hypot(v_c.y), (2.0 * brake_h_mps2 * ex.x.hypot(ex.y)).sqrt());
        if v_h > v_h_max {
            v_c.x *= v_h_max / v_h;
            v_c.y *= v_h_max / v_h;
        }
        let mut a_fb = c.kv_per_s * (v_c - ev);
        let (a_h, a_h_max) = (a_fb.x.hypot(a_fb.y), brake_h_mps2 / BRAKE_FRAC);
        if a_h > a_h_max {
            a_fb.x *= a_h_max / a_h;
            a_fb.y *= a_h_max / a_h;
        }
        let a = a_fb - self.pos_int_mps2 + acc_ff - Vector3::new(0.0, 0.0, g);
        let u = m * a;
        // Braking a descent keeps the vertical priority: the ceiling is near the weight.
        let shared = if input.vel_ned_mps.z > 0.2 {
            u
        } else {
            yield_vertical_excess(&u, m * (g + self.pos_int_mps2.z), &c.limits)
        };
        let limited = limit_thrust_vector(&shared, &c.limits);

        // Integrate, except on an axis the limiter cut while the error pushes further that way.
        let excess = u - limited.force_ned_n;
        for i in 0..3 {
            let cut = excess[i].abs() > 1e-9 * (1.0 + u[i].abs());
            // The integral term enters `a` with a minus sign: it pushes along -ex.
            if (cut && -ex[i] * excess[i] > 0.0) || ex[i].abs() > c.pos_int_zone_m {
                continue;
            }
            let max = c.pos_int_max_mps2;
            self.pos_int_mps2[i] =
                (self.pos_int_mps2[i] + c.ki_pos_per_s3 * ex[i] * self.clock.pos_dt_s).max(-max).min(max);
        }
        if attitude_only {
            self.pos_int_mps2.x = 0.0;
            self.pos_int_mps2.y = 0.0;
        }

        if let Some(frame) = desired_frame(&limited.force_ned_n, &(m * jerk), reference.yaw_rad) {
            self.rd = frame.rd;
            self.omega_d_radps = frame.omega_d_radps;
        }
        self.last_limit = Some(limited);
        self.clock.position_loop_done();
    }
}

/// The thrust-force vector `u` (N, NED) with up to three quarters of its vertical demand above the weight
/// it holds (`weight_n`, N: m̄ (g + the D integral)) given up to the horizontal demand (tilt limited) when
/// the two together exceed `T_hi`. The shared limiter ([`limit_thrust_vector`]) gives the vertical priority over
/// all of its range; near the thrust ceiling (the heavy plant hovers at 95 % of `T_hi`) a climb demand of
/// a few newtons, noise included, would then take the whole horizontal demand away and the desired frame
/// would snap upright. A large climb demand (a take-off, a climb step) still takes the whole ceiling
/// first, as in the shared limiter, and so does anything below the weight.
fn yield_vertical_excess(u_ned_n: &Vector3<f64>, weight_n: f64, limits: &ActuatorLimits) -> Vector3<f64> {
    let up = -u_ned_n.z;
    let horizontal = u_ned_n.x.hypot(u_ned_n.y).min(up.max(0.0) * limits.tilt_max_rad.tan());
    let room = limits.thrust_hi_n * limits.thrust_hi_n - horizontal * horizontal;
    if up <= weight_n || room <= 0.0 || up * up <= room {
        return *u_ned_n;
    }
    let kept = weight_n + 0.25 * (up - weight_n);
    Vector3::new(u_ned_n.x, u_ned_n.y, -room.sqrt().max(kept))
}

impl Controller for Se3Controller {
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4] {
        if !inputs_finite(input, reference) {
            self.clock.advance();
            return self.held.pwm_us;
        }
        let rates_only = reference.is_rates_only();
        if !rates_only && self.clock.position_loop_due() {
            self.step_position_loop(input, reference);
        }
        let c = &self.cfg;
        let r = rotation_ned_frd(&input.euler_rad);
        let (rd, omega_d) = if rates_only {
            // The rates through the shared shaping for a rate loop of gain kΩ, with the missed angle
            // fed back at 1/s (the law has no rate integrator at the rate level).
            let k_w = [c.kw_per_s, c.kw_per_s, c.kw_yaw_per_s];
            let asked = reference.rate_frd_radps.unwrap_or_default();
            let shaped = self.rate_shaper.shape(&asked, &input.rate_frd_radps, &k_w, 1.0, self.clock.dt_s);
            (r, shaped.setpoint_frd_radps)
        } else if let Some(att) = reference.attitude_rad {
            (rotation_ned_frd(&att), reference.rate_frd_radps.unwrap_or_default())
        } else {
            (self.rd, self.omega_d_radps)
        };
        if !rates_only {
            self.rate_shaper.reset();
        }
        if reference.attitude_rad.is_some() || rates_only {
            self.rd = rd;
            self.omega_d_radps = omega_d;
        }

        // Eqs 10-11; eR = 0 at the rate level (Rd = R).
        let omega = input.rate_frd_radps;
        let e_r = if rates_only { Vector3::zeros() } else { attitude_error(&r, &rd) };
        let e_w = rate_error(&r, &rd, &omega, &omega_d);
        if !rates_only {
            let max = c.att_int_max_radps2;
            // The same integral time kR/kI on every axis: yaw's integral gain scaled as its kR.
            let k_i = [c.ki_att_per_s3, c.ki_att_per_s3, c.ki_att_per_s3 * c.kr_yaw_per_s2 / c.kr_per_s2];
            for i in 0..3 {
                if e_r[i].abs() <= c.att_int_zone_rad {
                    self.att_int_radps2[i] =
                        (self.att_int_radps2[i] + k_i[i] * self.clock.dt_s * e_r[i]).max(-max).min(max);
                }
            }
        }

        // Eq 16 with Ω̇d = 0: M = J(-kR eR - kΩ eΩ - αI) + Ω × JΩ - J Ω̂ RᵀRd Ωd.
        let j = Matrix3::from_diagonal(&c.airframe.inertia());
        let k_r = Vector3::new(c.kr_per_s2, c.kr_per_s2, c.kr_yaw_per_s2);
        let k_w = Vector3::new(c.kw_per_s, c.kw_per_s, c.kw_yaw_per_s);
        let alpha = -k_r.component_mul(&e_r) - k_w.component_mul(&e_w) - self.att_int_radps2;
        let moment = j * alpha + omega.cross(&(j * omega)) - j * (hat(&omega) * r.transpose() * rd * omega_d);

        // Eq 15, f = -u · R e3; the D loop tilt-compensated in attitude-only mode; the hover thrust at the
        // rate level without a thrust; a direct thrust over all of them.
        let m_g = c.airframe.mass_kg * c.airframe.gravity_mps2;
        let collective_n = if rates_only {
            commanded_collective_n(reference, m_g, &input.euler_rad, &c.limits, false)
        } else if reference.attitude_rad.is_some() {
            let vertical = self.last_limit.map_or(m_g, |l| l.vertical_n);
            commanded_collective_n(reference, vertical, &input.euler_rad, &c.limits, true)
        } else {
            let projected = self.last_limit.map_or(m_g, |l| (-l.force_ned_n.dot(&r.column(2))).max(0.0));
            commanded_collective_n(reference, projected, &input.euler_rad, &c.limits, false)
        };

        self.e_r_rad = e_r;
        self.e_w_radps = e_w;
        self.collective_n = collective_n;
        self.moment_cmd_nm = moment;
        self.clock.advance();
        self.held.distribute(collective_n, &moment, &c.airframe, &c.limits);
        self.held.pwm_us
    }

    fn reconfigure(&mut self, config: &ControllerConfig) {
        if let Ok(se3) = config.section::<Se3Config>(TABLE) {
            Se3Controller::reconfigure(self, &se3);
        }
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::of(&SE3)
    }

    fn telemetry(&self) -> Vec<(&'static str, f64)> {
        let limit = self.last_limit;
        let flag = |b: bool| f64::from(u8::from(b));
        vec![
            ("se3.pos_int_n_mps2", self.pos_int_mps2.x),
            ("se3.pos_int_e_mps2", self.pos_int_mps2.y),
            ("se3.pos_int_d_mps2", self.pos_int_mps2.z),
            ("se3.att_int_x_radps2", self.att_int_radps2.x),
            ("se3.att_int_y_radps2", self.att_int_radps2.y),
            ("se3.att_int_z_radps2", self.att_int_radps2.z),
            ("se3.e_r_norm_rad", self.e_r_rad.norm()),
            ("se3.e_w_norm_radps", self.e_w_radps.norm()),
            ("se3.omega_d_x_radps", self.omega_d_radps.x),
            ("se3.omega_d_y_radps", self.omega_d_radps.y),
            ("se3.omega_d_z_radps", self.omega_d_radps.z),
            ("se3.collective_n", self.collective_n),
            ("se3.moment_x_nm", self.moment_cmd_nm.x),
            ("se3.moment_y_nm", self.moment_cmd_nm.y),
            ("se3.moment_z_nm", self.moment_cmd_nm.z),
            ("se3.yaw_factor", self.held.saturation.yaw_factor),
            ("se3.vertical_clamped", flag(limit.is_some_and(|l| l.vertical_clamped))),
            ("se3.horizontal_limited", flag(limit.is_some_and(|l| l.horizontal_limited))),
        ]
    }

    /// No adaptive weights; the integrals are saturated by design.
    fn weights_at_bounds(&self) -> bool {
        false
    }

    fn attitude_setpoint_rad(&self) -> Vector3<f64> {
        euler_of(&self.rd)
    }
}

/// The type of `se3`, for the registry.
pub struct Se3;

/// The one `se3` type, listed in the registry's `BUILT_IN`.
pub static SE3: Se3 = Se3;

impl ControllerType for Se3 {
    fn name(&self) -> &'static str {
        "se3"
    }
    fn summary(&self) -> &'static str {
        "geometric tracking on SE(3), Lee, Leok and McClamroch 2010, with integral terms (guest)"
    }
    fn default_table(&self) -> toml::Table {
        toml::Table::try_from(Se3Config::default()).unwrap_or_default()
    }
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError> {
        config.section::<Se3Config>(TABLE)?.check()
    }
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
        let se3 = config.section::<Se3Config>(TABLE)?;
        se3.check()?;
        Ok(Box::new(Se3Controller::new(&se3, config.rates)))
    }
    fn params(&self) -> &'static [ParamDef] {
        params::PARAMS
    }
    fn flies_rates(&self) -> bool {
        true
    }
    fn gains(&self) -> &'static [TunableGain] {
        params::GAINS
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::distributor::{lift_from_pwm_n, mix_forward};
    use crate::core::control::{new_controller, registry};

    fn at_rest(pos_ned_m: Vector3<f64>, euler_rad: Vector3<f64>) -> ControlInput {
        ControlInput {
            pos_ned_m,
            vel_ned_mps: Vector3::zeros(),
            euler_rad,
            rate_frd_radps: Vector3::zeros(),
            specific_force_frd_mps2: Vector3::new(0.0, 0.0, -9.81),
        }
    }

    fn se3() -> Se3Controller {
        Se3Controller::new(&Se3Config::default(), LoopRates::default())
    }

    /// The collective (N) and moments (N·m) the four PWM commands give.
    fn thrust_and_moment(pwm: &[f64; 4]) -> (f64, Vector3<f64>) {
        mix_forward(&pwm.map(lift_from_pwm_n), &Airframe::default())
    }

    #[test]
    fn given_the_registry_then_se3_is_registered_flies_rates_and_builds_from_the_default_config() {
        let kind: ControllerKind = "se3".parse().expect("registered");
        assert!(kind.flies_rates());
        assert!(registry::all().contains(&kind));
        let c = new_controller(kind, &ControllerConfig::default());
        assert_eq!(c.kind(), kind);
        assert_eq!(Se3.default_table().get("kx_per_s2").and_then(toml::Value::as_float), Some(defaults::KX_PER_S2));
    }

    #[test]
    fn given_hover_at_the_reference_when_ticked_then_hover_thrust_and_no_moment() {
        let mut c = se3();
        let p = Vector3::new(1.0, -2.0, -3.0);
        let pwm = c.update(&at_rest(p, Vector3::new(0.0, 0.0, 0.4)), &Reference::position(p, 0.4));
        let (t, m) = thrust_and_moment(&pwm);
        assert!((t - 5.2 * 9.81).abs() < 1e-6, "{t}");
        assert!(m.norm() < 1e-9, "{m}");
        assert_eq!(c.attitude_setpoint_rad(), Vector3::new(0.0, 0.0, 0.4));
    }

    #[test]
    fn given_a_horizontal_acceleration_when_ticked_then_rd_tilts_the_thrust_along_b3_and_f_is_its_projection() {
        let mut c = se3();
        let p = Vector3::new(0.0, 0.0, -2.0);
        let r = Reference { acc_ned_mps2: Vector3::new(2.0, 0.0, 0.0), ..Reference::position(p, 0.0) };
        // Already tilted as asked: pitch down (nose down, θ < 0) accelerates north.
        let theta = -(2.0_f64 / 9.81).atan();
        let pwm = c.update(&at_rest(p, Vector3::new(0.0, theta, 0.0)), &r);
        let u = c.last_limit.expect("position loop ran").force_ned_n;
        assert!((c.rd.column(2) + u.normalize()).norm() < 1e-12, "b3d = -u/|u|");
        assert!((c.attitude_setpoint_rad() - Vector3::new(0.0, theta, 0.0)).norm() < 1e-9);
        let (t, m) = thrust_and_moment(&pwm);
        assert!((t - u.norm()).abs() < 1e-6, "f = -u·Re3 = |u| when b3 = b3d: {t} vs {}", u.norm());
        assert!(m.norm() < 1e-6, "{m}");
    }

    #[test]
    fn given_the_rate_level_when_ticked_then_rates_tracked_with_hover_or_the_given_thrust() {
        let mut c = se3();
        let input = at_rest(Vector3::new(3.0, 0.0, -1.0), Vector3::new(0.2, 0.0, 0.0));
        let r = Reference { collective_frac: None, ..Reference::rates(Vector3::new(0.3, 0.0, 0.0), 0.5, 0.0) };
        let (t, m) = thrust_and_moment(&c.update(&input, &r));
        assert!((t - 5.2 * 9.81).abs() < 1e-6, "hover without a thrust: {t}");
        assert!(m.x > 0.1 && m.y.abs() < 1e-9 && m.z.abs() < 1e-9, "a roll rate asked, not the attitude: {m}");
        assert_eq!(c.e_r_rad, Vector3::zeros());
        assert_eq!(c.att_int_radps2, Vector3::zeros());
        assert_eq!(c.pos_int_mps2, Vector3::zeros(), "no position loop at the rate level");
        let (t, _) = thrust_and_moment(&c.update(&input, &Reference::rates(Vector3::zeros(), 0.8, 0.0)));
        let want = ActuatorLimits::default().collective_from_frac_n(0.8);
        assert!((t - want).abs() < 1e-6, "{t} vs {want}");
    }

    #[test]
    fn given_attitude_with_rates_when_ticked_then_rates_are_the_feed_forward() {
        let (mut a, mut b) = (se3(), se3());
        let input = at_rest(Vector3::new(0.0, 0.0, -2.0), Vector3::zeros());
        let plain = Reference::attitude(Vector3::zeros(), -2.0);
        let with_rates = Reference { rate_frd_radps: Some(Vector3::new(0.0, 0.5, 0.0)), ..plain };
        let (_, m0) = thrust_and_moment(&a.update(&input, &plain));
        let (_, m1) = thrust_and_moment(&b.update(&input, &with_rates));
        assert!(m0.norm() < 1e-9 && m1.y > 0.1, "{m0} {m1}");
        assert_eq!(b.e_r_rad, Vector3::zeros());
    }

    #[test]
    fn given_bad_gains_or_unknown_keys_when_validated_then_refused_by_name() {
        let mut cfg = ControllerConfig::default();
        let bad = Se3Config { kv_per_s: -1.0, ..Se3Config::default() };
        cfg.set_section(TABLE, &bad).expect("a table");
        assert_eq!(cfg.validate(), Err(ConfigError::NotPositive { name: "se3", field: "kv_per_s", value: -1.0 }));
        let bad = Se3Config { ki_att_per_s3: f64::NAN, ..Se3Config::default() };
        cfg.set_section(TABLE, &bad).expect("a table");
        assert!(matches!(cfg.validate(), Err(ConfigError::Negative { field: "ki_att_per_s3", .. })));
        let mut af = Se3Config::default();
        af.airframe.mass_kg = 0.0;
        cfg.set_section(TABLE, &af).expect("a table");
        assert!(matches!(cfg.validate(), Err(ConfigError::NotPositive { name: "se3.airframe", field: "mass_kg", .. })));
        let mut table = toml::Table::new();
        table.insert("kx".into(), toml::Value::Float(1.0));
        cfg.tables.insert(TABLE.into(), table);
        assert!(matches!(cfg.validate(), Err(ConfigError::Table { .. })), "a misspelt key is refused");
        cfg.set_section(TABLE, &Se3Config::default()).expect("a table");
        assert_eq!(cfg.validate(), Ok(()));
    }

    #[test]
    fn given_integrals_when_reconfigured_with_tighter_bounds_then_kept_and_projected() {
        let mut c = se3();
        c.pos_int_mps2 = Vector3::new(2.5, -0.5, 1.0);
        c.att_int_radps2 = Vector3::new(-4.0, 0.2, 3.0);
        let tighter =
            Se3Config { pos_int_max_mps2: 1.0, att_int_max_radps2: 2.0, kx_per_s2: 9.0, ..Se3Config::default() };
        let mut cfg = ControllerConfig::default();
        cfg.set_section(TABLE, &tighter).expect("a table");
        Controller::reconfigure(&mut c, &cfg);
        assert_eq!(c.position_integral_mps2(), Vector3::new(1.0, -0.5, 1.0));
        assert_eq!(c.attitude_integral_radps2(), Vector3::new(-2.0, 0.2, 2.0));
        assert_eq!(c.cfg.kx_per_s2, 9.0);
    }

    #[test]
    fn given_a_parameter_when_set_then_the_se3_table_carries_it_and_reads_back() {
        use crate::core::config::VehicleConfig;
        use crate::core::params::ParamStore;
        let mut store = ParamStore::defaults();
        store.set("SE3_KX", 7.5).expect("in range");
        store.set("SE3_TILT_MAX", 0.625).expect("in range");
        let mut config = VehicleConfig::default();
        store.apply(&mut config);
        let s = config.control.section::<Se3Config>(TABLE).expect("the table");
        assert_eq!((s.kx_per_s2, s.limits.tilt_max_rad, s.kv_per_s), (7.5, 0.625, defaults::KV_PER_S));
        assert_eq!(ParamStore::from_config(&config), store);
        assert!(params::PARAMS.iter().all(|d| d.name.starts_with("SE3_") && d.name.len() <= 16));
    }

    #[test]
    fn given_telemetry_then_names_are_prefixed_distinct_and_plain() {
        let names: Vec<&str> = se3().telemetry().iter().map(|(n, _)| *n).collect();
        let bare: std::collections::HashSet<&str> = names.iter().filter_map(|n| n.strip_prefix("se3.")).collect();
        assert_eq!(bare.len(), names.len(), "{names:?}");
        assert!(bare.iter().all(|n| n.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')));
    }
}
