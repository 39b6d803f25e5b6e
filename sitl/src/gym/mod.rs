//! A batched reinforcement-learning environment core in pure Rust (a Python binding wraps it): the
//! plant and a controller stepped in lockstep at 500 Hz as `scenario::runner` does, many environments
//! at once across the cores, each reset drawing its plant, wind and start with the sweep's distributions.
//!
//! # Tasks
//! - **Hover-v0** (`hover`): hold a point at 1.5 m (NED D = -1.5) on the `gust-hover` scenario (mismatch
//!   plant): steady wind, a 1-cos gust (1 s rise and fall) at a random time (onset uniform in
//!   [0.5, episode_s - 2] s, held 1-4 s) of random amplitude and direction, gust-scaled Gauss-Markov
//!   turbulence, the paper's sensor noise on the `estimate`. Episodes of 10 s by default.
//! - **Track-v0** (`track`): follow the prefiltered reference of a closed path at 1.5 m with its
//!   feed-forward. `figure8`: the built-in `figure8` scenario's track (36 s). `random`: 5-8 waypoints at
//!   increasing angles around the origin, 0.5-1.5 m out (within ±1.5 m), a periodic spline flown once at
//!   0.3-0.6 m/s from 1 s; truncated 2 s after its reference comes to rest, or at `episode_s` (36 s).
//!
//! Default randomization per reset ([`default_randomize`], the sweep's [`Param`]s and
//! [`Distribution`]s): mass ×[0.93, 1.02] (the rotors' 11.3-14.5 N leave little
//! headroom above the 5.4 kg hover), inertia ×[0.8, 1.2], steady wind 0-3 m/s (track 0-2) from any
//! azimuth; hover: gust amplitude 0-7.9 m/s (up to Beaufort 4's top) from any azimuth, turbulence scale
//! 0-0.5 (σ 1.3, 1.3, 0.67 m/s times it, times the gust profile); track: turbulence scale 0-0.3
//! (constant). With `randomize_start`: start offset ±0.5 m per axis from the reference's start, Euler
//! angles ±0.2 rad each, velocity ±0.3 m/s per axis (all uniform).
//!
//! # Actions (four float32 values; finite values outside the bounds are clipped, non-finite refused)
//! - `motors`: a in [0, 1]⁴, PWM 1000 + 1000 a µs, rotors numbered as the plant's (1 right, 2 rear,
//!   3 front, 4 left). No controller.
//! - `ctbr`: [collective 0..1, p, q, r], rates FRD within ±[π, π, 1.4] rad/s (PX4 Acro's 180/180/80 deg/s),
//!   as `Reference::rates` to the controller's rate loop every inner tick (a controller with one only).
//! - `attitude`: [collective 0..1, roll, pitch within ±0.6 rad, yaw ±π], as `Reference::attitude` with
//!   `collective_frac`.
//! - `velocity`: [vN, vE within ±3, vD ±2 m/s, yaw rate ±1.4 rad/s]: a position setpoint integrated from
//!   the velocity every inner tick (kept within 1 m of the vehicle as the controller sees it) and the
//!   yaw integrated from the rate, with the velocity as feed-forward (PX4 offboard velocity).
//!
//! The action is held over the policy step: 500 / `policy_hz` inner ticks of 2 ms. The collective is the
//! controller's normalized thrust: 4 (F_min + c (F_max - F_min)) of its nominal model. A fresh controller
//! is built at every reset (no adaptive history).
//!
//! # Observations (float32, at the end of the step; NED m, m/s, FRD rad/s)
//! `[0:3]` p - p_ref, `[3:6]` v - v_ref, `[6:10]` attitude quaternion (w, x, y, z) body FRD to NED with
//! w >= 0, `[10:13]` body rates p, q, r. Track appends `[13:16]` v_ref and `[16:19]` p_ref(t + 0.5 s) -
//! p_ref(t). `truth` observes the true state; `estimate` the noisy state of the scenario's `state_noise`
//! (the quaternion from its noisy Euler angles), the very sample the controller flies on at the next tick.
//! Names: [`EnvConfig::obs_names`].
//!
//! # Reward (per step, on the TRUTH at the end of the step)
//! `r = 1 − ‖p − p_ref‖ − 0.1 ‖v − v_ref‖ − 0.01 ‖ω‖` (m, m/s, rad/s; ω the body rates).
//!
//! # Termination and truncation
//! Terminated (on the truth, at the end of a step): ‖p − p_ref‖ > 3 m, tilt (angle between the body's down
//! axis and the earth's) > 80°, ground contact, or a non-finite state (then reward 0 and a zero
//! observation). Truncated: the episode time reaches `episode_s` (not when terminated on the same step).
//!
//! # Determinism
//! Env i's k-th episode (k = 0 at [`VecEnv::reset`], then one more per autoreset) draws everything
//! (randomized values, gust timing, start, path, plant seed) from a ChaCha8 stream keyed by (seed, i, k)
//! alone: not by the number of envs or threads.

mod config;
mod env;
mod track;
mod vec_env;

pub use config::{
    ActionMode, EnvConfig, INNER_DT_US, INNER_HZ, LOOKAHEAD_S, Observe, Task, TrackPath, default_randomize,
};
pub use env::{EnvTruth, MAX_POSITION_ERROR_M, MAX_TILT_DEG, TRACK_SETTLE_S, VELOCITY_LEASH_M, episode_rng};
pub use vec_env::VecEnv;

pub use crate::sweep::{Distribution, Param};

/// Why a configuration, a reset or a step was refused.
#[derive(Debug, thiserror::Error)]
pub enum GymError {
    #[error("unknown {what} `{name}` (known: {known})")]
    UnknownName { what: &'static str, name: String, known: String },
    #[error("invalid environment configuration: {0}")]
    Config(String),
    #[error("ctbr needs a controller with a rate loop; {controller} has none")]
    NoRateLoop { controller: String },
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    #[error("env {env} cannot be reset: {reason}")]
    Reset { env: u64, reason: String },
    #[error("actions have {got} values, expected {per_env} x {num_envs} = {}", per_env * num_envs)]
    ActionLength { got: usize, per_env: usize, num_envs: usize },
    #[error("{name} buffer has {got} values, expected {per_env} x {num_envs} = {}", per_env * num_envs)]
    Length { name: &'static str, got: usize, per_env: usize, num_envs: usize },
    #[error("action for env {env}, component {component} is {value}: actions must be finite")]
    NonFiniteAction { env: usize, component: usize, value: f32 },
    #[error("env {env} has {how}: reset it before stepping")]
    Ended { env: usize, how: &'static str },
}

#[cfg(test)]
mod tests;
