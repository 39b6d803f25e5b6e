//! Wind (spec (b) "Wind"): in, the plant time (µs, once per plant step), the vehicle's height above ground
//! (m) and velocity (m/s NED); out, the wind velocity (m/s NED, the direction the air moves toward), held by
//! the plant over that step. Three additive parts:
//!
//! - a steady wind vector;
//! - the spec's gust `w = A·s(t)·dir`: s(t) rises as 1-cos over `rise_s` from `onset_s`, holds at 1, and
//!   falls as 1-cos over `fall_s` from `release_s` (defaults: 6.7 m/s toward +E, 5 s, 1 s, 17 s, 1 s);
//! - turbulence, per axis a first-order Gauss-Markov process, discretised exactly at the plant step period
//!   (x_{k+1} = a x_k + σ sqrt(1-a²) n_k, a = exp(-Δ/τ)) and held over each step. Either with fixed σ, τ
//!   (the spec's σ = (1.3, 1.3, 0.67) m/s, τ = (1.76, 1.76, 0.22) s) or with σ, τ from the MIL-F-8785C
//!   low-altitude Dryden model (first-order equivalent, see [`dryden_low_altitude`]), optionally scaled by
//!   the gust profile s(t).
//!
//! - a train of 1-cos crosswind pulses of random amplitude, width and spacing (`[wind.pulses]`, see
//!   [`super::pulses`]), drawn once from its own stream.
//!
//! [`BEAUFORT`] gives the Beaufort scale 0..8; `beaufort = n` in the config sets the gust amplitude (or,
//! without a gust, the steady wind speed) to the middle of that force's range.
//!
//! Randomness comes from the plant's wind stream only, so the wind is bit-identical for a seed whatever the
//! sensor noise settings.

use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::Deserialize;

use super::PlantError;
use super::airframe::{finite, non_negative, positive};
use super::pulses::{Pulse, PulseTrain, PulseTrainConfig};

/// One row of the Beaufort scale: mean wind speed range at 10 m (m/s, WMO).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeaufortForce {
    pub force: u8,
    pub name: &'static str,
    pub min_mps: f64,
    pub max_mps: f64,
}

impl BeaufortForce {
    /// Middle of the range, (min + max)/2 (m/s); force 4 gives 6.7 m/s.
    #[must_use]
    pub fn mid_mps(&self) -> f64 {
        0.5 * (self.min_mps + self.max_mps)
    }
}

/// The Beaufort scale, forces 0..8 (WMO ranges in m/s).
pub const BEAUFORT: [BeaufortForce; 9] = [
    BeaufortForce { force: 0, name: "calm", min_mps: 0.0, max_mps: 0.2 },
    BeaufortForce { force: 1, name: "light air", min_mps: 0.3, max_mps: 1.5 },
    BeaufortForce { force: 2, name: "light breeze", min_mps: 1.6, max_mps: 3.3 },
    BeaufortForce { force: 3, name: "gentle breeze", min_mps: 3.4, max_mps: 5.4 },
    BeaufortForce { force: 4, name: "moderate breeze", min_mps: 5.5, max_mps: 7.9 },
    BeaufortForce { force: 5, name: "fresh breeze", min_mps: 8.0, max_mps: 10.7 },
    BeaufortForce { force: 6, name: "strong breeze", min_mps: 10.8, max_mps: 13.8 },
    BeaufortForce { force: 7, name: "near gale", min_mps: 13.9, max_mps: 17.1 },
    BeaufortForce { force: 8, name: "gale", min_mps: 17.2, max_mps: 20.7 },
];

/// The Beaufort row for `force`.
///
/// # Errors
/// [`PlantError::InvalidValue`] for a force above 8.
pub fn beaufort(force: u8) -> Result<BeaufortForce, PlantError> {
    BEAUFORT.get(usize::from(force)).copied().ok_or_else(|| PlantError::InvalidValue {
        name: "wind.beaufort",
        value: force.to_string(),
        reason: "Beaufort presets cover forces 0..8",
    })
}

/// The spec's gust amplitude (m/s): the middle of Beaufort 4.
pub const SPEC_GUST_AMPLITUDE_MPS: f64 = 6.7;

/// The gust of spec (b). A `[wind.gust]` table with no keys is the spec's gust.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GustConfig {
    /// Peak speed A (m/s); `None` = 6.7 m/s, or the Beaufort mid-range when `wind.beaufort` is set.
    pub amplitude_mps: Option<f64>,
    /// Direction the gust blows toward, NED (normalised; default +E).
    pub direction_ned: [f64; 3],
    /// Start of the rise (s of plant time).
    pub onset_s: f64,
    /// Duration of the 1-cos rise (s).
    pub rise_s: f64,
    /// Start of the fall (s of plant time).
    pub release_s: f64,
    /// Duration of the 1-cos fall (s).
    pub fall_s: f64,
}

impl Default for GustConfig {
    fn default() -> Self {
        Self {
            amplitude_mps: None,
            direction_ned: [0.0, 1.0, 0.0],
            onset_s: 5.0,
            rise_s: 1.0,
            release_s: 17.0,
            fall_s: 1.0,
        }
    }
}

/// Turbulence model, chosen by `model = "gauss_markov"` or `model = "dryden"` in `[wind.turbulence]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum TurbulenceConfig {
    GaussMarkov(GaussMarkovConfig),
    Dryden(DrydenConfig),
}

/// Per-axis first-order Gauss-Markov turbulence with fixed σ and τ (defaults: the spec's values).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GaussMarkovConfig {
    /// Standard deviation per NED axis (m/s).
    pub sigma_mps: [f64; 3],
    /// Correlation time per NED axis (s).
    pub tau_s: [f64; 3],
    /// Multiply by the gust profile s(t) (the spec's usage; needs a gust). Off: constant intensity.
    pub scale_with_gust: bool,
}

impl Default for GaussMarkovConfig {
    fn default() -> Self {
        Self { sigma_mps: [1.3, 1.3, 0.67], tau_s: [1.76, 1.76, 0.22], scale_with_gust: false }
    }
}

/// MIL-F-8785C low-altitude Dryden turbulence, first-order equivalent (see [`dryden_low_altitude`]).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DrydenConfig {
    /// Fixed altitude h (m) for the scales; `None` = the vehicle's height above the ground plane.
    pub altitude_m: Option<f64>,
    /// Wind speed at 6 m (20 ft), W20 (m/s); `None` = the current horizontal mean wind (steady + gust),
    /// so the intensity follows the gust.
    pub w20_mps: Option<f64>,
    /// Floor on the airspeed V (m/s) in τ = L/V, so hover does not freeze the process.
    pub min_airspeed_mps: f64,
    /// Floor on h (m): the low-altitude formulas give L → 0 at the ground.
    pub min_altitude_m: f64,
    /// Multiply by the gust profile s(t) (needs a gust).
    pub scale_with_gust: bool,
}

impl Default for DrydenConfig {
    fn default() -> Self {
        Self { altitude_m: None, w20_mps: None, min_airspeed_mps: 1.0, min_altitude_m: 1.0, scale_with_gust: false }
    }
}

/// The `[wind]` table. Default: no wind at all.
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WindConfig {
    /// Constant wind (m/s NED, toward).
    pub steady_ned_mps: [f64; 3],
    /// Beaufort force 0..8: sets the gust amplitude to the force's mid-range if a gust is configured,
    /// otherwise the steady wind speed (along `steady_ned_mps` if non-zero, else toward +E).
    pub beaufort: Option<u8>,
    /// The gust; `None` = no gust.
    pub gust: Option<GustConfig>,
    /// Turbulence; `None` = none.
    pub turbulence: Option<TurbulenceConfig>,
    /// A train of crosswind pulses; `None` = none.
    pub pulses: Option<PulseTrainConfig>,
}

/// A resolved, validated gust.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gust {
    /// A (m/s).
    pub amplitude_mps: f64,
    /// Unit direction the gust blows toward (NED).
    pub direction_ned: Vector3<f64>,
    pub onset_s: f64,
    pub rise_s: f64,
    pub release_s: f64,
    pub fall_s: f64,
}

impl Gust {
    /// From its configuration; an unset amplitude is `default_amplitude_mps`.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for a negative or non-finite amplitude, a zero or non-finite direction,
    /// non-positive rise/fall times, or a release before the rise has finished.
    pub fn from_config(config: &GustConfig, default_amplitude_mps: f64) -> Result<Self, PlantError> {
        let amplitude_mps = config.amplitude_mps.unwrap_or(default_amplitude_mps);
        non_negative("wind.gust.amplitude_mps", amplitude_mps)?;
        let direction = Vector3::from(config.direction_ned);
        let norm = direction.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(PlantError::InvalidValue {
                name: "wind.gust.direction_ned",
                value: format!("{:?}", config.direction_ned),
                reason: "must be a finite non-zero vector",
            });
        }
        finite("wind.gust.onset_s", config.onset_s)?;
        positive("wind.gust.rise_s", config.rise_s)?;
        finite("wind.gust.release_s", config.release_s)?;
        positive("wind.gust.fall_s", config.fall_s)?;
        if config.release_s < config.onset_s + config.rise_s {
            return Err(PlantError::InvalidValue {
                name: "wind.gust.release_s",
                value: config.release_s.to_string(),
                reason: "must be >= onset_s + rise_s (the fall starts after the rise ends)",
            });
        }
        Ok(Self {
            amplitude_mps,
            direction_ned: direction / norm,
            onset_s: config.onset_s,
            rise_s: config.rise_s,
            release_s: config.release_s,
            fall_s: config.fall_s,
        })
    }

    /// The profile s(t) in [0, 1] at plant time `t_s`.
    #[must_use]
    pub fn scale(&self, t_s: f64) -> f64 {
        gust_profile(t_s, self.onset_s, self.rise_s, self.release_s, self.fall_s)
    }

    /// A·s(t)·dir (m/s NED).
    #[must_use]
    pub fn velocity_ned_mps(&self, t_s: f64) -> Vector3<f64> {
        self.direction_ned * (self.amplitude_mps * self.scale(t_s))
    }
}

/// The spec's gust profile: 0 before `onset_s`; ½(1 - cos(π(t - onset)/rise)) while rising; 1 until
/// `release_s`; ½(1 + cos(π(t - release)/fall)) while falling; 0 after.
#[must_use]
pub fn gust_profile(t_s: f64, onset_s: f64, rise_s: f64, release_s: f64, fall_s: f64) -> f64 {
    if t_s < onset_s {
        0.0
    } else if t_s < onset_s + rise_s {
        0.5 * (1.0 - (std::f64::consts::PI * (t_s - onset_s) / rise_s).cos())
    } else if t_s < release_s {
        1.0
    } else if t_s < release_s + fall_s {
        0.5 * (1.0 + (std::f64::consts::PI * (t_s - release_s) / fall_s).cos())
    } else {
        0.0
    }
}

/// Intensities and correlation times of a per-axis first-order turbulence process (NED order).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurbulenceParams {
    /// σ per axis (m/s).
    pub sigma_mps: Vector3<f64>,
    /// τ per axis (s).
    pub tau_s: Vector3<f64>,
}

const FT_PER_M: f64 = 1.0 / 0.3048;
/// Upper limit of the MIL-F-8785C low-altitude model: 1000 ft.
const LOW_ALTITUDE_MAX_M: f64 = 1000.0 * 0.3048;

/// MIL-F-8785C low-altitude (h < 1000 ft) Dryden scales and intensities, as first-order equivalents:
///
/// - with h in feet: L_u = L_v = h/(0.177 + 0.000823 h)^1.2 ft, L_w = h ft;
///   σ_w = 0.1 W20, σ_u = σ_v = σ_w/(0.177 + 0.000823 h)^0.4.
///   The length formulas are homogeneous in h except for the 0.000823 h term, so only that term needs h
///   in feet: here `height_m` is converted to feet there and the lengths come out in metres. σ has the
///   unit of W20 (m/s here).
/// - τ = L/V per axis (frozen turbulence convected at airspeed V, m/s). The longitudinal Dryden filter is
///   exactly first order with this τ; the lateral and vertical second-order filters are replaced by
///   first-order ones with the same σ and τ = L/V. This is the form of the spec's fixed values: at
///   h = 1.5 m and W20 = V = 6.7 m/s it gives σ = (1.33, 1.33, 0.67) m/s and τ = (1.74, 1.74, 0.22) s.
/// - Since L_u = L_v and σ_u = σ_v, the horizontal pair is isotropic and is generated along N and E
///   directly; w is along D.
///
/// `height_m` must be > 0 and `airspeed_mps` > 0 (the caller applies the floors).
#[must_use]
pub fn dryden_low_altitude(height_m: f64, w20_mps: f64, airspeed_mps: f64) -> TurbulenceParams {
    let h_ft = height_m * FT_PER_M;
    let denom = 0.177 + 0.000823 * h_ft;
    let l_horizontal_m = height_m / denom.powf(1.2);
    let l_vertical_m = height_m;
    let sigma_w = 0.1 * w20_mps;
    let sigma_horizontal = sigma_w / denom.powf(0.4);
    TurbulenceParams {
        sigma_mps: Vector3::new(sigma_horizontal, sigma_horizontal, sigma_w),
        tau_s: Vector3::new(l_horizontal_m / airspeed_mps, l_horizontal_m / airspeed_mps, l_vertical_m / airspeed_mps),
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Turbulence {
    GaussMarkov { params: TurbulenceParams, scale_with_gust: bool },
    Dryden(DrydenConfig),
}

impl Turbulence {
    fn from_config(config: &TurbulenceConfig, has_gust: bool) -> Result<Self, PlantError> {
        let scale_with_gust = match config {
            TurbulenceConfig::GaussMarkov(c) => c.scale_with_gust,
            TurbulenceConfig::Dryden(c) => c.scale_with_gust,
        };
        if scale_with_gust && !has_gust {
            return Err(PlantError::InvalidValue {
                name: "wind.turbulence.scale_with_gust",
                value: "true".to_owned(),
                reason: "scaling turbulence by the gust profile needs a [wind.gust]",
            });
        }
        match config {
            TurbulenceConfig::GaussMarkov(c) => {
                const SIGMA: [&str; 3] =
                    ["wind.turbulence.sigma_mps[0]", "wind.turbulence.sigma_mps[1]", "wind.turbulence.sigma_mps[2]"];
                const TAU: [&str; 3] =
                    ["wind.turbulence.tau_s[0]", "wind.turbulence.tau_s[1]", "wind.turbulence.tau_s[2]"];
                for i in 0..3 {
                    non_negative(SIGMA[i], c.sigma_mps[i])?;
                    positive(TAU[i], c.tau_s[i])?;
                }
                Ok(Self::GaussMarkov {
                    params: TurbulenceParams { sigma_mps: Vector3::from(c.sigma_mps), tau_s: Vector3::from(c.tau_s) },
                    scale_with_gust: c.scale_with_gust,
                })
            }
            TurbulenceConfig::Dryden(c) => {
                if let Some(h) = c.altitude_m {
                    positive("wind.turbulence.altitude_m", h)?;
                }
                if let Some(w20) = c.w20_mps {
                    non_negative("wind.turbulence.w20_mps", w20)?;
                }
                positive("wind.turbulence.min_airspeed_mps", c.min_airspeed_mps)?;
                positive("wind.turbulence.min_altitude_m", c.min_altitude_m)?;
                Ok(Self::Dryden(c.clone()))
            }
        }
    }

    fn scale_with_gust(&self) -> bool {
        match self {
            Self::GaussMarkov { scale_with_gust, .. } => *scale_with_gust,
            Self::Dryden(c) => c.scale_with_gust,
        }
    }
}

/// Exact-discretisation coefficients (a, sqrt(1-a²)) for one (Δ µs, τ) pair.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CoeffCache {
    elapsed_us: u64,
    tau_s: Vector3<f64>,
    a: Vector3<f64>,
    b: Vector3<f64>,
}

/// The wind field seen by the vehicle: steady + gust + turbulence, updated once per plant step.
#[derive(Debug, Clone)]
pub struct Wind {
    steady_ned_mps: Vector3<f64>,
    gust: Option<Gust>,
    pulses: Option<PulseTrain>,
    turbulence: Option<Turbulence>,
    /// Unit-variance Gauss-Markov states; the turbulence is σ ⊙ this (⊙ s(t)), so σ may change at run
    /// time (Dryden follows h, W20 and V) without a transient in the variance.
    unit_state: Vector3<f64>,
    rng: ChaCha8Rng,
    last_update_us: Option<u64>,
    /// Cached (Δ µs, τ) -> (a, sqrt(1-a²)) of the last update: with fixed τ and step, no exp per step.
    coeff_cache: Option<CoeffCache>,
    turbulence_ned_mps: Vector3<f64>,
    current_ned_mps: Vector3<f64>,
}

impl Wind {
    /// A wind field from its configuration, drawing from `rng` (the plant's wind stream) only; a pulse
    /// train draws its pulses from `rng`'s seed on stream [`super::stream::WIND_PULSES`] (so `rng` must be
    /// fresh: the plant's `stream_rng(seed, stream::WIND)`, nothing drawn yet).
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for any invalid value (see [`Gust::from_config`]; non-finite steady
    /// wind; Beaufort above 8 or together with an explicit gust amplitude; negative σ, non-positive τ or
    /// floors; `scale_with_gust` without a gust).
    pub fn new(config: &WindConfig, rng: ChaCha8Rng) -> Result<Self, PlantError> {
        let mut steady_ned_mps = Vector3::from(config.steady_ned_mps);
        for (i, name) in
            ["wind.steady_ned_mps[0]", "wind.steady_ned_mps[1]", "wind.steady_ned_mps[2]"].into_iter().enumerate()
        {
            finite(name, steady_ned_mps[i])?;
        }
        let beaufort_mid_mps = config.beaufort.map(beaufort).transpose()?.map(|b| b.mid_mps());
        let gust = match &config.gust {
            Some(g) => {
                if let (Some(_), Some(_)) = (g.amplitude_mps, beaufort_mid_mps) {
                    return Err(PlantError::InvalidValue {
                        name: "wind.beaufort",
                        value: format!("{:?}", config.beaufort),
                        reason: "set either wind.beaufort or wind.gust.amplitude_mps, not both",
                    });
                }
                Some(Gust::from_config(g, beaufort_mid_mps.unwrap_or(SPEC_GUST_AMPLITUDE_MPS))?)
            }
            None => {
                if let Some(speed) = beaufort_mid_mps {
                    let norm = steady_ned_mps.norm();
                    let direction = if norm > 0.0 { steady_ned_mps / norm } else { Vector3::y() };
                    steady_ned_mps = direction * speed;
                }
                None
            }
        };
        let turbulence = config.turbulence.as_ref().map(|t| Turbulence::from_config(t, gust.is_some())).transpose()?;
        let pulses = match &config.pulses {
            Some(p) => {
                let mut pulse_rng = rng.clone();
                pulse_rng.set_stream(super::stream::WIND_PULSES);
                Some(PulseTrain::new(p, pulse_rng)?)
            }
            None => None,
        };
        let mut wind = Self {
            steady_ned_mps,
            gust,
            pulses,
            turbulence: None,
            unit_state: Vector3::zeros(),
            rng,
            last_update_us: None,
            coeff_cache: None,
            turbulence_ned_mps: Vector3::zeros(),
            current_ned_mps: Vector3::zeros(),
        };
        wind.install_turbulence(turbulence);
        wind.current_ned_mps = wind.mean_ned_mps(0.0);
        Ok(wind)
    }

    fn install_turbulence(&mut self, turbulence: Option<Turbulence>) {
        if turbulence.is_some() && self.turbulence.is_none() {
            // Start in the stationary distribution, so statistics hold from t = 0.
            self.unit_state = self.standard_normal3();
        }
        self.turbulence = turbulence;
        self.coeff_cache = None;
    }

    fn standard_normal3(&mut self) -> Vector3<f64> {
        let n: [f64; 3] = std::array::from_fn(|_| self.rng.sample(StandardNormal));
        Vector3::from(n)
    }

    /// Steady + gust + pulses (m/s NED) at plant time `t_s`, without turbulence.
    #[must_use]
    pub fn mean_ned_mps(&self, t_s: f64) -> Vector3<f64> {
        let mean = self.steady_ned_mps + self.gust.map_or_else(Vector3::zeros, |g| g.velocity_ned_mps(t_s));
        // Added only with a train, so a wind without one keeps its bits (even the sign of a zero).
        match &self.pulses {
            Some(train) => mean + train.velocity_ned_mps(t_s),
            None => mean,
        }
    }

    /// The pulses of the `[wind.pulses]` train, in time order (empty without one).
    #[must_use]
    pub fn pulses(&self) -> &[Pulse] {
        self.pulses.as_ref().map_or(&[], PulseTrain::pulses)
    }

    /// The gust profile s(t) at `t_s` (0 without a gust).
    #[must_use]
    pub fn gust_scale(&self, t_s: f64) -> f64 {
        self.gust.map_or(0.0, |g| g.scale(t_s))
    }

    /// The wind of the current step (m/s NED), as returned by the last [`Wind::update`].
    #[must_use]
    pub fn current_ned_mps(&self) -> Vector3<f64> {
        self.current_ned_mps
    }

    /// The turbulence part of the current wind (m/s NED).
    #[must_use]
    pub fn turbulence_ned_mps(&self) -> Vector3<f64> {
        self.turbulence_ned_mps
    }

    /// The configured gust, if any.
    #[must_use]
    pub fn gust(&self) -> Option<&Gust> {
        self.gust.as_ref()
    }

    /// The steady wind (m/s NED, toward).
    #[must_use]
    pub fn steady_ned_mps(&self) -> Vector3<f64> {
        self.steady_ned_mps
    }

    /// Whether a turbulence model is on.
    #[must_use]
    pub fn has_turbulence(&self) -> bool {
        self.turbulence.is_some()
    }

    /// Replace the steady wind (m/s NED), e.g. from a fault-injection command.
    pub fn set_steady_ned_mps(&mut self, steady_ned_mps: Vector3<f64>) {
        self.steady_ned_mps = steady_ned_mps;
    }

    /// Replace the gust (`None` removes it); an unset amplitude is the spec's 6.7 m/s. Use onset/release
    /// times ahead of the plant time for a gust on demand.
    ///
    /// # Errors
    /// As [`Gust::from_config`]; also refuses removing the gust while the turbulence is scaled by it.
    pub fn set_gust(&mut self, gust: Option<&GustConfig>) -> Result<(), PlantError> {
        let gust = gust.map(|g| Gust::from_config(g, SPEC_GUST_AMPLITUDE_MPS)).transpose()?;
        if gust.is_none() && self.turbulence.as_ref().is_some_and(Turbulence::scale_with_gust) {
            return Err(PlantError::InvalidValue {
                name: "wind.gust",
                value: "none".to_owned(),
                reason: "the turbulence is scaled by the gust profile",
            });
        }
        self.gust = gust;
        Ok(())
    }

    /// Replace the turbulence model (`None` switches it off). Its state carries over if it was on.
    ///
    /// # Errors
    /// As [`Wind::new`] for the turbulence part.
    pub fn set_turbulence(&mut self, turbulence: Option<&TurbulenceConfig>) -> Result<(), PlantError> {
        let turbulence = turbulence.map(|t| Turbulence::from_config(t, self.gust.is_some())).transpose()?;
        self.install_turbulence(turbulence);
        Ok(())
    }

    /// The current turbulence parameters (σ, τ), given the mean wind, the height above ground (m) and
    /// the vehicle velocity (m/s NED); `None` without turbulence.
    #[must_use]
    pub fn turbulence_params(
        &self,
        mean_ned_mps: &Vector3<f64>,
        height_m: f64,
        vel_ned_mps: &Vector3<f64>,
    ) -> Option<TurbulenceParams> {
        match self.turbulence.as_ref()? {
            Turbulence::GaussMarkov { params, .. } => Some(*params),
            Turbulence::Dryden(c) => {
                let h = c.altitude_m.unwrap_or(height_m);
                let h = if h.is_finite() { h } else { c.min_altitude_m };
                let h = h.clamp(c.min_altitude_m, LOW_ALTITUDE_MAX_M.max(c.min_altitude_m));
                let w20 = c.w20_mps.unwrap_or_else(|| mean_ned_mps.xy().norm());
                let airspeed = (vel_ned_mps - mean_ned_mps).norm();
                let airspeed = if airspeed.is_finite() { airspeed.max(c.min_airspeed_mps) } else { c.min_airspeed_mps };
                Some(dryden_low_altitude(h, w20, airspeed))
            }
        }
    }

    /// Advance to plant time `time_us` and return the wind (m/s NED) to hold over the coming step.
    /// The turbulence advances by the exact discretisation over the time since the last update (nothing
    /// on the first call or when the time has not moved). `height_m` (above the ground plane) and
    /// `vel_ned_mps` only matter to Dryden turbulence.
    pub fn update(&mut self, time_us: u64, height_m: f64, vel_ned_mps: &Vector3<f64>) -> Vector3<f64> {
        let t_s = time_us as f64 * 1e-6;
        let mean = self.mean_ned_mps(t_s);
        let params = self.turbulence_params(&mean, height_m, vel_ned_mps);
        let elapsed_us = self.last_update_us.map_or(0, |last| time_us.saturating_sub(last));
        self.last_update_us = Some(time_us);
        self.turbulence_ned_mps = match params {
            Some(p) => {
                if elapsed_us > 0 {
                    let (a, b) = self.coefficients(elapsed_us, &p.tau_s);
                    let n = self.standard_normal3();
                    self.unit_state = a.component_mul(&self.unit_state) + b.component_mul(&n);
                }
                let scale = match &self.turbulence {
                    Some(t) if t.scale_with_gust() => self.gust_scale(t_s),
                    _ => 1.0,
                };
                p.sigma_mps.component_mul(&self.unit_state) * scale
            }
            None => Vector3::zeros(),
        };
        self.current_ned_mps = mean + self.turbulence_ned_mps;
        self.current_ned_mps
    }

    /// a = exp(-Δ/τ), b = sqrt(1 - a²) = sqrt(-expm1(-2Δ/τ)) per axis.
    fn coefficients(&mut self, elapsed_us: u64, tau_s: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        if let Some(c) = &self.coeff_cache
            && c.elapsed_us == elapsed_us
            && c.tau_s == *tau_s
        {
            return (c.a, c.b);
        }
        let dt_s = elapsed_us as f64 * 1e-6;
        let a = tau_s.map(|tau| (-dt_s / tau).exp());
        let b = tau_s.map(|tau| (-(-2.0 * dt_s / tau).exp_m1()).sqrt());
        self.coeff_cache = Some(CoeffCache { elapsed_us, tau_s: *tau_s, a, b });
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn rng(seed: u64) -> ChaCha8Rng {
        ChaCha8Rng::seed_from_u64(seed)
    }

    fn gauss_markov_spec() -> WindConfig {
        WindConfig {
            turbulence: Some(TurbulenceConfig::GaussMarkov(GaussMarkovConfig::default())),
            ..WindConfig::default()
        }
    }

    /// Runs `wind` for `steps` updates of `dt_us` and returns the turbulence samples per axis.
    fn record(wind: &mut Wind, steps: usize, dt_us: u64) -> [Vec<f64>; 3] {
        let mut out: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(steps));
        for k in 0..steps {
            wind.update(k as u64 * dt_us, 1.5, &Vector3::zeros());
            let t = wind.turbulence_ned_mps();
            for (axis, samples) in out.iter_mut().enumerate() {
                samples.push(t[axis]);
            }
        }
        out
    }

    /// (σ, τ) of an AR(1) record: σ from the mean square, τ from the lag-1 least-squares fit of a.
    fn fit_sigma_tau(x: &[f64], dt_s: f64) -> (f64, f64) {
        let n = x.len() as f64;
        let var = x.iter().map(|v| v * v).sum::<f64>() / n;
        let num: f64 = x.windows(2).map(|w| w[0] * w[1]).sum();
        let den: f64 = x[..x.len() - 1].iter().map(|v| v * v).sum();
        let a = num / den;
        (var.sqrt(), -dt_s / a.ln())
    }

    #[test]
    fn given_the_spec_gust_when_sampling_key_times_then_the_profile_matches() {
        let mut wind =
            Wind::new(&WindConfig { gust: Some(GustConfig::default()), ..WindConfig::default() }, rng(1)).unwrap();
        let at = |wind: &mut Wind, t_s: f64| wind.update((t_s * 1e6).round() as u64, 1.5, &Vector3::zeros());
        assert_eq!(at(&mut wind, 0.0), Vector3::zeros());
        assert_eq!(at(&mut wind, 4.999), Vector3::zeros());
        assert!((at(&mut wind, 5.5) - Vector3::new(0.0, 3.35, 0.0)).norm() < 1e-12);
        assert!((at(&mut wind, 6.0) - Vector3::new(0.0, 6.7, 0.0)).norm() < 1e-12);
        assert_eq!(at(&mut wind, 10.0), Vector3::new(0.0, 6.7, 0.0));
        assert_eq!(at(&mut wind, 16.999), Vector3::new(0.0, 6.7, 0.0));
        assert!((at(&mut wind, 17.5) - Vector3::new(0.0, 3.35, 0.0)).norm() < 1e-12);
        assert!(at(&mut wind, 18.0).norm() < 1e-12);
        assert_eq!(at(&mut wind, 30.0), Vector3::zeros());
        // Monotonic rise.
        let rise: Vec<f64> = (0..=100).map(|k| gust_profile(5.0 + k as f64 * 0.01, 5.0, 1.0, 17.0, 1.0)).collect();
        assert!(rise.windows(2).all(|w| w[1] >= w[0]));
    }

    #[test]
    fn given_spec_gauss_markov_turbulence_when_run_long_then_sigma_and_tau_are_within_10_percent() {
        let mut wind = Wind::new(&gauss_markov_spec(), rng(7)).unwrap();
        let dt_us = 2000;
        let samples = record(&mut wind, 5_000_000, dt_us); // 10 000 s at 2 ms
        let expected = [(1.3, 1.76), (1.3, 1.76), (0.67, 0.22)];
        for (axis, x) in samples.iter().enumerate() {
            let (sigma, tau) = fit_sigma_tau(x, dt_us as f64 * 1e-6);
            let (sigma0, tau0) = expected[axis];
            assert!((sigma / sigma0 - 1.0).abs() < 0.1, "axis {axis}: sigma {sigma}");
            assert!((tau / tau0 - 1.0).abs() < 0.1, "axis {axis}: tau {tau}");
        }
    }

    #[test]
    fn given_dryden_turbulence_when_run_long_then_sigma_and_tau_match_the_mil_formulas() {
        let config = WindConfig {
            steady_ned_mps: [0.0, 6.7, 0.0],
            turbulence: Some(TurbulenceConfig::Dryden(DrydenConfig {
                altitude_m: Some(1.5),
                ..DrydenConfig::default()
            })),
            ..WindConfig::default()
        };
        let mut wind = Wind::new(&config, rng(11)).unwrap();
        let expected = dryden_low_altitude(1.5, 6.7, 6.7);
        let dt_us = 2000;
        let samples = record(&mut wind, 5_000_000, dt_us);
        for (axis, x) in samples.iter().enumerate() {
            let (sigma, tau) = fit_sigma_tau(x, dt_us as f64 * 1e-6);
            assert!((sigma / expected.sigma_mps[axis] - 1.0).abs() < 0.1, "axis {axis}: sigma {sigma}");
            assert!((tau / expected.tau_s[axis] - 1.0).abs() < 0.1, "axis {axis}: tau {tau}");
        }
    }

    #[test]
    fn given_h_1_5_m_and_w20_6_7_when_computing_dryden_then_it_reproduces_the_spec_values() {
        let p = dryden_low_altitude(1.5, 6.7, 6.7);
        let spec_sigma = [1.3, 1.3, 0.67];
        let spec_tau = [1.76, 1.76, 0.22];
        for axis in 0..3 {
            assert!((p.sigma_mps[axis] / spec_sigma[axis] - 1.0).abs() < 0.03, "{p:?}");
            assert!((p.tau_s[axis] / spec_tau[axis] - 1.0).abs() < 0.03, "{p:?}");
        }
        // Hand-computed: h = 4.9213 ft, 0.177 + 0.000823 h = 0.1810503; σ_u = 0.67/0.1810503^0.4.
        let denom: f64 = 0.177 + 0.000823 * (1.5 / 0.3048);
        assert!((p.sigma_mps.x - 0.67 / denom.powf(0.4)).abs() < 1e-12);
        assert!((p.tau_s.x - 1.5 / denom.powf(1.2) / 6.7).abs() < 1e-12);
    }

    #[test]
    fn given_dryden_at_hover_in_still_air_when_updated_then_the_airspeed_floor_keeps_it_finite() {
        let config = WindConfig {
            turbulence: Some(TurbulenceConfig::Dryden(DrydenConfig { w20_mps: Some(6.7), ..DrydenConfig::default() })),
            ..WindConfig::default()
        };
        let mut wind = Wind::new(&config, rng(3)).unwrap();
        let params = wind.turbulence_params(&Vector3::zeros(), 0.0, &Vector3::zeros()).unwrap();
        // h floored at 1 m, V floored at 1 m/s: τ_w = L_w/V = 1 s.
        assert!((params.tau_s.z - 1.0).abs() < 1e-12, "{params:?}");
        let mut max = 0.0_f64;
        for k in 0..100_000u64 {
            let w = wind.update(k * 2000, 0.0, &Vector3::zeros());
            assert!(w.iter().all(|x| x.is_finite()));
            max = max.max(w.norm());
        }
        assert!(max > 0.1 && max < 10.0, "{max}");
    }

    #[test]
    fn given_the_same_seed_when_run_twice_then_the_wind_is_bit_identical_and_another_seed_differs() {
        let config = WindConfig {
            gust: Some(GustConfig::default()),
            turbulence: Some(TurbulenceConfig::GaussMarkov(GaussMarkovConfig {
                scale_with_gust: true,
                ..GaussMarkovConfig::default()
            })),
            ..WindConfig::default()
        };
        let run = |seed: u64| {
            let mut wind = Wind::new(&config, rng(seed)).unwrap();
            (0..10_000u64).map(|k| wind.update(k * 2000, 1.5, &Vector3::zeros())).collect::<Vec<_>>()
        };
        let a = run(42);
        let b = run(42);
        let c = run(43);
        assert!(a.iter().zip(&b).all(|(x, y)| x.iter().zip(y.iter()).all(|(p, q)| p.to_bits() == q.to_bits())));
        assert!(a.iter().zip(&c).any(|(x, y)| (x - y).norm() > 1e-3));
    }

    #[test]
    fn given_turbulence_scaled_by_the_gust_when_outside_the_gust_then_it_is_zero() {
        let config = WindConfig {
            gust: Some(GustConfig::default()),
            turbulence: Some(TurbulenceConfig::GaussMarkov(GaussMarkovConfig {
                scale_with_gust: true,
                ..GaussMarkovConfig::default()
            })),
            ..WindConfig::default()
        };
        let mut wind = Wind::new(&config, rng(5)).unwrap();
        let mut during = 0.0_f64;
        for k in 0..15_000u64 {
            let t_s = k as f64 * 0.002;
            wind.update(k * 2000, 1.5, &Vector3::zeros());
            let turb = wind.turbulence_ned_mps();
            if !(5.0..18.0).contains(&t_s) {
                assert_eq!(turb, Vector3::zeros(), "t = {t_s}");
            } else if (6.0..17.0).contains(&t_s) {
                during = during.max(turb.norm());
            }
        }
        assert!(during > 0.5, "{during}");
    }

    #[test]
    fn given_beaufort_presets_when_configured_then_the_mid_range_sets_the_gust_or_steady_wind() {
        assert_eq!(BEAUFORT.len(), 9);
        assert!((beaufort(4).unwrap().mid_mps() - 6.7).abs() < 1e-12);
        assert!(beaufort(9).is_err());
        for w in BEAUFORT.windows(2) {
            assert!(w[0].max_mps < w[1].min_mps && w[1].force == w[0].force + 1);
        }
        let gusty: WindConfig = toml::from_str("beaufort = 6\n[gust]\nonset_s = 1.0\nrelease_s = 3.0\n").unwrap();
        let wind = Wind::new(&gusty, rng(0)).unwrap();
        assert!((wind.gust().unwrap().amplitude_mps - 12.3).abs() < 1e-12);
        let steady = Wind::new(&WindConfig { beaufort: Some(4), ..WindConfig::default() }, rng(0)).unwrap();
        assert!((steady.mean_ned_mps(0.0) - Vector3::new(0.0, 6.7, 0.0)).norm() < 1e-12);
        let both: WindConfig = toml::from_str("beaufort = 4\n[gust]\namplitude_mps = 3.0\n").unwrap();
        assert!(Wind::new(&both, rng(0)).unwrap_err().to_string().contains("not both"));
    }

    #[test]
    fn given_a_wind_toml_when_parsed_then_models_and_errors_are_clear() {
        let config: WindConfig = toml::from_str(
            "steady_ned_mps = [1.0, 0.0, 0.0]\n[gust]\n[turbulence]\nmodel = \"gauss_markov\"\nscale_with_gust = true\n",
        )
        .unwrap();
        assert_eq!(config.gust, Some(GustConfig::default()));
        assert_eq!(
            config.turbulence,
            Some(TurbulenceConfig::GaussMarkov(GaussMarkovConfig {
                scale_with_gust: true,
                ..GaussMarkovConfig::default()
            }))
        );
        let dryden: WindConfig = toml::from_str("[turbulence]\nmodel = \"dryden\"\nw20_mps = 5.0\n").unwrap();
        assert!(matches!(dryden.turbulence, Some(TurbulenceConfig::Dryden(DrydenConfig { w20_mps: Some(5.0), .. }))));
        assert!(toml::from_str::<WindConfig>("[turbulence]\nmodel = \"von_karman\"\n").is_err());
        let unscaled: WindConfig =
            toml::from_str("[turbulence]\nmodel = \"gauss_markov\"\nscale_with_gust = true\n").unwrap();
        let err = Wind::new(&unscaled, rng(0)).unwrap_err().to_string();
        assert!(err.contains("needs a [wind.gust]"), "{err}");
        let bad_gust: WindConfig = toml::from_str("[gust]\nonset_s = 5.0\nrelease_s = 5.5\n").unwrap();
        assert!(Wind::new(&bad_gust, rng(0)).unwrap_err().to_string().contains("release_s"));
        let bad_tau: WindConfig =
            toml::from_str("[turbulence]\nmodel = \"gauss_markov\"\ntau_s = [1.0, 0.0, 1.0]\n").unwrap();
        assert!(Wind::new(&bad_tau, rng(0)).unwrap_err().to_string().contains("tau_s[1]"));
    }
}
