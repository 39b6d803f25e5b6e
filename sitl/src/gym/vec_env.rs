//! [`VecEnv`]: a batch of environments stepped together across the cores (rayon), with Gymnasium 1.x
//! next-step autoreset.

use rayon::prelude::*;

use super::GymError;
use super::config::{EnvConfig, Prepared};
use super::env::{Env, EnvTruth};

/// A batch of `num_envs` environments of one configuration.
pub struct VecEnv {
    prepared: Prepared,
    envs: Vec<Env>,
    autoreset: bool,
    /// The seed of the last [`VecEnv::reset`]: every later episode of env i draws from (seed, i, k).
    seed: u64,
}

impl VecEnv {
    /// Validates `config` and builds `num_envs` environments, each reset with seed 0 (call
    /// [`VecEnv::reset`] with your own seed before stepping).
    ///
    /// # Errors
    /// An invalid configuration ([`EnvConfig::validate`]) or `num_envs` = 0.
    pub fn new(config: EnvConfig, num_envs: usize, autoreset: bool) -> Result<Self, GymError> {
        if num_envs == 0 {
            return Err(GymError::Config("num_envs must be at least 1".into()));
        }
        let prepared = Prepared::new(&config)?;
        let mut obs = vec![0.0; config.obs_dim()];
        let envs = (0..num_envs)
            .into_par_iter()
            .map_with(obs.clone(), |obs, i| Env::reset(&prepared, 0, i as u64, 0, obs))
            .collect::<Result<Vec<_>, _>>()?;
        obs.clear();
        Ok(Self { prepared, envs, autoreset, seed: 0 })
    }

    #[must_use]
    pub fn num_envs(&self) -> usize {
        self.envs.len()
    }

    #[must_use]
    pub fn config(&self) -> &EnvConfig {
        &self.prepared.config
    }

    #[must_use]
    pub fn autoreset(&self) -> bool {
        self.autoreset
    }

    fn check_len(name: &'static str, got: usize, per_env: usize, num_envs: usize) -> Result<(), GymError> {
        if got == per_env * num_envs { Ok(()) } else { Err(GymError::Length { name, got, per_env, num_envs }) }
    }

    /// Resets every env: env i's episode 0 draws from (seed, i) only. `obs`: num_envs × obs_dim.
    ///
    /// # Errors
    /// A wrong `obs` length (nothing changes), or a randomized plant that cannot be built.
    pub fn reset(&mut self, seed: u64, obs: &mut [f32]) -> Result<(), GymError> {
        let d = self.prepared.config.obs_dim();
        Self::check_len("observations", obs.len(), d, self.envs.len())?;
        let p = &self.prepared;
        let fresh = obs
            .par_chunks_mut(d)
            .enumerate()
            .map(|(i, o)| Env::reset(p, seed, i as u64, 0, o))
            .collect::<Result<Vec<_>, _>>()?;
        self.envs = fresh;
        self.seed = seed;
        Ok(())
    }

    /// One policy step of every env. `actions`: num_envs × 4, row-major; outputs sized num_envs (obs:
    /// × obs_dim). Finite actions outside [action_low, action_high] are clipped.
    ///
    /// With autoreset (Gymnasium 1.x NEXT_STEP): an env that ended on the previous step is reset now with
    /// its next episode's draws (its action ignored) and returns its reset observation, reward 0,
    /// terminated = truncated = false and `reset_now[i]` = true. Without: stepping an ended env is an
    /// error and nothing changes.
    ///
    /// # Errors
    /// Wrong buffer lengths, a non-finite action, or (without autoreset) an ended env: all before any env
    /// changes. A reset's plant that cannot be built (after the others stepped).
    pub fn step(
        &mut self,
        actions: &[f32],
        obs: &mut [f32],
        reward: &mut [f32],
        terminated: &mut [bool],
        truncated: &mut [bool],
        reset_now: &mut [bool],
    ) -> Result<(), GymError> {
        let n = self.envs.len();
        let d = self.prepared.config.obs_dim();
        let a = self.prepared.config.action_dim();
        if actions.len() != a * n {
            return Err(GymError::ActionLength { got: actions.len(), per_env: a, num_envs: n });
        }
        Self::check_len("observations", obs.len(), d, n)?;
        for (name, len) in [("rewards", reward.len()), ("terminated", terminated.len())] {
            Self::check_len(name, len, 1, n)?;
        }
        Self::check_len("truncated", truncated.len(), 1, n)?;
        Self::check_len("reset_now", reset_now.len(), 1, n)?;
        if let Some(k) = actions.iter().position(|x| !x.is_finite()) {
            return Err(GymError::NonFiniteAction { env: k / a, component: k % a, value: actions[k] });
        }
        if !self.autoreset
            && let Some((i, e)) = self.envs.iter().enumerate().find(|(_, e)| e.ended.is_some())
        {
            return Err(GymError::Ended { env: i, how: e.ended.unwrap_or("ended") });
        }
        let p = &self.prepared;
        let seed = self.seed;
        self.envs
            .par_iter_mut()
            .zip(actions.par_chunks(a))
            .zip(obs.par_chunks_mut(d))
            .zip(reward.par_iter_mut())
            .zip(terminated.par_iter_mut())
            .zip(truncated.par_iter_mut())
            .zip(reset_now.par_iter_mut())
            .enumerate()
            .try_for_each(|(i, ((((((env, act), o), r), term), trunc), now))| {
                if env.ended.is_some() {
                    *env = Env::reset(p, seed, i as u64, env.episode + 1, o)?;
                    (*r, *term, *trunc, *now) = (0.0, false, false, true);
                } else {
                    let out = env.step(p, act, o);
                    (*r, *term, *trunc, *now) = (out.reward, out.terminated, out.truncated, false);
                }
                Ok(())
            })
    }

    /// Marks the envs with `ended[i]` = true as ended (a Python-side termination), so they reset at the
    /// next step (or refuse it without autoreset); `false` leaves an env as it is.
    ///
    /// # Errors
    /// A wrong length (nothing changes).
    pub fn set_ended(&mut self, ended: &[bool]) -> Result<(), GymError> {
        Self::check_len("ended", ended.len(), 1, self.envs.len())?;
        for (env, &e) in self.envs.iter_mut().zip(ended) {
            if e && env.ended.is_none() {
                env.ended = Some("been marked ended");
            }
        }
        Ok(())
    }

    /// Per-env time in the episode (s).
    #[must_use]
    pub fn episode_time_s(&self) -> Vec<f64> {
        self.envs.iter().map(Env::time_s).collect()
    }

    /// Per-env episode count since the last [`VecEnv::reset`] (0 for the reset's own episode).
    #[must_use]
    pub fn episode_index(&self) -> Vec<u64> {
        self.envs.iter().map(|e| e.episode).collect()
    }

    /// The true state of env `i` and its reference.
    ///
    /// # Panics
    /// If `i` >= `num_envs`.
    #[must_use]
    pub fn truth(&self, i: usize) -> EnvTruth {
        self.envs[i].truth()
    }

    /// Memory of env 0: (the env struct's size, an estimate of its heap: controller, reference, plant).
    #[must_use]
    pub fn env_bytes(&self) -> (usize, usize) {
        (std::mem::size_of::<Env>(), self.envs[0].heap_bytes())
    }
}
