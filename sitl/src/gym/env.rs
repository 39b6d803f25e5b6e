//! One environment: its reset from (seed, env index, episode) and its policy step (inner ticks of plant
//! and controller, then observation, reward, termination).

use std::f64::consts::{PI, TAU};
use std::sync::Arc;

use autopilot::core::control::{Controller, Reference, try_new_controller};
use nalgebra::{UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::GymError;
use super::config::{ActionMode, INNER_DT_US, LOOKAHEAD_S, Observe, Prepared, Task, TrackPath};
use super::track::Track;
use crate::plant::rigid_body::attitude_from_euler;
use crate::plant::sensors::NoisyState;
use crate::plant::{InitialState, Plant, StateNoise, Truth};
use crate::scenario::reference::{ReferenceGen, ReferenceMode, TrackSpec};
use crate::scenario::runner::{control_input, lockstep_plant_config};
use crate::scenario::{PathKind, ReferenceSpec};

/// Termination: the largest position error (m).
pub const MAX_POSITION_ERROR_M: f64 = 3.0;
/// Termination: the largest tilt of the body's down axis from the earth's (deg).
pub const MAX_TILT_DEG: f64 = 80.0;
/// Velocity action: how far the integrated position setpoint may lead the vehicle (m).
pub const VELOCITY_LEASH_M: f64 = 1.0;
/// Random track: how long after its reference comes to rest an episode is truncated (s).
pub const TRACK_SETTLE_S: f64 = 2.0;

/// The true state of one environment, for infos and rendering.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvTruth {
    /// Time in the episode (s).
    pub time_s: f64,
    pub pos_ned_m: [f64; 3],
    pub vel_ned_mps: [f64; 3],
    /// (w, x, y, z), body FRD to NED.
    pub q_ned_frd: [f64; 4],
    pub rate_frd_radps: [f64; 3],
    /// The reference position and velocity at `time_s`.
    pub ref_pos_ned_m: [f64; 3],
    pub ref_vel_ned_mps: [f64; 3],
}

/// What one policy step of one environment produced.
pub(super) struct StepOut {
    pub reward: f32,
    pub terminated: bool,
    pub truncated: bool,
}

/// What the vehicle is asked to follow.
enum Target {
    /// The hover's position steps.
    Steps(ReferenceGen),
    /// The track, with its look-ahead.
    Track(Track),
}

/// One environment between resets.
pub(super) struct Env {
    plant: Plant,
    /// None for `motors`.
    controller: Option<Box<dyn Controller>>,
    target: Target,
    noise: StateNoise,
    /// The noisy state sampled for the last observation: the controller's input at the next tick.
    pending: Option<NoisyState>,
    end_us: u64,
    pub episode: u64,
    pub ended: Option<&'static str>,
    /// Velocity mode: the integrated position setpoint and yaw.
    cmd_pos: Vector3<f64>,
    cmd_yaw: f64,
    ref_pos: Vector3<f64>,
    ref_vel: Vector3<f64>,
    ahead_pos: Vector3<f64>,
}

/// The random stream of env `env`'s episode `episode` of a batch reset with `seed`: a ChaCha8 key made of
/// the three numbers, so it depends on nothing else (not the batch size, not the threads).
#[must_use]
pub fn episode_rng(seed: u64, env: u64, episode: u64) -> ChaCha8Rng {
    let mut key = [0_u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&env.to_le_bytes());
    key[16..24].copy_from_slice(&episode.to_le_bytes());
    key[24..].copy_from_slice(b"aco-gym1");
    ChaCha8Rng::from_seed(key)
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// A random smooth closed track: 5-8 waypoints at increasing angles around the origin, 0.5-1.5 m out
/// (so within ±1.5 m), a periodic spline through them flown once at 0.3-0.6 m/s from 1 s.
fn random_track(rng: &mut ChaCha8Rng, base: &TrackSpec) -> TrackSpec {
    let n = rng.random_range(5..=8_usize);
    let theta0 = uniform(rng, 0.0, TAU);
    let mut waypoints: Vec<[f64; 2]> = (0..n)
        .map(|j| {
            let theta = theta0 + TAU * (j as f64 + uniform(rng, -0.3, 0.3)) / n as f64;
            let r = uniform(rng, 0.5, 1.5);
            [r * theta.cos(), r * theta.sin()]
        })
        .collect();
    waypoints.push(waypoints[0]);
    TrackSpec {
        waypoints_ne_m: waypoints,
        path: PathKind::Spline,
        speed_mps: uniform(rng, 0.3, 0.6),
        start_s: 1.0,
        laps: 1,
        reference_modes: vec![ReferenceMode::FeedForward],
        ..base.clone()
    }
}

impl Env {
    /// Env `index`'s episode `episode` of a batch reset with `seed`; writes its first observation.
    pub fn reset(p: &Prepared, seed: u64, index: u64, episode: u64, obs: &mut [f32]) -> Result<Self, GymError> {
        let cfg = &p.config;
        let mut rng = episode_rng(seed, index, episode);
        // The draws always happen in this order, whatever is used, so one setting never shifts another's.
        let sweep_seed: u64 = rng.random();
        let gust_onset_s = uniform(&mut rng, 0.5, (cfg.episode_s - 2.0).max(0.5));
        let gust_hold_s = uniform(&mut rng, 1.0, 4.0);
        let start: [f64; 9] = std::array::from_fn(|k| match k / 3 {
            0 => uniform(&mut rng, -0.5, 0.5),
            1 => uniform(&mut rng, -0.2, 0.2),
            _ => uniform(&mut rng, -0.3, 0.3),
        });
        let mut sweep = p.sweep.clone();
        sweep.seed = sweep_seed;
        let case = sweep.case(0).map_err(|e| GymError::Reset { env: index, reason: e.to_string() })?;
        let mut scenario = case.scenario;
        if p.random_gust_timing
            && let Some(g) = &mut scenario.wind.gust
        {
            g.onset_s = gust_onset_s;
            g.release_s = gust_onset_s + g.rise_s + gust_hold_s;
        }
        if let (Task::Track, TrackPath::Random, ReferenceSpec::Track(base)) =
            (cfg.task, cfg.track_path, &scenario.reference)
        {
            scenario.reference = ReferenceSpec::Track(random_track(&mut rng, base));
        }
        let mut end_s = cfg.episode_s;
        let (target, start_pos, start_yaw) = match &scenario.reference {
            ReferenceSpec::Track(spec) => {
                let path = match (&p.shared_path, cfg.track_path) {
                    (Some(path), TrackPath::Figure8) => Arc::clone(path),
                    _ => Track::path(spec),
                };
                let mut track = Track::new(spec, path);
                if cfg.track_path == TrackPath::Random {
                    end_s = end_s.min(track.end_s() + TRACK_SETTLE_S);
                }
                let start = track.at(0.0, LOOKAHEAD_S).0;
                (Target::Track(track), start, spec.yaw_rad)
            }
            spec => {
                let mut steps = ReferenceGen::new(spec, ReferenceMode::FeedForward);
                let r0 = steps.at(0.0);
                (Target::Steps(steps), r0.pos_ned_m, r0.yaw_rad)
            }
        };
        let mut initial = InitialState { pos_ned_m: start_pos, ..InitialState::default() };
        initial.euler_rad.z = start_yaw;
        if cfg.randomize_start {
            initial.pos_ned_m += Vector3::new(start[0], start[1], start[2]);
            initial.euler_rad += Vector3::new(start[3], start[4], start[5]);
            initial.vel_ned_mps = Vector3::new(start[6], start[7], start[8]);
        }
        let err = |e: String| GymError::Reset { env: index, reason: e };
        let config = lockstep_plant_config(&scenario, None).map_err(|e| err(e.to_string()))?;
        let plant = Plant::new(config, &initial, case.seed).map_err(|e| err(e.to_string()))?;
        let noise = scenario.state_noise().map_err(|e| err(e.to_string()))?;
        let controller = match cfg.action {
            ActionMode::Motors => None,
            _ => Some(try_new_controller(cfg.controller, &p.controller_config).map_err(|e| err(e.to_string()))?),
        };
        let mut env = Self {
            plant,
            controller,
            target,
            noise,
            pending: None,
            end_us: (end_s * 1e6).round() as u64,
            episode,
            ended: None,
            cmd_pos: initial.pos_ned_m,
            cmd_yaw: initial.euler_rad.z,
            ref_pos: Vector3::zeros(),
            ref_vel: Vector3::zeros(),
            ahead_pos: Vector3::zeros(),
        };
        let truth = env.plant.truth();
        env.observe(p, &truth, obs);
        Ok(env)
    }

    /// One policy step with `action` (already checked finite) held over it; writes the observation.
    pub fn step(&mut self, p: &Prepared, action: &[f32], obs: &mut [f32]) -> StepOut {
        let a: [f64; 4] = std::array::from_fn(|k| f64::from(action[k].clamp(p.low[k], p.high[k])));
        let mode = p.config.action;
        let held = match mode {
            ActionMode::Ctbr => Reference::rates(Vector3::new(a[1], a[2], a[3]), a[0], 0.0),
            ActionMode::Attitude => {
                let mut r = Reference::attitude(Vector3::new(a[1], a[2], a[3]), self.ref_pos.z);
                r.collective_frac = Some(a[0]);
                r
            }
            _ => Reference::position(Vector3::zeros(), 0.0),
        };
        let motors = a.map(|x| 1000.0 + 1000.0 * x);
        let dt_s = INNER_DT_US as f64 * 1e-6;
        let velocity = Vector3::new(a[0], a[1], a[2]);
        for _ in 0..p.ticks_per_step {
            let pwm_us = match &mut self.controller {
                None => motors,
                Some(controller) => {
                    let state = match self.pending.take() {
                        Some(s) => s,
                        None => {
                            let truth = self.plant.truth();
                            self.plant.sample_state_of(&truth, &self.noise)
                        }
                    };
                    let reference = if mode == ActionMode::Velocity {
                        let mut r = Reference::position(self.cmd_pos, self.cmd_yaw);
                        r.vel_ned_mps = velocity;
                        // The setpoint advances with the commanded velocity, held within a leash of the
                        // vehicle (as the controller sees it), so a blocked vehicle does not wind it up.
                        let lead = self.cmd_pos + velocity * dt_s - state.pos_ned_m;
                        let lead =
                            if lead.norm() > VELOCITY_LEASH_M { lead * (VELOCITY_LEASH_M / lead.norm()) } else { lead };
                        self.cmd_pos = state.pos_ned_m + lead;
                        self.cmd_yaw = wrap_pi(self.cmd_yaw + a[3] * dt_s);
                        r
                    } else {
                        held
                    };
                    controller.update(&control_input(&state), &reference)
                }
            };
            self.plant.step(pwm_us, INNER_DT_US);
        }
        let truth = self.plant.truth();
        self.observe(p, &truth, obs);
        let e_p = truth.pos_ned_m - self.ref_pos;
        let e_v = truth.vel_ned_mps - self.ref_vel;
        let finite = [truth.pos_ned_m, truth.vel_ned_mps, truth.rate_frd_radps].iter().flatten().all(|x| x.is_finite())
            && truth.q_ned_frd.coords.iter().all(|x| x.is_finite());
        let reward = 1.0 - e_p.norm() - 0.1 * e_v.norm() - 0.01 * truth.rate_frd_radps.norm();
        let cos_tilt = (truth.q_ned_frd * Vector3::z()).z;
        let terminated = !finite
            || e_p.norm() > MAX_POSITION_ERROR_M
            || cos_tilt < MAX_TILT_DEG.to_radians().cos()
            || truth.on_ground;
        let truncated = !terminated && truth.time_us >= self.end_us;
        self.ended = if terminated {
            Some("terminated")
        } else if truncated {
            Some("been truncated")
        } else {
            None
        };
        if !finite {
            obs.fill(0.0);
        }
        StepOut { reward: if finite { reward as f32 } else { 0.0 }, terminated, truncated }
    }

    /// Updates the reference at the plant's time and writes the observation of `truth` (or of the noisy
    /// state, sampled now and kept as the controller's next input).
    fn observe(&mut self, p: &Prepared, truth: &Truth, obs: &mut [f32]) {
        let t_s = truth.time_us as f64 * 1e-6;
        match &mut self.target {
            Target::Steps(steps) => {
                let r = steps.at(t_s);
                (self.ref_pos, self.ref_vel) = (r.pos_ned_m, r.vel_ned_mps);
            }
            Target::Track(track) => (self.ref_pos, self.ref_vel, self.ahead_pos) = track.at(t_s, t_s + LOOKAHEAD_S),
        }
        let noisy = if self.controller.is_some() || p.config.observe == Observe::Estimate {
            Some(self.plant.sample_state_of(truth, &self.noise))
        } else {
            None
        };
        let (pos, vel, q, rate) = match (&noisy, p.config.observe) {
            (Some(s), Observe::Estimate) => {
                (s.pos_ned_m, s.vel_ned_mps, attitude_from_euler(&s.euler_rad), s.rate_frd_radps)
            }
            _ => (truth.pos_ned_m, truth.vel_ned_mps, truth.q_ned_frd, truth.rate_frd_radps),
        };
        if self.controller.is_some() {
            self.pending = noisy;
        }
        let q = canonical(&q);
        let values = [pos - self.ref_pos, vel - self.ref_vel];
        for (k, v) in values.iter().flat_map(|v| v.iter()).enumerate() {
            obs[k] = *v as f32;
        }
        for (k, v) in q.iter().chain(rate.iter()).enumerate() {
            obs[6 + k] = *v as f32;
        }
        if matches!(self.target, Target::Track(_)) {
            let ahead = self.ahead_pos - self.ref_pos;
            for (k, v) in self.ref_vel.iter().chain(ahead.iter()).enumerate() {
                obs[13 + k] = *v as f32;
            }
        }
    }

    /// Time in the episode (s).
    pub fn time_s(&self) -> f64 {
        self.plant.time_us() as f64 * 1e-6
    }

    pub fn truth(&self) -> EnvTruth {
        let t = self.plant.truth();
        EnvTruth {
            time_s: self.time_s(),
            pos_ned_m: t.pos_ned_m.into(),
            vel_ned_mps: t.vel_ned_mps.into(),
            q_ned_frd: canonical(&t.q_ned_frd),
            rate_frd_radps: t.rate_frd_radps.into(),
            ref_pos_ned_m: self.ref_pos.into(),
            ref_vel_ned_mps: self.ref_vel.into(),
        }
    }

    /// Bytes this env holds beside its own struct: the controller, the hover's steps or the track's path
    /// when it is its own (not shared), and the plant's pack of GPS samples in flight (none here).
    pub fn heap_bytes(&self) -> usize {
        let controller = self.controller.as_ref().map_or(0, |c| std::mem::size_of_val(&**c));
        let target = match &self.target {
            Target::Steps(ReferenceGen::Position { steps }) => std::mem::size_of_val(steps.as_slice()),
            Target::Steps(_) => 0,
            Target::Track(t) if t.shared() => 0,
            Target::Track(t) => t.path_bytes(),
        };
        controller + target
    }
}

/// (w, x, y, z) with w >= 0.
fn canonical(q: &UnitQuaternion<f64>) -> [f64; 4] {
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.i, s * q.j, s * q.k]
}

fn wrap_pi(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w == -PI { PI } else { w }
}
