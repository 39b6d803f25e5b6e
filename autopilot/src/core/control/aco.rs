//! The paper's ACO controller read as indirect adaptive dynamic inversion (spec A.1, A.4): LMS
//! (Eqs 11-18) identifies the control effectiveness and a lumped disturbance of the translation
//! (Eqs 19-21) and rotation (Eq 9) dynamics online, and fixed linear laws are inverted through them.
//!
//! In: a [`ControlInput`] (NED/FRD, SI units) and a [`Reference`] once per inner tick (500 Hz nominal).
//! Out: four rotor PWM commands (µs). Per tick, in the spec's order (A.4): 1 rotor-lag model, 2
//! translation LMS (8 Hz LPF on both sides), 3 rotation LMS (15 Hz LPF, filtered-gyro derivative,
//! averaged moment), 4 position loop every `inner_hz / position_hz`-th tick (Eqs 19-21, limiter, attitude
//! extraction), 5 collective (Eq 20 z row), 6 attitude law (Eqs 22-24), 7 rate loop (Eq 9 inverted),
//! 8 distributor (Eqs 26-27) and lift curve (Eq 10).
//!
//! [`AcoController::reconfigure`] takes new gains, limits, adaptation rates, bounds, filter cutoffs and
//! nominal model while flying and keeps the identified weights, the filter histories, the rotor model and
//! the position integral; the loop rates are fixed at construction.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::distributor::{ActuatorLimits, LimitedThrust, MixerSaturation, limit_thrust_vector, mix_forward};
use super::filters::LowPass2Vec3;
use super::frames::{body_z_in_ned, euler_rates_to_body, rotation_ned_frd, wrap_pi};
use super::lms::{LmsBounds, LmsChannel};
use super::rate_level::RateShaper;
use super::{
    Airframe, ControlInput, Controller, ControllerKind, HeldOutput, LoopClock, LoopRates, Reference,
    attitude_setpoint_rad, clip_abs, commanded_collective_n, inputs_finite, tilt_lead_mps2,
};

/// ACO constants, gains, adaptation rates and bounds (spec A.1, A.3, A.4). Default = the spec's values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AcoConfig {
    /// Nominal model m̄, Ī, l, λ, τ̄, g.
    pub airframe: Airframe,
    /// Rotor and thrust limits (distributor, limiter, collective).
    pub limits: ActuatorLimits,
    /// Normalisation of the rotation regressor, alpha_ref (rad/s²); the nominal `c_j`.
    pub alpha_ref_radps2: f64,
    /// Position gain Kp (1/s).
    pub kp_pos_per_s: f64,
    /// Velocity gain Kv (1/s).
    pub kv_vel_per_s: f64,
    /// Attitude gains Kη (1/s), (roll, pitch, yaw).
    pub k_att_per_s: [f64; 3],
    /// Rate gains Kω (1/s), FRD.
    pub k_rate_per_s: [f64; 3],
    /// Desired body-rate limits (rad/s), FRD.
    pub rate_limit_radps: [f64; 3],
    /// Velocity-command limit on N and E (m/s), per axis.
    pub vel_limit_ne_mps: f64,
    /// Velocity-command limit on D (m/s).
    pub vel_limit_d_mps: f64,
    /// Limit on the horizontal norm of the desired acceleration (m/s²).
    pub acc_limit_ne_mps2: f64,
    /// Limit on the vertical desired acceleration (m/s²).
    pub acc_limit_d_mps2: f64,
    /// Translation gain-weight adaptation rate gamma_w,T = 2 mu f_s (1/s).
    pub gamma_w_t_per_s: f64,
    /// Translation bias-weight adaptation rate gamma_b,T (1/s).
    pub gamma_b_t_per_s: f64,
    /// Rotation gain-weight adaptation rate gamma_c,R (1/s).
    pub gamma_c_r_per_s: f64,
    /// Rotation bias-weight adaptation rate gamma_d,R (1/s).
    pub gamma_d_r_per_s: f64,
    /// Cutoff of the translation LPF (Hz).
    pub lpf_translation_hz: f64,
    /// Cutoff of the rotation LPF (Hz).
    pub lpf_rotation_hz: f64,
    /// Bounds on `w_i` as multiples of g: `[0.5, 2]`.
    pub w_t_bounds_g: [f64; 2],
    /// Bound on `|b_i|` (m/s²).
    pub b_t_max_mps2: f64,
    /// Bounds on `c_j` as multiples of alpha_ref: `[0.5, 2]`.
    pub c_r_bounds_alpha_ref: [f64; 2],
    /// Bound on `|d_j|` (rad/s²).
    pub d_r_max_radps2: f64,
    /// Optional zoned position integral (spec A.4, "optional on hardware"); off by default.
    pub pos_integral_enabled: bool,
    /// Position integral gain Ki (1/s): `v_c = Kp (e_p + Ki ∫e_p dt) + v_ref`.
    pub ki_pos_per_s: f64,
    /// The integral accumulates on an axis only while `|e_p,i|` is below this (m).
    pub pos_integral_zone_m: f64,
    /// False freezes every LMS weight at its initial value (the "adaptation off" experiment).
    pub adaptation_enabled: bool,
}

impl Default for AcoConfig {
    fn default() -> Self {
        Self {
            airframe: Airframe::default(),
            limits: ActuatorLimits::default(),
            alpha_ref_radps2: 10.0,
            kp_pos_per_s: 0.6667,
            kv_vel_per_s: 2.16,
            k_att_per_s: [2.778, 2.778, 1.389],
            k_rate_per_s: [9.0, 9.0, 4.5],
            rate_limit_radps: [3.5, 3.5, 1.5],
            vel_limit_ne_mps: 3.0,
            vel_limit_d_mps: 2.0,
            acc_limit_ne_mps2: 5.0,
            acc_limit_d_mps2: 4.0,
            gamma_w_t_per_s: 10.0,
            gamma_b_t_per_s: 5.0,
            gamma_c_r_per_s: 20.0,
            gamma_d_r_per_s: 5.0,
            lpf_translation_hz: 8.0,
            lpf_rotation_hz: 15.0,
            w_t_bounds_g: [0.5, 2.0],
            b_t_max_mps2: 4.0,
            c_r_bounds_alpha_ref: [0.5, 2.0],
            d_r_max_radps2: 8.0,
            pos_integral_enabled: false,
            ki_pos_per_s: 0.1,
            pos_integral_zone_m: 0.25,
            adaptation_enabled: true,
        }
    }
}

/// The identified weights, readable for logging and tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AcoWeights {
    /// Translation effectiveness `w_i = g m̄ / m` (m/s²), N, E, D.
    pub w_t: [f64; 3],
    /// Translation disturbance `b_i` (m/s²), N, E, D.
    pub b_t_mps2: [f64; 3],
    /// Rotation effectiveness `c_j` (rad/s², nominal alpha_ref), FRD.
    pub c_r: [f64; 3],
    /// Rotation disturbance `d_j` (rad/s²), FRD.
    pub d_r_radps2: [f64; 3],
    /// Mass estimate per axis `m̂_i = m̄ g / w_i` (kg).
    pub mass_est_kg: [f64; 3],
}

/// The gain (1/s) on the angle the rate loop has missed at the rate level ([`RateShaper`]): the ACO's
/// rate loop has no integrator of its own.
const RATE_LEVEL_ANGLE_GAIN_PER_S: f64 = 1.0;

/// The ACO controller (spec A.4).
#[derive(Debug, Clone)]
pub struct AcoController {
    cfg: AcoConfig,
    /// Inner-loop rate f_s (Hz).
    sample_hz: f64,
    /// Inner period Δ, position period and tick.
    clock: LoopClock,
    /// `1 - exp(-Δ/τ̄)`: the exact discretisation of the rotor lag over one tick.
    rotor_lag_factor: f64,
    started: bool,

    // Step 1: rotor model.
    rotor_est_n: [f64; 4],
    rotor_cmd_n: [f64; 4],
    moment_est_prev_nm: Vector3<f64>,

    // Step 2: translation LMS.
    lpf_specific_force: LowPass2Vec3,
    lpf_thrust_force: LowPass2Vec3,
    lms_t: [LmsChannel; 3],

    // Step 3: rotation LMS.
    lpf_gyro: LowPass2Vec3,
    lpf_moment: LowPass2Vec3,
    gyro_filtered_prev_radps: Vector3<f64>,
    rotation_primed: bool,
    lms_r: [LmsChannel; 3],

    // Step 4: position loop.
    pos_integral_m_s: Vector3<f64>,
    vertical_thrust_n: f64,
    attitude_sp_rad: Vector3<f64>,
    last_limit: Option<LimitedThrust>,

    // Outputs.
    collective_n: f64,
    moment_cmd_nm: Vector3<f64>,
    rate_sp_radps: Vector3<f64>,
    /// The rate level's setpoint shaping (reset while an attitude is flown).
    rate_shaper: RateShaper,
    held: HeldOutput,
}

impl AcoController {
    /// A controller at hover, weights at the nominal model, running at `rates`.
    #[must_use]
    pub fn new(config: &AcoConfig, rates: LoopRates) -> Self {
        let cfg = config.clone();
        let a = cfg.airframe;
        let fs = f64::from(rates.inner_hz.max(1));
        let dt_s = rates.inner_dt_s();
        let g = a.gravity_mps2;
        let hover_n = a.hover_rotor_lift_n();
        let rotor_est_n = [hover_n; 4];
        let (_, moment0) = mix_forward(&rotor_est_n, &a);

        let mut lpf_specific_force = LowPass2Vec3::new(cfg.lpf_translation_hz, fs);
        lpf_specific_force.reset_to(&Vector3::new(0.0, 0.0, -g));
        let mut lpf_thrust_force = LowPass2Vec3::new(cfg.lpf_translation_hz, fs);
        lpf_thrust_force.reset_to(&Vector3::new(0.0, 0.0, -a.mass_kg * g));
        let t_bounds = translation_bounds(&cfg);
        let lms_t = [LmsChannel::new(g, 0.0, cfg.gamma_w_t_per_s, cfg.gamma_b_t_per_s, fs, t_bounds); 3];

        let mut lpf_moment = LowPass2Vec3::new(cfg.lpf_rotation_hz, fs);
        lpf_moment.reset_to(&moment0);
        let r_bounds = rotation_bounds(&cfg);
        let lms_r =
            [LmsChannel::new(cfg.alpha_ref_radps2, 0.0, cfg.gamma_c_r_per_s, cfg.gamma_d_r_per_s, fs, r_bounds); 3];

        Self {
            sample_hz: fs,
            clock: LoopClock::new(rates),
            rotor_lag_factor: 1.0 - (-dt_s / a.rotor_tau_s).exp(),
            started: false,
            rotor_est_n,
            rotor_cmd_n: rotor_est_n,
            moment_est_prev_nm: moment0,
            lpf_specific_force,
            lpf_thrust_force,
            lms_t,
            lpf_gyro: LowPass2Vec3::new(cfg.lpf_rotation_hz, fs),
            lpf_moment,
            gyro_filtered_prev_radps: Vector3::zeros(),
            rotation_primed: false,
            lms_r,
            pos_integral_m_s: Vector3::zeros(),
            vertical_thrust_n: a.mass_kg * g,
            attitude_sp_rad: Vector3::zeros(),
            last_limit: None,
            collective_n: a.mass_kg * g,
            moment_cmd_nm: Vector3::zeros(),
            rate_sp_radps: Vector3::zeros(),
            rate_shaper: RateShaper::default(),
            held: HeldOutput::hover(&a),
            cfg,
        }
    }

    /// Take `config` from the next [`Controller::update`] on, keeping the adaptive state: the LMS weights
    /// (projected onto new, tighter bounds, which marks them as clipped), the filter histories (the LPFs
    /// are retuned, not restarted), the rotor-lag model, the position integral (kept, and not applied
    /// while `pos_integral_enabled` is false) and the last setpoints. A new `alpha_ref_radps2` rescales the
    /// rotation gain weights `c_j` by the ratio of the new to the old value, so the identified model
    /// `c_j psi_j` is unchanged (alpha_ref only normalises the regressor). A new nominal model is used as
    /// given: the translation weights stay relative to it (`m̂ = m̄ g / w`) and the LMS re-identifies.
    /// The loop rates are those of [`AcoController::new`]; rebuild the controller to change them.
    pub fn reconfigure(&mut self, config: &AcoConfig) {
        let old = std::mem::replace(&mut self.cfg, config.clone());
        let cfg = &self.cfg;
        let fs = self.sample_hz;
        self.rotor_lag_factor = 1.0 - (-self.clock.dt_s / cfg.airframe.rotor_tau_s).exp();
        if cfg.lpf_translation_hz != old.lpf_translation_hz {
            self.lpf_specific_force.retune(cfg.lpf_translation_hz, fs);
            self.lpf_thrust_force.retune(cfg.lpf_translation_hz, fs);
        }
        if cfg.lpf_rotation_hz != old.lpf_rotation_hz {
            self.lpf_gyro.retune(cfg.lpf_rotation_hz, fs);
            self.lpf_moment.retune(cfg.lpf_rotation_hz, fs);
        }
        if cfg.alpha_ref_radps2 != old.alpha_ref_radps2 {
            let ratio = cfg.alpha_ref_radps2 / old.alpha_ref_radps2;
            for ch in &mut self.lms_r {
                ch.rescale_w(ratio);
            }
        }
        let t_bounds = translation_bounds(cfg);
        for ch in &mut self.lms_t {
            ch.reconfigure(cfg.gamma_w_t_per_s, cfg.gamma_b_t_per_s, fs, t_bounds);
        }
        let r_bounds = rotation_bounds(cfg);
        for ch in &mut self.lms_r {
            ch.reconfigure(cfg.gamma_c_r_per_s, cfg.gamma_d_r_per_s, fs, r_bounds);
        }
    }

    /// The identified weights.
    #[must_use]
    pub fn weights(&self) -> AcoWeights {
        let mg = self.cfg.airframe.mass_kg * self.cfg.airframe.gravity_mps2;
        AcoWeights {
            w_t: self.lms_t.map(|c| c.w()),
            b_t_mps2: self.lms_t.map(|c| c.b()),
            c_r: self.lms_r.map(|c| c.w()),
            d_r_radps2: self.lms_r.map(|c| c.b()),
            mass_est_kg: self.lms_t.map(|c| mg / c.w()),
        }
    }

    /// The modelled achieved rotor lifts F̂ (N).
    #[must_use]
    pub fn rotor_lift_estimate_n(&self) -> [f64; 4] {
        self.rotor_est_n
    }

    /// The saturation report of the last distribution.
    #[must_use]
    pub fn last_saturation(&self) -> MixerSaturation {
        self.held.saturation
    }

    /// Step 1: the rotor-lag model, `F̂ <- F̂ + (1 - e^(-Δ/τ̄)) (F_cmd[k-1] - F̂)`; returns `(T̂, M̂)`.
    fn step_rotor_model(&mut self) -> (f64, Vector3<f64>) {
        for (est, cmd) in self.rotor_est_n.iter_mut().zip(self.rotor_cmd_n.iter()) {
            *est += self.rotor_lag_factor * (cmd - *est);
        }
        mix_forward(&self.rotor_est_n, &self.cfg.airframe)
    }

    /// Step 2: the translation LMS on the 8 Hz-filtered specific force and modelled thrust force.
    fn step_translation_lms(&mut self, input: &ControlInput, thrust_est_n: f64) {
        let a = self.cfg.airframe;
        let r = rotation_ned_frd(&input.euler_rad);
        let s_ned = r * input.specific_force_frd_mps2;
        let u_hat_ned = -thrust_est_n * body_z_in_ned(&input.euler_rad);
        let y = self.lpf_specific_force.update(&s_ned);
        let phi = self.lpf_thrust_force.update(&u_hat_ned) / (a.mass_kg * a.gravity_mps2);
        let adapt = self.cfg.adaptation_enabled;
        for (i, ch) in self.lms_t.iter_mut().enumerate() {
            ch.update(phi[i], y[i], adapt);
        }
    }

    /// Step 3: the rotation LMS on the 15 Hz-filtered gyro derivative and averaged modelled moment.
    fn step_rotation_lms(&mut self, input: &ControlInput, moment_est_nm: &Vector3<f64>) {
        let a = self.cfg.airframe;
        let gyro_f = self.lpf_gyro.update(&input.rate_frd_radps);
        let moment_avg = 0.5 * (moment_est_nm + self.moment_est_prev_nm);
        let moment_f = self.lpf_moment.update(&moment_avg);
        if self.rotation_primed {
            let alpha = (gyro_f - self.gyro_filtered_prev_radps) / self.clock.dt_s;
            let gamma = a.gyroscopic_radps2(&gyro_f);
            let inertia = a.inertia();
            let adapt = self.cfg.adaptation_enabled;
            for (j, ch) in self.lms_r.iter_mut().enumerate() {
                let psi = moment_f[j] / (inertia[j] * self.cfg.alpha_ref_radps2);
                ch.update(psi, alpha[j] - gamma[j], adapt);
            }
        }
        self.gyro_filtered_prev_radps = gyro_f;
        self.moment_est_prev_nm = *moment_est_nm;
        self.rotation_primed = true;
    }

    /// Step 4: the position loop (Eqs 19-21), the shared limiter and the attitude extraction.
    fn step_position_loop(&mut self, input: &ControlInput, reference: &Reference) {
        let c = &self.cfg;
        let g = c.airframe.gravity_mps2;
        let attitude_only = reference.attitude_rad.is_some();
        let e_p = reference.pos_ned_m - input.pos_ned_m;
        if c.pos_integral_enabled {
            for i in 0..3 {
                if (i == 2 || !attitude_only) && e_p[i].abs() < c.pos_integral_zone_m {
                    self.pos_integral_m_s[i] += e_p[i] * self.clock.pos_dt_s;
                }
            }
        }
        // A disabled integral is not applied (it is zero unless a reconfigure turned it off).
        let e_p_eff = if c.pos_integral_enabled { e_p + c.ki_pos_per_s * self.pos_integral_m_s } else { e_p };
        let v_lim = [c.vel_limit_ne_mps, c.vel_limit_ne_mps, c.vel_limit_d_mps];
        let v_c = clip_abs(&(c.kp_pos_per_s * e_p_eff + reference.vel_ned_mps), &v_lim);
        let mut a_d = c.kv_vel_per_s * (v_c - input.vel_ned_mps)
            + reference.acc_ned_mps2
            + tilt_lead_mps2(&reference.jerk_ned_mps3, &c.k_att_per_s);
        let a_ne = a_d.x.hypot(a_d.y);
        if a_ne > c.acc_limit_ne_mps2 {
            let s = c.acc_limit_ne_mps2 / a_ne;
            a_d.x *= s;
            a_d.y *= s;
        }
        a_d.z = a_d.z.clamp(-c.acc_limit_d_mps2, c.acc_limit_d_mps2);

        let mass_est = self.weights().mass_est_kg;
        let mut u = Vector3::zeros();
        for i in 0..3 {
            let gravity = if i == 2 { g } else { 0.0 };
            u[i] = mass_est[i] * (a_d[i] - gravity - self.lms_t[i].b());
        }
        if attitude_only {
            u.x = 0.0;
            u.y = 0.0;
        }
        let limited = limit_thrust_vector(&u, &c.limits);
        self.vertical_thrust_n = limited.vertical_n;
        self.attitude_sp_rad = attitude_setpoint_rad(reference, &limited);
        self.last_limit = Some(limited);
        self.clock.position_loop_done();
    }
}

/// Projection bounds of the translation LMS: `w_i` in `w_t_bounds_g` times g, `|b_i| <= b_t_max_mps2`.
fn translation_bounds(cfg: &AcoConfig) -> LmsBounds {
    let g = cfg.airframe.gravity_mps2;
    LmsBounds { w_min: cfg.w_t_bounds_g[0] * g, w_max: cfg.w_t_bounds_g[1] * g, b_abs_max: cfg.b_t_max_mps2 }
}

/// Projection bounds of the rotation LMS: `c_j` in `c_r_bounds_alpha_ref` times alpha_ref,
/// `|d_j| <= d_r_max_radps2`.
fn rotation_bounds(cfg: &AcoConfig) -> LmsBounds {
    LmsBounds {
        w_min: cfg.c_r_bounds_alpha_ref[0] * cfg.alpha_ref_radps2,
        w_max: cfg.c_r_bounds_alpha_ref[1] * cfg.alpha_ref_radps2,
        b_abs_max: cfg.d_r_max_radps2,
    }
}

impl Controller for AcoController {
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4] {
        if !inputs_finite(input, reference) {
            // The rotors keep answering the held command; everything that reads the input waits, and
            // the gyro derivative is not taken across the gap.
            let (_, moment_est) = self.step_rotor_model();
            self.moment_est_prev_nm = moment_est;
            self.rotation_primed = false;
            self.clock.advance();
            return self.held.pwm_us;
        }
        if !self.started {
            self.lpf_gyro.reset_to(&input.rate_frd_radps);
            self.started = true;
        }
        let a = self.cfg.airframe;

        // 1. Rotor model.
        let (thrust_est_n, moment_est_nm) = self.step_rotor_model();
        // 2. Translation LMS.
        self.step_translation_lms(input, thrust_est_n);
        // 3. Rotation LMS (the update itself is skipped on the first tick).
        self.step_rotation_lms(input, &moment_est_nm);
        // 4. Position loop every `pos_divider`-th tick (and on the first good one); not at the rate level.
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
        // 5. Collective (or the thrust asked for directly; hover at the rate level without one).
        let vertical_n = if rates_only { a.mass_kg * a.gravity_mps2 } else { self.vertical_thrust_n };
        self.collective_n = commanded_collective_n(reference, vertical_n, &input.euler_rad, &self.cfg.limits, true);
        // 6. Attitude (Eqs 22-24).
        let eta = &input.euler_rad;
        let sp = &self.attitude_sp_rad;
        let e_eta = Vector3::new(sp.x - eta.x, sp.y - eta.y, wrap_pi(sp.z - eta.z));
        let eta_dot_d = Vector3::from(self.cfg.k_att_per_s).component_mul(&e_eta);
        let rate_sp = match (rates_only, reference.rate_frd_radps) {
            // The rate level: the body rates asked for, shaped for the rate loop; the attitude loop off.
            (true, Some(rates)) => {
                let (k, dt) = (&self.cfg.k_rate_per_s, self.clock.dt_s);
                self.rate_shaper
                    .shape(&rates, &input.rate_frd_radps, k, RATE_LEVEL_ANGLE_GAIN_PER_S, dt)
                    .setpoint_frd_radps
            }
            (_, feed_forward) => {
                self.rate_shaper.reset();
                let from_attitude = euler_rates_to_body(eta) * eta_dot_d;
                feed_forward.map_or(from_attitude, |ff| from_attitude + ff)
            }
        };
        self.rate_sp_radps = clip_abs(&rate_sp, &self.cfg.rate_limit_radps);
        // 7. Rate loop (Eq 9 inverted through c_j, d_j and the gyroscopic term).
        let omega = &input.rate_frd_radps;
        let alpha_d = Vector3::from(self.cfg.k_rate_per_s).component_mul(&(self.rate_sp_radps - omega));
        let gamma = a.gyroscopic_radps2(omega);
        let inertia = a.inertia();
        for j in 0..3 {
            self.moment_cmd_nm[j] =
                inertia[j] * self.cfg.alpha_ref_radps2 * (alpha_d[j] - self.lms_r[j].b() - gamma[j])
                    / self.lms_r[j].w();
        }
        // 8. Distributor and lift curve.
        self.clock.advance();
        if let Some(d) = self.held.distribute(self.collective_n, &self.moment_cmd_nm, &a, &self.cfg.limits) {
            self.rotor_cmd_n = d.forces_n;
        }
        self.held.pwm_us
    }

    fn reconfigure(&mut self, config: &super::ControllerConfig) {
        AcoController::reconfigure(self, &config.aco);
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::ACO
    }

    fn telemetry(&self) -> Vec<(&'static str, f64)> {
        let w = self.weights();
        let limit = self.last_limit;
        vec![
            ("aco.w_t_n", w.w_t[0]),
            ("aco.w_t_e", w.w_t[1]),
            ("aco.w_t_d", w.w_t[2]),
            ("aco.b_t_n_mps2", w.b_t_mps2[0]),
            ("aco.b_t_e_mps2", w.b_t_mps2[1]),
            ("aco.b_t_d_mps2", w.b_t_mps2[2]),
            ("aco.c_r_x", w.c_r[0]),
            ("aco.c_r_y", w.c_r[1]),
            ("aco.c_r_z", w.c_r[2]),
            ("aco.d_r_x_radps2", w.d_r_radps2[0]),
            ("aco.d_r_y_radps2", w.d_r_radps2[1]),
            ("aco.d_r_z_radps2", w.d_r_radps2[2]),
            ("aco.mass_est_n_kg", w.mass_est_kg[0]),
            ("aco.mass_est_e_kg", w.mass_est_kg[1]),
            ("aco.mass_est_d_kg", w.mass_est_kg[2]),
            ("aco.pos_int_n_m_s", self.pos_integral_m_s.x),
            ("aco.pos_int_e_m_s", self.pos_integral_m_s.y),
            ("aco.pos_int_d_m_s", self.pos_integral_m_s.z),
            ("aco.vertical_thrust_n", self.vertical_thrust_n),
            ("aco.collective_n", self.collective_n),
            ("aco.moment_x_nm", self.moment_cmd_nm.x),
            ("aco.moment_y_nm", self.moment_cmd_nm.y),
            ("aco.moment_z_nm", self.moment_cmd_nm.z),
            ("aco.rate_sp_x_radps", self.rate_sp_radps.x),
            ("aco.rate_sp_y_radps", self.rate_sp_radps.y),
            ("aco.rate_sp_z_radps", self.rate_sp_radps.z),
            ("aco.yaw_factor", self.held.saturation.yaw_factor),
            ("aco.roll_pitch_scale", self.held.saturation.roll_pitch_scale),
            ("aco.vertical_clamped", f64::from(u8::from(limit.is_some_and(|l| l.vertical_clamped)))),
            ("aco.horizontal_limited", f64::from(u8::from(limit.is_some_and(|l| l.horizontal_limited)))),
        ]
    }

    fn weights_at_bounds(&self) -> bool {
        self.lms_t.iter().chain(self.lms_r.iter()).any(LmsChannel::hit_bound)
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
        max_after, mismatch,
    };
    use crate::core::control::{ControllerConfig, toy_plant};

    fn aco() -> AcoController {
        AcoController::new(&AcoConfig::default(), LoopRates::default())
    }

    /// The default controller through the shared harness ([`toy_plant::fly_reconfigured`]): 4 s holding
    /// `(0, 0, -1.5)` (the weights adapt away from the nominal), then `reconfigure(config)` when given, then
    /// 3 s flying to `target`; the state compared is the weights.
    fn fly_reconfigured(config: Option<&AcoConfig>, target: Vector3<f64>) -> Reconfigured<AcoWeights, AcoController> {
        let config = config.map(|aco| ControllerConfig { aco: aco.clone(), ..ControllerConfig::default() });
        let hold = Vector3::new(0.0, 0.0, -1.5);
        toy_plant::fly_reconfigured(aco(), (hold, 4.0), config.as_ref(), (target, 3.0), AcoController::weights)
    }

    /// Second-leg targets: a diagonal step (everything moves) and a 1 m climb (the D loop alone).
    const DIAGONAL: Vector3<f64> = Vector3::new(1.0, 0.5, -2.5);
    const CLIMB: Vector3<f64> = Vector3::new(0.0, 0.0, -2.5);

    #[test]
    fn given_adapted_controller_when_reconfigured_with_same_config_then_trajectory_bit_identical() {
        let plain = fly_reconfigured(None, DIAGONAL);
        let same = fly_reconfigured(Some(&AcoConfig::default()), DIAGONAL);
        assert_same_config_reconfigure_is_bit_identical(&plain, &same);
        assert_ne!(plain.1.w_t, [9.81; 3], "the weights adapted before the reconfigure");
        assert!(plain.0.iter().zip(same.0.iter()).all(|(a, b)| a.input == b.input));
    }

    #[test]
    fn given_adapted_controller_when_position_gain_raised_then_weights_kept_and_target_reached_sooner() {
        let (plain, _, _, _) = fly_reconfigured(None, CLIMB);
        let stiffer = AcoConfig { kp_pos_per_s: 2.0, ..AcoConfig::default() };
        let (fast, before, after, c) = fly_reconfigured(Some(&stiffer), CLIMB);
        assert_eq!(before, after, "reconfigure does not reset the weights");
        assert_eq!(c.cfg.kp_pos_per_s, 2.0);
        let err = |tr: &[Sample], t: f64| (at(tr, t).input.pos_ned_m - CLIMB).norm();
        assert!(err(&fast, 2.0) < 0.5 * err(&plain, 2.0), "{} vs {}", err(&fast, 2.0), err(&plain, 2.0));
        assert!(!c.weights_at_bounds());
    }

    #[test]
    fn given_adapted_controller_when_bounds_tightened_then_weights_projected_and_flagged() {
        let mut c = aco();
        let p = Vector3::new(0.0, 0.0, -1.5);
        let mut plant = ToyPlant::new(p, Vector3::zeros());
        mismatch(&mut plant);
        fly(&mut c, &mut plant, 500, 4.0, |_| Reference::position(p, 0.0));
        let w_d = c.weights().w_t[2];
        assert!(w_d < 0.97 * 9.81 && !c.weights_at_bounds(), "{w_d}");
        c.reconfigure(&AcoConfig { w_t_bounds_g: [0.97, 2.0], ..AcoConfig::default() });
        assert_eq!(c.weights().w_t[2], 0.97 * 9.81);
        assert!(c.weights_at_bounds());
    }

    #[test]
    fn given_new_alpha_ref_when_reconfigured_then_rotation_weights_rescaled_and_command_unchanged() {
        let p = Vector3::new(0.0, 0.0, -1.5);
        let mut plant = ToyPlant::new(p, Vector3::zeros());
        mismatch(&mut plant);
        let mut c = aco();
        fly(&mut c, &mut plant, 500, 4.0, |_| Reference::position(p, 0.0));
        let mut scaled = c.clone();
        scaled.reconfigure(&AcoConfig { alpha_ref_radps2: 20.0, ..AcoConfig::default() });
        for (a, b) in c.weights().c_r.iter().zip(scaled.weights().c_r.iter()) {
            assert!((2.0 * a - b).abs() < 1e-12, "{a} -> {b}");
        }
        let input = plant.sense();
        let r = Reference::position(p, 0.0);
        // The same command up to rounding and the (now slower, in c/alpha_ref terms) LMS step of this tick.
        let (u, v) = (c.update(&input, &r), scaled.update(&input, &r));
        for (x, y) in u.iter().zip(v.iter()) {
            assert!((x - y).abs() < 1e-4, "{u:?} vs {v:?}");
        }
    }

    #[test]
    fn given_new_filter_cutoffs_when_reconfigured_then_filters_retuned_not_restarted() {
        let mut c = aco();
        let p = Vector3::new(0.0, 0.0, -2.0);
        for _ in 0..100 {
            c.update(&hover_input(p, 0.0), &Reference::position(p, 0.0));
        }
        let out = c.lpf_thrust_force.output();
        c.reconfigure(&AcoConfig { lpf_translation_hz: 12.0, lpf_rotation_hz: 20.0, ..AcoConfig::default() });
        assert_eq!(c.lpf_thrust_force.output(), out, "history kept");
        let pwm = c.update(&hover_input(p, 0.0), &Reference::position(p, 0.0));
        let hover = Airframe::default().hover_pwm_us();
        assert!(pwm.iter().all(|x| (x - hover).abs() < 1.0), "{pwm:?}");
        let fresh = LowPass2Vec3::new(12.0, 500.0);
        let mut probe = c.lpf_thrust_force;
        let mut reference = fresh;
        let step = Vector3::new(1.0, 0.0, 0.0);
        probe.reset_to(&Vector3::zeros());
        reference.reset_to(&Vector3::zeros());
        assert_eq!(probe.update(&step), reference.update(&step), "12 Hz design in place");
    }

    #[test]
    fn given_hover_input_at_hover_reference_when_ticked_then_hover_pwm_within_1_us() {
        let mut c = aco();
        let p = Vector3::new(3.0, -2.0, -5.0);
        let hover = Airframe::default().hover_pwm_us();
        assert!((hover - 1404.7).abs() < 0.2);
        for _ in 0..2000 {
            let pwm = c.update(&hover_input(p, 0.3), &Reference::position(p, 0.3));
            for x in pwm {
                assert!((x - hover).abs() < 1.0, "{pwm:?} vs {hover}");
            }
        }
        assert!(!c.weights_at_bounds());
        let w = c.weights();
        assert!((w.mass_est_kg[2] - 5.2).abs() < 1e-9, "{w:?}");
    }

    #[test]
    fn given_1_m_north_and_up_step_when_flown_on_toy_plant_then_settles_without_overshoot() {
        let mut plant = ToyPlant::new(Vector3::new(0.0, 0.0, -2.0), Vector3::zeros());
        let mut c = aco();
        let target = Vector3::new(1.0, 0.0, -3.0);
        let tr = fly(&mut c, &mut plant, 500, 15.0, |_| Reference::position(target, 0.0));
        let last = at(&tr, 15.0).input;
        assert!((last.pos_ned_m - target).norm() < 0.005, "{}", last.pos_ned_m);
        assert!(max_after(&tr, 0.0, |s| s.input.pos_ned_m.x) < 1.01, "N overshoot");
        assert!(max_after(&tr, 0.0, |s| s.input.euler_rad.x.max(s.input.euler_rad.y)) < 0.5);
        assert!(!c.weights_at_bounds());
        let hover = Airframe::default().hover_pwm_us();
        assert!(max_after(&tr, 12.0, |s| s.pwm_us.iter().map(|p| p - hover).fold(0.0, |m, d| d.abs().max(m))) < 1.0);
    }

    #[test]
    fn given_0_2_rad_attitude_step_when_flown_then_tracks_with_altitude_held() {
        let mut plant = ToyPlant::new(Vector3::new(0.0, 0.0, -2.0), Vector3::zeros());
        let mut c = aco();
        let sp = Vector3::new(0.2, -0.2, 0.2);
        let tr = fly(&mut c, &mut plant, 500, 6.0, |_| Reference::attitude(sp, -2.0));
        let last = at(&tr, 6.0).input;
        assert!((last.euler_rad - sp).abs().max() < 1e-3, "{}", last.euler_rad);
        assert!(max_after(&tr, 0.0, |s| s.input.euler_rad.x) < 0.2 * 1.02, "roll overshoot");
        assert!((last.pos_ned_m.z + 2.0).abs() < 0.05, "altitude {}", last.pos_ned_m.z);
        assert_eq!(c.attitude_setpoint_rad(), sp);
        // Attitude-only: no horizontal thrust demand.
        let lim = c.last_limit.expect("position loop ran");
        assert_eq!((lim.force_ned_n.x, lim.force_ned_n.y), (0.0, 0.0));
    }

    #[test]
    fn given_mismatch_truth_when_hovering_then_lms_identifies_it_and_beats_frozen_weights() {
        let p = Vector3::new(0.0, 0.0, -1.5);
        let run = |adapt: bool| {
            let mut plant = ToyPlant::new(p, Vector3::zeros());
            mismatch(&mut plant);
            let cfg = AcoConfig { adaptation_enabled: adapt, ..AcoConfig::default() };
            let mut c = AcoController::new(&cfg, LoopRates::default());
            let tr = fly(&mut c, &mut plant, 500, 12.0, |_| Reference::position(p, 0.0));
            (max_after(&tr, 8.0, |s| (s.input.pos_ned_m - p).norm()), c.weights(), c.weights_at_bounds())
        };
        let (err_adapt, w, at_bounds) = run(true);
        let (err_frozen, w_frozen, _) = run(false);
        assert!(err_adapt < 0.005, "adaptive steady error {err_adapt}");
        assert!(err_frozen > 4.0 * err_adapt, "frozen {err_frozen} vs adaptive {err_adapt}");
        assert!(!at_bounds);
        // In hover the rate loop cancels the torque disturbance (0.06, -0.06) N·m, so M = -τ and the
        // identified model must give zero acceleration: c psi + d = 0 with psi = -τ / (Ī alpha_ref).
        let psi = [-0.06 / 0.8, 0.06 / 0.8];
        for ((c, d), psi) in w.c_r.iter().zip(w.d_r_radps2.iter()).zip(psi) {
            assert!((c * psi + d).abs() < 0.02, "{w:?}");
        }
        assert!(w.d_r_radps2[0] > 0.5 && w.d_r_radps2[1] < -0.5, "{w:?}");
        // Mass 5.4 kg and k_F 0.99 seen on the vertical channel: m_D ≈ 5.4 / 0.99 when b_D = 0.
        assert!(w.mass_est_kg[2] > 5.25, "{w:?}");
        assert_eq!(w_frozen.c_r, [10.0; 3]);
        assert_eq!(w_frozen.b_t_mps2, [0.0; 3]);
    }

    #[test]
    fn given_250_500_1000_hz_when_flying_the_step_then_trajectories_agree() {
        let target = Vector3::new(1.0, 0.0, -3.0);
        let run = |inner_hz: u32| {
            let rates = LoopRates { inner_hz, position_hz: 100.min(inner_hz / 5) };
            let mut plant = ToyPlant::new(Vector3::new(0.0, 0.0, -2.0), Vector3::new(0.1, 0.0, 0.0));
            mismatch(&mut plant);
            let mut c = AcoController::new(&AcoConfig::default(), rates);
            let tr = fly(&mut c, &mut plant, inner_hz, 8.0, |_| Reference::position(target, 0.0));
            [2.0, 4.0, 8.0].map(|t| at(&tr, t).input.pos_ned_m)
        };
        let p500 = run(500);
        for hz in [250, 1000] {
            let p = run(hz);
            for (a, b) in p.iter().zip(p500.iter()) {
                assert!((a - b).norm() < 0.02, "{hz} Hz: {a} vs {b} at 500 Hz");
            }
        }
    }

    #[test]
    fn given_position_divider_when_ticking_then_position_loop_runs_every_fifth_tick() {
        let mut c = aco();
        let p = Vector3::new(0.0, 0.0, -2.0);
        let input = hover_input(p, 0.0);
        c.update(&input, &Reference::position(p, 0.0));
        let u0 = c.vertical_thrust_n;
        // A new reference between position ticks does not change U until the next 5th tick.
        let r = Reference::position(Vector3::new(0.0, 0.0, -2.5), 0.0);
        for _ in 1..5 {
            c.update(&input, &r);
            assert_eq!(c.vertical_thrust_n, u0);
        }
        c.update(&input, &r);
        assert!(c.vertical_thrust_n > u0);
    }

    #[test]
    fn given_config_when_serialised_shape_then_defaults_are_the_spec_values() {
        let c = AcoConfig::default();
        assert_eq!(c.k_att_per_s, [2.778, 2.778, 1.389]);
        assert_eq!(c.k_rate_per_s, [9.0, 9.0, 4.5]);
        assert_eq!(
            (c.gamma_w_t_per_s, c.gamma_b_t_per_s, c.gamma_c_r_per_s, c.gamma_d_r_per_s),
            (10.0, 5.0, 20.0, 5.0)
        );
        assert!(!c.pos_integral_enabled && c.adaptation_enabled);
        let ctrl = aco();
        let (mu_w, mu_b) = ctrl.lms_t[0].step_sizes();
        assert!((mu_w - 0.01).abs() < 1e-15 && (mu_b - 0.005).abs() < 1e-15);
        let (mu_c, mu_d) = ctrl.lms_r[0].step_sizes();
        assert!((mu_c - 0.02).abs() < 1e-15 && (mu_d - 0.005).abs() < 1e-15);
    }

    #[test]
    fn given_zoned_integral_enabled_when_accelerometer_biased_then_offset_removed() {
        let p = Vector3::new(0.0, 0.0, -1.5);
        let run = |integral: bool| {
            let mut plant = ToyPlant::new(p, Vector3::zeros());
            let cfg = AcoConfig { pos_integral_enabled: integral, ..AcoConfig::default() };
            let mut c = AcoController::new(&cfg, LoopRates::default());
            let dt = 0.002;
            let mut err = 0.0;
            for k in 0..(40.0 / dt) as usize {
                let mut input = plant.sense();
                input.specific_force_frd_mps2.x += 0.1;
                let pwm = c.update(&input, &Reference::position(p, 0.0));
                plant.step(&pwm, dt, 2);
                if k as f64 * dt > 39.0 {
                    err = (input.pos_ned_m - p).norm();
                }
            }
            err
        };
        let plain = run(false);
        let zoned = run(true);
        assert!(plain > 0.05, "bias offset without integral {plain}");
        assert!(zoned < 0.25 * plain, "zoned integral {zoned} vs {plain}");
    }
}
