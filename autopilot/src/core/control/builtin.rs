//! The built-in controllers' types for the registry: the paper's ACO (`aco`), its "common adaptive"
//! baseline (`ca`, table `mrac`) and the PID cascade (`pid`). In: their typed sections of a
//! [`ControllerConfig`]. Out: the checks of those sections and the controllers built from them.

use super::registry::{ControllerType, GainScale, TunableGain};
use super::{AcoController, Airframe, ConfigError, Controller, ControllerConfig, MracController, PidController};

/// The ACO's type.
pub struct Aco;
/// The CA's type.
pub struct Ca;
/// The PID cascade's type.
pub struct Pid;

pub static ACO: Aco = Aco;
pub static CA: Ca = Ca;
pub static PID: Pid = Pid;

/// A typed section as a TOML table (the built-in sections always serialise to one).
fn table_of<T: serde::Serialize>(section: &T) -> toml::Table {
    toml::Table::try_from(section).unwrap_or_default()
}

/// Every field of the nominal model must be finite and positive.
fn check_airframe(name: &'static str, airframe: &Airframe) -> Result<(), ConfigError> {
    let [ix, iy, iz] = airframe.inertia_kgm2;
    for (field, value) in [
        ("mass_kg", airframe.mass_kg),
        ("inertia_kgm2", ix.min(iy).min(iz)),
        ("arm_m", airframe.arm_m),
        ("yaw_moment_m", airframe.yaw_moment_m),
        ("rotor_tau_s", airframe.rotor_tau_s),
        ("gravity_mps2", airframe.gravity_mps2),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(ConfigError::NotPositive { name, field, value });
        }
    }
    Ok(())
}

impl ControllerType for Aco {
    fn name(&self) -> &'static str {
        "aco"
    }
    fn summary(&self) -> &'static str {
        "the paper's adaptive control-optimization cascade with LMS adaptation (built in)"
    }
    fn default_table(&self) -> toml::Table {
        table_of(&super::AcoConfig::default())
    }
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError> {
        let max_hz = 0.45 * f64::from(config.rates.inner_hz);
        for (name, value_hz) in [
            ("aco.lpf_translation_hz", config.aco.lpf_translation_hz),
            ("aco.lpf_rotation_hz", config.aco.lpf_rotation_hz),
        ] {
            if !(value_hz > 0.0 && value_hz < max_hz) {
                return Err(ConfigError::FilterCutoff { name, value_hz, max_hz, inner_hz: config.rates.inner_hz });
            }
        }
        check_airframe("aco.airframe", &config.aco.airframe)?;
        if !(config.aco.alpha_ref_radps2.is_finite() && config.aco.alpha_ref_radps2 > 0.0) {
            return Err(ConfigError::NotPositive {
                name: "aco",
                field: "alpha_ref_radps2",
                value: config.aco.alpha_ref_radps2,
            });
        }
        Ok(())
    }
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
        Ok(Box::new(AcoController::new(&config.aco, config.rates)))
    }
    /// Its rate loop (Eq 9 inverted) takes the body rates in place of the attitude loop's.
    fn flies_rates(&self) -> bool {
        true
    }
    /// The gains `sitl/tunes/aco.toml` searches: the cascade's and the LMS adaptation rates.
    fn gains(&self) -> &'static [TunableGain] {
        &[
            TunableGain { name: "aco.kp_pos_per_s", axes: &[], bounds: [0.2, 3.0], scale: GainScale::Log },
            TunableGain { name: "aco.kv_vel_per_s", axes: &[], bounds: [0.5, 8.0], scale: GainScale::Log },
            TunableGain { name: "aco.k_att_per_s", axes: &[0, 1], bounds: [0.5, 12.0], scale: GainScale::Log },
            TunableGain { name: "aco.k_rate_per_s", axes: &[0, 1], bounds: [2.0, 40.0], scale: GainScale::Log },
            TunableGain { name: "aco.gamma_w_t_per_s", axes: &[], bounds: [0.5, 60.0], scale: GainScale::Log },
            TunableGain { name: "aco.gamma_c_r_per_s", axes: &[], bounds: [1.0, 80.0], scale: GainScale::Log },
        ]
    }
}

impl ControllerType for Ca {
    fn name(&self) -> &'static str {
        "ca"
    }
    fn aliases(&self) -> &'static [&'static str] {
        &["mrac"]
    }
    fn table(&self) -> &'static str {
        "mrac"
    }
    fn summary(&self) -> &'static str {
        "the paper's \"common adaptive\" baseline: per-channel MRAC (built in)"
    }
    fn default_table(&self) -> toml::Table {
        table_of(&super::MracConfig::default())
    }
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError> {
        check_airframe("mrac.airframe", &config.mrac.airframe)?;
        for (field, value) in [
            ("wi_att_radps", config.mrac.wi_att_radps),
            ("wi_pos_radps", config.mrac.wi_pos_radps),
            ("e_mod_sigma", config.mrac.e_mod_sigma),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConfigError::Negative { name: "mrac", field, value });
            }
        }
        Ok(())
    }
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
        Ok(Box::new(MracController::new(&config.mrac, config.rates)))
    }
    /// The CA's stated structure (natural frequencies, damping, adaptation rates); the competent CA's
    /// options (`wi_*`, `e_mod_sigma`) are left to a spec that names them.
    fn gains(&self) -> &'static [TunableGain] {
        &[
            TunableGain { name: "mrac.wn_att_radps", axes: &[0, 1], bounds: [2.0, 15.0], scale: GainScale::Log },
            TunableGain { name: "mrac.zeta_att", axes: &[0, 1], bounds: [0.5, 1.5], scale: GainScale::Linear },
            TunableGain { name: "mrac.wn_att_radps", axes: &[2], bounds: [1.0, 8.0], scale: GainScale::Log },
            TunableGain { name: "mrac.zeta_att", axes: &[2], bounds: [0.5, 1.5], scale: GainScale::Linear },
            TunableGain { name: "mrac.wn_pos_radps", axes: &[], bounds: [0.4, 4.0], scale: GainScale::Log },
            TunableGain { name: "mrac.zeta_pos", axes: &[], bounds: [0.5, 1.5], scale: GainScale::Linear },
            TunableGain { name: "mrac.gamma_k_att", axes: &[], bounds: [50.0, 10000.0], scale: GainScale::Log },
            TunableGain { name: "mrac.gamma_theta_att", axes: &[], bounds: [10.0, 3000.0], scale: GainScale::Log },
            TunableGain { name: "mrac.gamma_theta_pos", axes: &[], bounds: [0.1, 20.0], scale: GainScale::Log },
        ]
    }
}

impl ControllerType for Pid {
    fn name(&self) -> &'static str {
        "pid"
    }
    fn summary(&self) -> &'static str {
        "a PX4-style position, velocity, attitude and rate PID cascade (built in)"
    }
    fn default_table(&self) -> toml::Table {
        table_of(&super::PidConfig::default())
    }
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError> {
        check_airframe("pid.airframe", &config.pid.airframe)?;
        let pid = &config.pid;
        for (field, value) in [
            ("krd_rate_s[0]", pid.krd_rate_s[0]),
            ("krd_rate_s[1]", pid.krd_rate_s[1]),
            ("krd_rate_s[2]", pid.krd_rate_s[2]),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConfigError::Negative { name: "pid", field, value });
            }
        }
        let max_hz = 0.45 * f64::from(config.rates.inner_hz);
        let value_hz = pid.rate_d_cutoff_hz;
        if !(value_hz.is_finite() && value_hz > 0.0 && value_hz < max_hz) {
            return Err(ConfigError::FilterCutoff {
                name: "pid.rate_d_cutoff_hz",
                value_hz,
                max_hz,
                inner_hz: config.rates.inner_hz,
            });
        }
        Ok(())
    }
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
        Ok(Box::new(PidController::new(&config.pid, config.rates)))
    }
    /// Its rate PI takes the body rates in place of the attitude P's.
    fn flies_rates(&self) -> bool {
        true
    }
    /// The gains `sitl/tunes/pid.toml` searches: the cascade's, tilt and yaw apart.
    fn gains(&self) -> &'static [TunableGain] {
        &[
            TunableGain { name: "pid.kp_pos_per_s", axes: &[], bounds: [0.2, 3.0], scale: GainScale::Log },
            TunableGain { name: "pid.kv_vel_per_s", axes: &[], bounds: [0.5, 8.0], scale: GainScale::Log },
            TunableGain { name: "pid.kvi_vel_per_s2", axes: &[0, 1], bounds: [0.05, 4.0], scale: GainScale::Log },
            TunableGain { name: "pid.k_att_per_s", axes: &[0, 1], bounds: [0.5, 12.0], scale: GainScale::Log },
            TunableGain { name: "pid.k_rate_per_s", axes: &[0, 1], bounds: [2.0, 40.0], scale: GainScale::Log },
            TunableGain { name: "pid.kri_rate_per_s2", axes: &[0, 1], bounds: [0.5, 60.0], scale: GainScale::Log },
            TunableGain { name: "pid.k_att_per_s", axes: &[2], bounds: [0.3, 8.0], scale: GainScale::Log },
            TunableGain { name: "pid.k_rate_per_s", axes: &[2], bounds: [1.0, 30.0], scale: GainScale::Log },
            TunableGain { name: "pid.kri_rate_per_s2", axes: &[2], bounds: [0.1, 30.0], scale: GainScale::Log },
        ]
    }
}
