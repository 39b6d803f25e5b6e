//! The CA baseline's settings: the paper's reference models, adaptation rates, bounds and saturation
//! freezes, and the options of the competent CA (docs/controller.md §4.3), with their presets.

use serde::{Deserialize, Serialize};

use crate::core::control::Airframe;
use crate::core::control::distributor::ActuatorLimits;

/// MRAC baseline settings (spec (c)). Default = "CA" as the reference prototype flew it (see
/// `freeze_roll_pitch`); `freeze_on_saturation = false` gives "CA-raw",
/// `gamma_theta_pos = 3` gives "CA-fast".
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MracConfig {
    /// Nominal model m̄, Ī, l, λ, g.
    pub airframe: Airframe,
    /// Rotor and thrust limits.
    pub limits: ActuatorLimits,
    /// Reference-model natural frequencies (rad/s), roll, pitch, yaw.
    pub wn_att_radps: [f64; 3],
    /// Reference-model damping, roll, pitch, yaw.
    pub zeta_att: [f64; 3],
    /// Reference-model natural frequency of the position channels (rad/s).
    pub wn_pos_radps: f64,
    /// Reference-model damping of the position channels.
    pub zeta_pos: f64,
    /// Attitude gain adaptation rate Γk.
    pub gamma_k_att: f64,
    /// Attitude offset adaptation rate Γθ.
    pub gamma_theta_att: f64,
    /// Position gain adaptation rate Γk.
    pub gamma_k_pos: f64,
    /// Position offset adaptation rate Γθ ("CA-fast": 3).
    pub gamma_theta_pos: f64,
    /// Each gain stays within `[lo, hi]` times its initial value.
    pub gain_projection: [f64; 2],
    /// `|theta|` bound of the attitude channels (rad/s²).
    pub theta_max_att: f64,
    /// `|theta|` bound of the position channels (m/s²).
    pub theta_max_pos: f64,
    /// Stop adapting a channel while its actuator is saturated (false: "CA-raw").
    pub freeze_on_saturation: bool,
    /// Also freeze roll and pitch while the distributor scales or clips them, as the spec's text says.
    /// Off by default, as the reference prototype flew (see
    /// [`MixerSaturation::freeze_axes`](crate::core::control::distributor::MixerSaturation::freeze_axes)).
    pub freeze_roll_pitch: bool,
    /// Competent CA: the position channels take the reference's velocity, acceleration and jerk. The
    /// reference model is commanded `r = p + (2ζ/ωn) v + a/ωn²`, whose solution is the reference itself,
    /// and the acceleration demand leads by `jerk · 2ζ_att/ωn_att` (the attitude model's ramp lag). Off:
    /// the paper's CA, which reads the reference position only.
    pub feed_forward: bool,
    /// Competent CA: the pole ωi (rad/s) of an integral of the model-following error in the attitude
    /// channels, with error feedback `kI ∫e1 + kP e1 + kD e2 = ωi ωn² ∫e1 + 2ζωn ωi e1 + ωi e2`, so the
    /// error dynamics are `(s + ωi)(s² + 2ζωn s + ωn²)` and any equilibrium has `x = r`; the adaptive
    /// laws then use the Lyapunov weights of that third-order error system. 0: the paper's channel.
    pub wi_att_radps: f64,
    /// Competent CA: the integral pole ωi (rad/s) of the position channels, as `wi_att_radps`.
    pub wi_pos_radps: f64,
    /// Competent CA: e-modification σ (Narendra and Annaswamy): every adaptive parameter leaks toward its
    /// initial value at `Γ σ |s|`, which bounds the parameters under disturbances and vanishes with the
    /// error (σ-modification would leave a steady error). 0: off.
    pub e_mod_sigma: f64,
    /// Competent CA: pseudo-control hedging (Johnson and Calise): each reference model is slowed by the
    /// part of its channel's last demand the actuators could not give (the distributor's scaling and
    /// clipping for roll, pitch and yaw; the thrust limiter for N, E, D), so a saturated channel's model
    /// does not run ahead of the vehicle and its error, integral and adaptation do not wind up. Off: the
    /// paper's reference models.
    pub hedging: bool,
}

impl Default for MracConfig {
    fn default() -> Self {
        Self {
            airframe: Airframe::default(),
            limits: ActuatorLimits::default(),
            wn_att_radps: [5.0, 5.0, 2.5],
            zeta_att: [0.9, 0.9, 0.9],
            wn_pos_radps: 1.2,
            zeta_pos: 0.9,
            gamma_k_att: 1000.0,
            gamma_theta_att: 1000.0,
            gamma_k_pos: 0.3,
            gamma_theta_pos: 1.0,
            gain_projection: [0.2, 5.0],
            theta_max_att: 8.0,
            theta_max_pos: 4.0,
            freeze_on_saturation: true,
            freeze_roll_pitch: false,
            feed_forward: false,
            wi_att_radps: 0.0,
            wi_pos_radps: 0.0,
            e_mod_sigma: 0.0,
            hedging: false,
        }
    }
}

impl MracConfig {
    /// The competent CA of docs/controller.md §4.3: [`MracConfig::default`] with the feed-forward, the
    /// integral poles, the e-modification and the hedging on, and attitude adaptation rates of 100
    /// instead of 1000 (at 1000 the yaw channel limit-cycles against the rotor lag, ±5 mrad at about 1.7 Hz).
    #[must_use]
    pub fn competent() -> Self {
        Self {
            gamma_k_att: 100.0,
            gamma_theta_att: 100.0,
            feed_forward: true,
            wi_att_radps: 2.0,
            wi_pos_radps: 0.0,
            e_mod_sigma: 0.1,
            hedging: true,
            ..Self::default()
        }
    }

    /// True when any competent-CA option is on (the paper's CA otherwise).
    #[must_use]
    pub fn is_competent(&self) -> bool {
        self.feed_forward
            || self.wi_att_radps != 0.0
            || self.wi_pos_radps != 0.0
            || self.e_mod_sigma != 0.0
            || self.hedging
    }
}
