//! `example_pd`: the Rust twin of the Python quick start's PD law (`aco_sim.pd.PdHover`), registered by
//! `aco_sim` so that the same law written in Python and in Rust can be flown through the same runner and
//! compared (python/tests/test_controller.py). The two are written operation for operation alike, so
//! their runs agree bit for bit.
//!
//! The law, on the nominal model ([`Airframe::default`]): a PD on position gives the acceleration
//! `a = kp (p_ref - p) + kd (v_ref - v) + a_ref` (NED); the collective is `m (g - a_D)`; the small-angle
//! tilt `roll = a_E / g`, `pitch = -a_N / g`, each clipped to `tilt_max_rad` (yaw held near 0); a PD on
//! attitude gives the angular acceleration, times the inertia the moments, and the inverse of Eq 27 the
//! rotor lifts, clipped to the rotors' range and turned into PWM by Eq 10.

use autopilot::core::control::distributor::{ROTOR_LIFT_MAX_N, ROTOR_LIFT_MIN_N, pwm_from_lift_us};
use autopilot::core::control::{
    Airframe, ConfigError, ControlInput, Controller, ControllerConfig, ControllerKind, ControllerType, Reference,
};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The PD's gains, its `[controller.example_pd]` table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct PdGains {
    /// Position gain (m/s² per m).
    pub kp_pos_per_s2: f64,
    /// Velocity gain (m/s² per m/s).
    pub kd_vel_per_s: f64,
    /// Attitude gain (rad/s² per rad).
    pub kp_att_per_s2: f64,
    /// Body-rate damping (rad/s² per rad/s).
    pub kd_rate_per_s: f64,
    /// Largest roll or pitch setpoint (rad).
    pub tilt_max_rad: f64,
}

impl Default for PdGains {
    fn default() -> Self {
        Self { kp_pos_per_s2: 2.0, kd_vel_per_s: 2.6, kp_att_per_s2: 25.0, kd_rate_per_s: 8.0, tilt_max_rad: 0.35 }
    }
}

/// The registered type.
pub(crate) struct ExamplePdType;

pub(crate) static EXAMPLE_PD: ExamplePdType = ExamplePdType;

impl ControllerType for ExamplePdType {
    fn name(&self) -> &'static str {
        "example_pd"
    }
    fn summary(&self) -> &'static str {
        "the Python quick start's PD law in Rust (aco_sim only; docs/python.md)"
    }
    fn default_table(&self) -> toml::Table {
        toml::Table::try_from(PdGains::default()).unwrap_or_default()
    }
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError> {
        let g: PdGains = config.section("example_pd")?;
        for (field, value) in [
            ("kp_pos_per_s2", g.kp_pos_per_s2),
            ("kd_vel_per_s", g.kd_vel_per_s),
            ("kp_att_per_s2", g.kp_att_per_s2),
            ("kd_rate_per_s", g.kd_rate_per_s),
            ("tilt_max_rad", g.tilt_max_rad),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError::NotPositive { name: "example_pd", field, value });
            }
        }
        Ok(())
    }
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
        self.validate(config)?;
        Ok(Box::new(ExamplePd { gains: config.section("example_pd")?, model: Airframe::default() }))
    }
}

struct ExamplePd {
    gains: PdGains,
    model: Airframe,
}

/// Eq 10 on a lift clipped to the rotors' range.
fn pwm_us(lift_n: f64) -> f64 {
    pwm_from_lift_us(lift_n.clamp(ROTOR_LIFT_MIN_N, ROTOR_LIFT_MAX_N))
}

impl Controller for ExamplePd {
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4] {
        let (k, m) = (&self.gains, &self.model);
        let (p, v, r) = (&input.pos_ned_m, &input.vel_ned_mps, reference);
        let a = |i: usize| {
            k.kp_pos_per_s2 * (r.pos_ned_m[i] - p[i]) + k.kd_vel_per_s * (r.vel_ned_mps[i] - v[i]) + r.acc_ned_mps2[i]
        };
        let (a_n, a_e, a_d) = (a(0), a(1), a(2));
        let g = m.gravity_mps2;
        let thrust_n = m.mass_kg * (g - a_d);
        let roll_sp = (a_e / g).clamp(-k.tilt_max_rad, k.tilt_max_rad);
        let pitch_sp = (-a_n / g).clamp(-k.tilt_max_rad, k.tilt_max_rad);
        let (e, w) = (&input.euler_rad, &input.rate_frd_radps);
        let alpha_x = k.kp_att_per_s2 * (roll_sp - e[0]) - k.kd_rate_per_s * w[0];
        let alpha_y = k.kp_att_per_s2 * (pitch_sp - e[1]) - k.kd_rate_per_s * w[1];
        let alpha_z = k.kp_att_per_s2 * (r.yaw_rad - e[2]) - k.kd_rate_per_s * w[2];
        let [ix, iy, iz] = m.inertia_kgm2;
        let (mx, my, mz) = (ix * alpha_x, iy * alpha_y, iz * alpha_z);
        let (c, l, lam) = (thrust_n / 4.0, m.arm_m, m.yaw_moment_m);
        [
            pwm_us(c - mx / (2.0 * l) - mz / (4.0 * lam)),
            pwm_us(c - my / (2.0 * l) + mz / (4.0 * lam)),
            pwm_us(c + my / (2.0 * l) + mz / (4.0 * lam)),
            pwm_us(c + mx / (2.0 * l) - mz / (4.0 * lam)),
        ]
    }

    fn reconfigure(&mut self, config: &ControllerConfig) {
        if let Ok(gains) = config.section("example_pd") {
            self.gains = gains;
        }
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::of(&EXAMPLE_PD)
    }

    fn telemetry(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }

    fn weights_at_bounds(&self) -> bool {
        false
    }

    fn attitude_setpoint_rad(&self) -> Vector3<f64> {
        Vector3::zeros()
    }
}
