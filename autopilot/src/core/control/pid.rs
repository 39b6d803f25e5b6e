//! The PID baseline: a PX4-style cascade with the same proportional poles as ACO (spec (c)).
//!
//! In: a [`ControlInput`] and a [`Reference`] once per inner tick. Out: four rotor PWM commands (µs).
//! Every `inner_hz / position_hz`-th tick: position P (`v_c = Kp e_p + v_ref`, limited per axis), velocity
//! PI (`a = Kv e_v + Kvi ∫e_v + a_ref`, conditional integration, |I| ≤ 3 m/s²), `u = m̄ (a - g e3)`
//! through the shared limiter, `T = ‖u‖`, attitude extraction. Every tick: quaternion attitude P
//! (`omega_d = 2 Kη ⊙ q_e,xyz`, `q_e = q⁻¹ ⊗ q_d`, `q_e,w ≥ 0`), the rate clip, rate PI
//! (`M = Ī ⊙ (Kω e_ω + Kri ∫e_ω)`, |I torque| ≤ 0.3 N·m, frozen per saturated axis), and the shared
//! distributor (Eqs 26-27) and lift curve (Eq 10). The spec's derivative gains Kvd and Krd are 0; the
//! competent PID (`[base.pid]` of `sitl/tunes/pid.toml`, PX4's multicopter rate controller) adds a rate D
//! on the measurement, `- Ī ⊙ Krd ⊙ dω/dt` with dω/dt low-passed at `rate_d_cutoff_hz` (PX4's
//! IMU_DGYRO_CUTOFF), and freezes the roll and pitch integrators under saturation (`freeze_roll_pitch`).
//!
//! [`PidController::reconfigure`] takes new gains, limits and nominal model while flying and keeps the
//! integrators (clamped to new, tighter limits).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::distributor::{ActuatorLimits, LimitedThrust, limit_thrust_vector};
use super::frames::quaternion_from_euler;
use super::rate_level::RateShaper;
use super::{
    Airframe, ControlInput, Controller, ControllerKind, HeldOutput, LoopClock, LoopRates, Reference,
    attitude_setpoint_rad, clip_abs, commanded_collective_n, inputs_finite, tilt_lead_mps2,
};

/// PID baseline gains and limits (spec (c)). Default = the spec's values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PidConfig {
    /// Nominal model m̄, Ī, l, λ, g.
    pub airframe: Airframe,
    /// Rotor and thrust limits.
    pub limits: ActuatorLimits,
    /// Position gain Kp (1/s).
    pub kp_pos_per_s: f64,
    /// Velocity gain Kv (1/s).
    pub kv_vel_per_s: f64,
    /// Velocity integral gains Kvi (1/s²), N, E, D.
    pub kvi_vel_per_s2: [f64; 3],
    /// Limit on each velocity integral term (m/s²).
    pub vel_integral_max_mps2: f64,
    /// Velocity-command limit on N and E (m/s).
    pub vel_limit_ne_mps: f64,
    /// Velocity-command limit on D (m/s).
    pub vel_limit_d_mps: f64,
    /// Attitude gains Kη (1/s), FRD.
    pub k_att_per_s: [f64; 3],
    /// Rate gains Kω (1/s), FRD.
    pub k_rate_per_s: [f64; 3],
    /// Rate integral gains Kri (1/s²), FRD.
    pub kri_rate_per_s2: [f64; 3],
    /// Limit on each integral torque (N·m).
    pub rate_integral_max_nm: f64,
    /// Desired body-rate limits (rad/s), FRD.
    pub rate_limit_radps: [f64; 3],
    /// Also freeze the roll and pitch rate integrators while the distributor saturates those axes, as
    /// the spec's text says. Off by default, as the reference prototype flew (see
    /// [`MixerSaturation::freeze_axes`](super::distributor::MixerSaturation::freeze_axes)); the yaw
    /// integrator is always frozen under saturation.
    pub freeze_roll_pitch: bool,
    /// Rate derivative gains Krd (s), FRD, on the measured rate (not the error, so a setpoint step does not
    /// kick): 0 in the spec and by default.
    pub krd_rate_s: [f64; 3],
    /// Cutoff of the first-order low-pass on the measured rate's derivative (Hz).
    pub rate_d_cutoff_hz: f64,
}

impl Default for PidConfig {
    fn default() -> Self {
        Self {
            airframe: Airframe::default(),
            limits: ActuatorLimits::default(),
            kp_pos_per_s: 0.6667,
            kv_vel_per_s: 2.16,
            kvi_vel_per_s2: [0.4, 0.4, 2.0],
            vel_integral_max_mps2: 3.0,
            vel_limit_ne_mps: 3.0,
            vel_limit_d_mps: 2.0,
            k_att_per_s: [2.778, 2.778, 1.389],
            k_rate_per_s: [9.0, 9.0, 4.5],
            kri_rate_per_s2: [12.0, 12.0, 2.25],
            rate_integral_max_nm: 0.3,
            rate_limit_radps: [3.5, 3.5, 1.5],
            freeze_roll_pitch: false,
            krd_rate_s: [0.0; 3],
            rate_d_cutoff_hz: 30.0,
        }
    }
}

/// The PID cascade.
#[derive(Debug, Clone)]
pub struct PidController {
    cfg: PidConfig,
    clock: LoopClock,
    /// Velocity integral terms `Kvi ∫e_v` (m/s²), NED.
    vel_integral_mps2: Vector3<f64>,
    /// Rate integral torques `Ī Kri ∫e_ω` (N·m), FRD.
    rate_integral_nm: Vector3<f64>,
    collective_n: f64,
    attitude_sp_rad: Vector3<f64>,
    rate_sp_radps: Vector3<f64>,
    /// The rate level's setpoint shaping (reset while an attitude is flown).
    rate_shaper: RateShaper,
    moment_cmd_nm: Vector3<f64>,
    /// The measured rate at the last tick and the low-passed derivative (rad/s²) the rate D acts on.
    rate_prev_frd_radps: Option<Vector3<f64>>,
    rate_dot_frd_radps2: Vector3<f64>,
    last_limit: Option<LimitedThrust>,
    held: HeldOutput,
}

impl PidController {
    /// A controller at hover with empty integrators, running at `rates`.
    #[must_use]
    pub fn new(config: &PidConfig, rates: LoopRates) -> Self {
        let mg = config.airframe.mass_kg * config.airframe.gravity_mps2;
        Self {
            clock: LoopClock::new(rates),
            vel_integral_mps2: Vector3::zeros(),
            rate_integral_nm: Vector3::zeros(),
            collective_n: mg,
            attitude_sp_rad: Vector3::zeros(),
            rate_sp_radps: Vector3::zeros(),
            rate_shaper: RateShaper::default(),
            moment_cmd_nm: Vector3::zeros(),
            rate_prev_frd_radps: None,
            rate_dot_frd_radps2: Vector3::zeros(),
            last_limit: None,
            held: HeldOutput::hover(&config.airframe),
            cfg: config.clone(),
        }
    }

    /// Take `config` from the next [`Controller::update`] on, keeping both integrators (each term
    /// clamped to the new `vel_integral_max_mps2` / `rate_integral_max_nm`) and the last setpoints. The
    /// integrators hold their values, not their gain-scaled history: a new integral gain applies to the
    /// error integrated from now on. The loop rates are those of [`PidController::new`].
    pub fn reconfigure(&mut self, config: &PidConfig) {
        self.cfg = config.clone();
        let (v_max, m_max) = (self.cfg.vel_integral_max_mps2, self.cfg.rate_integral_max_nm);
        // max/min rather than clamp: no panic on a non-finite or negative limit.
        self.vel_integral_mps2 = self.vel_integral_mps2.map(|x| x.max(-v_max).min(v_max));
        self.rate_integral_nm = self.rate_integral_nm.map(|x| x.max(-m_max).min(m_max));
    }

    /// Velocity integral terms (m/s²), NED.
    #[must_use]
    pub fn velocity_integral_mps2(&self) -> Vector3<f64> {
        self.vel_integral_mps2
    }

    /// Rate integral torques (N·m), FRD.
    #[must_use]
    pub fn rate_integral_nm(&self) -> Vector3<f64> {
        self.rate_integral_nm
    }

    fn step_position_loop(&mut self, input: &ControlInput, reference: &Reference) {
        let c = &self.cfg;
        let attitude_only = reference.attitude_rad.is_some();
        let e_p = reference.pos_ned_m - input.pos_ned_m;
        let v_lim = [c.vel_limit_ne_mps, c.vel_limit_ne_mps, c.vel_limit_d_mps];
        let v_c = clip_abs(&(c.kp_pos_per_s * e_p + reference.vel_ned_mps), &v_lim);
        let mut e_v = v_c - input.vel_ned_mps;
        if attitude_only {
            e_v.x = 0.0;
            e_v.y = 0.0;
            self.vel_integral_mps2.x = 0.0;
            self.vel_integral_mps2.y = 0.0;
        }
        let mut a = c.kv_vel_per_s * e_v
            + self.vel_integral_mps2
            + reference.acc_ned_mps2
            + tilt_lead_mps2(&reference.jerk_ned_mps3, &c.k_att_per_s);
        if attitude_only {
            a.x = 0.0;
            a.y = 0.0;
        }
        let g = c.airframe.gravity_mps2;
        let u = c.airframe.mass_kg * (a - Vector3::new(0.0, 0.0, g));
        let limited = limit_thrust_vector(&u, &c.limits);

        // Conditional integration: an axis does not integrate while the limiter cut its demand and the
        // velocity error points the same way as the part that was cut.
        let excess = u - limited.force_ned_n;
        for i in 0..3 {
            let saturated = excess[i].abs() > 1e-9 * (1.0 + u[i].abs());
            if saturated && e_v[i] * excess[i] > 0.0 {
                continue;
            }
            self.vel_integral_mps2[i] = (self.vel_integral_mps2[i]
                + c.kvi_vel_per_s2[i] * e_v[i] * self.clock.pos_dt_s)
                .clamp(-c.vel_integral_max_mps2, c.vel_integral_max_mps2);
        }

        self.collective_n = limited.force_ned_n.norm();
        self.attitude_sp_rad = attitude_setpoint_rad(reference, &limited);
        self.last_limit = Some(limited);
        self.clock.position_loop_done();
    }
}

impl Controller for PidController {
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4] {
        if !inputs_finite(input, reference) {
            self.clock.advance();
            return self.held.pwm_us;
        }
        let rates_only = reference.is_rates_only();
        if self.clock.position_loop_due() && !rates_only {
            self.step_position_loop(input, reference);
        }
        if let Some(att) = reference.attitude_rad {
            self.attitude_sp_rad = att;
        } else if rates_only {
            // The rate level holds no attitude: the setpoint follows the vehicle, for logs.
            self.attitude_sp_rad = input.euler_rad;
        }
        let c = &self.cfg;

        // Attitude P, quaternion form.
        let q = quaternion_from_euler(&input.euler_rad);
        let q_d = quaternion_from_euler(&self.attitude_sp_rad);
        let mut q_e = (q.inverse() * q_d).into_inner();
        if q_e.w < 0.0 {
            q_e = -q_e;
        }
        // The rate level: the body rates asked for, shaped for the rate loop (its integrator against the
        // low-passed request); the attitude loop off.
        let (rate_sp, integral_sp) = match (rates_only, reference.rate_frd_radps) {
            (true, Some(rates)) => {
                let shaped =
                    self.rate_shaper.shape(&rates, &input.rate_frd_radps, &c.k_rate_per_s, 0.0, self.clock.dt_s);
                (shaped.setpoint_frd_radps, Some(shaped.lowpassed_frd_radps))
            }
            (_, feed_forward) => {
                self.rate_shaper.reset();
                let from_attitude = 2.0 * Vector3::from(c.k_att_per_s).component_mul(&q_e.imag());
                (feed_forward.map_or(from_attitude, |ff| from_attitude + ff), None)
            }
        };
        self.rate_sp_radps = clip_abs(&rate_sp, &c.rate_limit_radps);

        // Rate PI; the integrator of an axis the distributor saturated at the last output is frozen.
        let inertia = c.airframe.inertia();
        let e_w = self.rate_sp_radps - input.rate_frd_radps;
        self.moment_cmd_nm =
            inertia.component_mul(&Vector3::from(c.k_rate_per_s).component_mul(&e_w)) + self.rate_integral_nm;
        // Rate D on the measurement (off at the spec's Krd = 0, which leaves the moment bit for bit).
        if let Some(prev) = self.rate_prev_frd_radps {
            let dt = self.clock.dt_s;
            let alpha = dt / (dt + 1.0 / (std::f64::consts::TAU * c.rate_d_cutoff_hz));
            let raw = (input.rate_frd_radps - prev) / dt;
            self.rate_dot_frd_radps2 += (raw - self.rate_dot_frd_radps2) * alpha;
        }
        self.rate_prev_frd_radps = Some(input.rate_frd_radps);
        if c.krd_rate_s.iter().any(|k| *k != 0.0) {
            self.moment_cmd_nm -=
                inertia.component_mul(&Vector3::from(c.krd_rate_s).component_mul(&self.rate_dot_frd_radps2));
        }
        let e_w = integral_sp.map_or(e_w, |sp| clip_abs(&sp, &c.rate_limit_radps) - input.rate_frd_radps);
        let sat = self.held.saturation;
        for (j, saturated) in sat.freeze_axes(c.freeze_roll_pitch).into_iter().enumerate() {
            if !saturated {
                self.rate_integral_nm[j] = (self.rate_integral_nm[j]
                    + inertia[j] * c.kri_rate_per_s2[j] * e_w[j] * self.clock.dt_s)
                    .clamp(-c.rate_integral_max_nm, c.rate_integral_max_nm);
            }
        }

        // In attitude-only mode there is no thrust vector to take the norm of: the vertical demand is
        // tilt-compensated as for the other controllers (the prototype's PID yaw settling, 3.89 / 4.67 s,
        // is reproduced only with it).
        let vertical_n = if rates_only { c.airframe.mass_kg * c.airframe.gravity_mps2 } else { self.collective_n };
        let collective_n = commanded_collective_n(
            reference,
            vertical_n,
            &input.euler_rad,
            &c.limits,
            reference.attitude_rad.is_some() || rates_only,
        );
        self.clock.advance();
        self.held.distribute(collective_n, &self.moment_cmd_nm, &c.airframe, &c.limits);
        self.held.pwm_us
    }

    fn reconfigure(&mut self, config: &super::ControllerConfig) {
        PidController::reconfigure(self, &config.pid);
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::PID
    }

    fn telemetry(&self) -> Vec<(&'static str, f64)> {
        let limit = self.last_limit;
        vec![
            ("pid.vel_int_n_mps2", self.vel_integral_mps2.x),
            ("pid.vel_int_e_mps2", self.vel_integral_mps2.y),
            ("pid.vel_int_d_mps2", self.vel_integral_mps2.z),
            ("pid.rate_int_x_nm", self.rate_integral_nm.x),
            ("pid.rate_int_y_nm", self.rate_integral_nm.y),
            ("pid.rate_int_z_nm", self.rate_integral_nm.z),
            ("pid.collective_n", self.collective_n),
            ("pid.moment_x_nm", self.moment_cmd_nm.x),
            ("pid.moment_y_nm", self.moment_cmd_nm.y),
            ("pid.moment_z_nm", self.moment_cmd_nm.z),
            ("pid.yaw_factor", self.held.saturation.yaw_factor),
            ("pid.vertical_clamped", f64::from(u8::from(limit.is_some_and(|l| l.vertical_clamped)))),
            ("pid.horizontal_limited", f64::from(u8::from(limit.is_some_and(|l| l.horizontal_limited)))),
        ]
    }

    /// The PID has no adaptive weights; its integrators are clamped by design, not projected.
    fn weights_at_bounds(&self) -> bool {
        false
    }

    fn attitude_setpoint_rad(&self) -> Vector3<f64> {
        self.attitude_sp_rad
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::toy_plant::{
        Reconfigured, Sample, ToyPlant, assert_same_config_reconfigure_is_bit_identical, at, fly, hover_input,
        max_after,
    };
    use crate::core::control::{ControllerConfig, toy_plant};

    fn pid() -> PidController {
        PidController::new(&PidConfig::default(), LoopRates::default())
    }

    /// The integrators: velocity (m/s², NED) and rate (N·m, FRD).
    type Integrators = (Vector3<f64>, Vector3<f64>);

    /// The default PID through the shared harness ([`toy_plant::fly_reconfigured`]): 4 s holding
    /// `(0, 0, -1.5)` (the integrators take up the extra mass and the torque disturbance), then
    /// `reconfigure(config)` when given, then 4 s flying to `target`; the state compared is the
    /// integrators `(velocity, rate)`.
    fn fly_reconfigured(config: Option<&PidConfig>, target: Vector3<f64>) -> Reconfigured<Integrators, PidController> {
        let config = config.map(|pid| ControllerConfig { pid: pid.clone(), ..ControllerConfig::default() });
        let hold = Vector3::new(0.0, 0.0, -1.5);
        toy_plant::fly_reconfigured(pid(), (hold, 4.0), config.as_ref(), (target, 4.0), |c: &PidController| {
            (c.velocity_integral_mps2(), c.rate_integral_nm())
        })
    }

    /// Second-leg targets: a diagonal step (everything moves) and a 1 m climb (the D loop alone).
    const DIAGONAL: Vector3<f64> = Vector3::new(1.0, 0.5, -2.5);
    const CLIMB: Vector3<f64> = Vector3::new(0.0, 0.0, -2.5);

    #[test]
    fn given_flying_pid_when_reconfigured_with_same_config_then_trajectory_bit_identical() {
        let plain = fly_reconfigured(None, DIAGONAL);
        let same = fly_reconfigured(Some(&PidConfig::default()), DIAGONAL);
        assert_same_config_reconfigure_is_bit_identical(&plain, &same);
        let before = plain.1;
        assert!(before.0.z.abs() > 0.05 && before.1.x.abs() > 0.01, "integrators took up the mismatch: {before:?}");
    }

    #[test]
    fn given_flying_pid_when_position_gain_raised_then_integrators_kept_and_target_reached_sooner() {
        let (plain, _, _, _) = fly_reconfigured(None, CLIMB);
        let stiffer = PidConfig { kp_pos_per_s: 2.0, ..PidConfig::default() };
        let (fast, before, after, c) = fly_reconfigured(Some(&stiffer), CLIMB);
        assert_eq!(before, after, "reconfigure does not reset the integrators");
        assert_eq!(c.cfg.kp_pos_per_s, 2.0);
        let err = |tr: &[Sample], t: f64| (at(tr, t).input.pos_ned_m - CLIMB).norm();
        assert!(err(&fast, 2.0) < 0.5 * err(&plain, 2.0), "{} vs {}", err(&fast, 2.0), err(&plain, 2.0));
    }

    #[test]
    fn given_integrators_when_limits_tightened_then_clamped() {
        let mut c = pid();
        let p = Vector3::new(0.0, 0.0, -2.0);
        let mut input = hover_input(p, 0.0);
        input.rate_frd_radps.x = -0.1;
        input.vel_ned_mps.x = -0.5;
        for _ in 0..20_000 {
            c.update(&input, &Reference::position(p, 0.0));
        }
        assert!(c.rate_integral_nm().x > 0.29 && c.velocity_integral_mps2().x > 2.9);
        c.reconfigure(&PidConfig { rate_integral_max_nm: 0.1, vel_integral_max_mps2: 1.0, ..PidConfig::default() });
        assert_eq!((c.rate_integral_nm().x, c.velocity_integral_mps2().x), (0.1, 1.0));
    }

    #[test]
    fn given_hover_input_at_hover_reference_when_ticked_then_hover_pwm() {
        let mut c = pid();
        let p = Vector3::new(3.0, -2.0, -5.0);
        let hover = Airframe::default().hover_pwm_us();
        for _ in 0..2000 {
            let pwm = c.update(&hover_input(p, 0.3), &Reference::position(p, 0.3));
            for x in pwm {
                assert!((x - hover).abs() < 1.0, "{pwm:?} vs {hover}");
            }
        }
    }

    #[test]
    fn given_attitude_error_when_quaternion_p_then_rate_follows_shortest_path() {
        let mut c = pid();
        let p = Vector3::new(0.0, 0.0, -2.0);
        c.update(&hover_input(p, 0.0), &Reference::attitude(Vector3::new(0.1, 0.0, 0.0), -2.0));
        let expected = 2.0 * 2.778 * (0.05_f64).sin();
        assert!((c.rate_sp_radps.x - expected).abs() < 1e-9, "{}", c.rate_sp_radps);
        let mut c = pid();
        let pi = std::f64::consts::PI;
        c.update(&hover_input(p, -pi + 0.05), &Reference::attitude(Vector3::new(0.0, 0.0, pi - 0.05), -2.0));
        assert!(c.rate_sp_radps.z < 0.0 && c.rate_sp_radps.z > -0.2, "{}", c.rate_sp_radps);
    }

    #[test]
    fn given_persistent_rate_error_when_unsaturated_then_integral_torque_limited_to_0_3_nm() {
        let mut c = pid();
        let p = Vector3::new(0.0, 0.0, -2.0);
        let mut input = hover_input(p, 0.0);
        input.rate_frd_radps.x = -0.1;
        for _ in 0..5000 {
            c.update(&input, &Reference::position(p, 0.0));
        }
        assert!((c.rate_integral_nm().x - 0.3).abs() < 1e-12, "{}", c.rate_integral_nm());
        assert!(!c.held.saturation.roll);
    }

    #[test]
    fn given_saturating_rate_error_when_ticking_then_rate_integrator_frozen() {
        // The spec's literal reading; by default roll/pitch integrate through saturation (the prototype).
        let mut c =
            PidController::new(&PidConfig { freeze_roll_pitch: true, ..PidConfig::default() }, LoopRates::default());
        let p = Vector3::new(0.0, 0.0, -2.0);
        let mut input = hover_input(p, 0.0);
        input.rate_frd_radps.x = -10.0;
        c.update(&input, &Reference::position(p, 0.0));
        let after_first = c.rate_integral_nm();
        assert!(c.held.saturation.roll);
        for _ in 0..100 {
            c.update(&input, &Reference::position(p, 0.0));
        }
        assert_eq!(c.rate_integral_nm().x, after_first.x);
        let mut default = pid();
        default.update(&input, &Reference::position(p, 0.0));
        let first = default.rate_integral_nm();
        assert!(default.held.saturation.roll);
        default.update(&input, &Reference::position(p, 0.0));
        assert_ne!(default.rate_integral_nm().x, first.x, "by default roll integrates through saturation");
    }

    #[test]
    fn given_vertical_clamp_in_error_direction_when_ticking_then_velocity_integral_held() {
        let p = Vector3::new(0.0, 0.0, -2.0);
        for target_d in [-10.0, 10.0] {
            let mut c = pid();
            for _ in 0..500 {
                c.update(&hover_input(p, 0.0), &Reference::position(Vector3::new(0.0, 0.0, target_d), 0.0));
            }
            assert_eq!(c.velocity_integral_mps2().z, 0.0, "target {target_d}");
        }
        // A small step is not clamped and integrates.
        let mut c = pid();
        for _ in 0..500 {
            c.update(&hover_input(p, 0.0), &Reference::position(Vector3::new(0.0, 0.0, -2.1), 0.0));
        }
        assert!(c.velocity_integral_mps2().z < -0.1, "{}", c.velocity_integral_mps2());
    }

    #[test]
    fn given_persistent_velocity_error_when_unsaturated_then_integral_limited_to_3() {
        let mut c = pid();
        let p = Vector3::new(0.0, 0.0, -2.0);
        let mut input = hover_input(p, 0.0);
        input.vel_ned_mps.x = -0.5;
        for _ in 0..20_000 {
            c.update(&input, &Reference::position(p, 0.0));
        }
        assert!((c.velocity_integral_mps2().x - 3.0).abs() < 1e-12, "{}", c.velocity_integral_mps2());
    }

    #[test]
    fn given_1_m_step_when_flown_on_toy_plant_then_settles() {
        let mut plant = ToyPlant::new(Vector3::new(0.0, 0.0, -2.0), Vector3::zeros());
        let mut c = pid();
        let target = Vector3::new(1.0, 0.0, -3.0);
        let tr = fly(&mut c, &mut plant, 500, 20.0, |_| Reference::position(target, 0.0));
        let last = at(&tr, 20.0).input;
        assert!((last.pos_ned_m - target).norm() < 0.02, "{}", last.pos_ned_m);
        assert!(max_after(&tr, 0.0, |s| s.input.pos_ned_m.x) < 1.1, "N overshoot");
    }

    #[test]
    fn given_0_2_rad_attitude_step_when_flown_then_tracks() {
        let mut plant = ToyPlant::new(Vector3::new(0.0, 0.0, -2.0), Vector3::zeros());
        let mut c = pid();
        let sp = Vector3::new(0.2, -0.2, 0.2);
        let tr = fly(&mut c, &mut plant, 500, 8.0, |_| Reference::attitude(sp, -2.0));
        let last = at(&tr, 8.0).input;
        assert!((last.euler_rad - sp).abs().max() < 0.01, "{}", last.euler_rad);
        assert!(max_after(&tr, 0.0, |s| s.input.euler_rad.x) < 0.2 * 1.15, "roll overshoot");
        assert!((last.pos_ned_m.z + 2.0).abs() < 0.2, "altitude {}", last.pos_ned_m.z);
    }

    #[test]
    fn the_rate_d_acts_on_the_measured_rate_and_is_off_by_default() {
        use crate::core::control::Reference;
        let hold = Reference::attitude(Vector3::zeros(), -3.0);
        let input = |p_radps: f64| ControlInput {
            pos_ned_m: Vector3::new(0.0, 0.0, -3.0),
            vel_ned_mps: Vector3::zeros(),
            euler_rad: Vector3::zeros(),
            rate_frd_radps: Vector3::new(p_radps, 0.0, 0.0),
            specific_force_frd_mps2: Vector3::new(0.0, 0.0, -9.81),
        };
        let fly = |krd: f64| {
            let cfg = PidConfig { krd_rate_s: [krd, krd, 0.0], ..PidConfig::default() };
            let mut c = PidController::new(&cfg, LoopRates::default());
            c.update(&input(0.0), &hold);
            // The roll rate rises: the D term opposes the rise with a negative roll moment.
            c.update(&input(0.2), &hold);
            c.moment_cmd_nm.x
        };
        let (without, with) = (fly(0.0), fly(0.05));
        assert!(with < without - 1e-3, "D on the measurement opposes a rising rate: {with} vs {without}");
        // A setpoint change alone does not kick it: the derivative is of the measurement, not the error.
        let cfg = PidConfig { krd_rate_s: [0.05, 0.05, 0.0], ..PidConfig::default() };
        let mut c = PidController::new(&cfg, LoopRates::default());
        c.update(&input(0.0), &hold);
        c.update(&input(0.0), &Reference::attitude(Vector3::new(0.3, 0.0, 0.0), -3.0));
        assert_eq!(c.rate_dot_frd_radps2, Vector3::zeros());
        // A negative gain or a cutoff past the loop's reach is refused when set.
        let mut config = crate::core::control::ControllerConfig::default();
        config.pid.krd_rate_s = [0.0, -0.1, 0.0];
        assert!(config.validate().unwrap_err().to_string().contains("krd_rate_s[1]"));
        config.pid.krd_rate_s = [0.0; 3];
        config.pid.rate_d_cutoff_hz = 400.0;
        assert!(config.validate().unwrap_err().to_string().contains("pid.rate_d_cutoff_hz"));
    }
}
