"""Gymnasium environments over the lockstep simulator: ``aco_sim/Hover-v0`` and ``aco_sim/Track-v0``.

Every environment, single or vector, is a batch stepped in Rust (``aco_sim._native.VecEnv``): the vector
form steps all N environments on all cores with no Python loop per environment, and environment i's
trajectory depends only on (seed, i). See docs/python.md for the observations, actions, rewards and
terminations, and how to replace the reward and termination functions.

``gymnasium.make("aco_sim/Hover-v0", action="ctbr")`` gives one environment;
``gymnasium.make_vec("aco_sim/Hover-v0", num_envs=N, vectorization_mode="vector_entry_point")`` the
native vector environment (autoreset: Gymnasium 1.x's next-step mode).
"""

from __future__ import annotations

from typing import Any, Callable, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _native

#: ``reward_fn(obs, actions, next_obs) -> rewards``: batched, (N, D), (N, 4), (N, D) -> (N,).
RewardFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
#: ``termination_fn(next_obs) -> terminated``: batched, (N, D) -> (N,) bool.
TerminationFn = Callable[[np.ndarray], np.ndarray]

ACTIONS = ("motors", "ctbr", "attitude", "velocity")


def _native_env(task: str, num_envs: int, autoreset: bool, **kwargs: Any) -> _native.VecEnv:
    return _native.VecEnv(task, num_envs=num_envs, autoreset=autoreset, **kwargs)


def _spaces(native: _native.VecEnv) -> tuple[spaces.Box, spaces.Box]:
    """One environment's observation space (float32, unbounded) and action space (float32, the mode's bounds)."""
    observation = spaces.Box(-np.inf, np.inf, shape=(native.obs_dim,), dtype=np.float32)
    action = spaces.Box(
        np.asarray(native.action_low, dtype=np.float32),
        np.asarray(native.action_high, dtype=np.float32),
        dtype=np.float32,
    )
    return observation, action


def _check_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Actions as a C-contiguous float32 array of `shape`; a wrong shape or a non-float dtype is refused."""
    a = np.asarray(actions)
    if a.dtype.kind != "f":
        raise TypeError(f"actions must be a floating-point array (got dtype {a.dtype})")
    if a.shape != shape:
        raise ValueError(f"actions have shape {a.shape}, expected {shape}")
    return np.ascontiguousarray(a, dtype=np.float32)


class _Functions:
    """The replaceable reward and termination, applied to a batch after the Rust step."""

    def __init__(self, reward_fn: RewardFn | None, termination_fn: TerminationFn | None) -> None:
        self.reward_fn = reward_fn
        self.termination_fn = termination_fn

    def apply(
        self,
        native: _native.VecEnv,
        obs: np.ndarray,
        actions: np.ndarray,
        next_obs: np.ndarray,
        reward: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
        reset_now: np.ndarray,
    ) -> None:
        if self.reward_fn is not None:
            custom = np.asarray(self.reward_fn(obs, actions, next_obs), dtype=np.float32)
            if custom.shape != reward.shape:
                raise ValueError(f"reward_fn returned shape {custom.shape}, expected {reward.shape}")
            reward[:] = np.where(reset_now, 0.0, custom)
        if self.termination_fn is not None:
            custom_t = np.asarray(self.termination_fn(next_obs), dtype=bool)
            if custom_t.shape != terminated.shape:
                raise ValueError(f"termination_fn returned shape {custom_t.shape}, expected {terminated.shape}")
            terminated[:] = custom_t & ~reset_now
            native.set_ended(terminated | truncated)


class AcoEnv(gymnasium.Env):
    """One environment (``gymnasium.make``): a native batch of one, without autoreset.

    Keyword arguments (all optional): ``action`` ("motors", "ctbr", "attitude", "velocity"), ``observe``
    ("truth" or "estimate"), ``controller`` (the registered controller that flies ctbr, attitude and
    velocity), ``policy_hz`` (100), ``episode_s``, ``track_path`` ("figure8" or "random", Track only),
    ``randomize`` ({sweep parameter: distribution}, the sweep's ``[vary]`` table), ``randomize_start``,
    ``reward_fn`` and ``termination_fn`` (batched functions replacing the defaults).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(
        self,
        task: str = "hover",
        *,
        reward_fn: RewardFn | None = None,
        termination_fn: TerminationFn | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        if render_mode is not None:
            raise ValueError("aco_sim environments do not render; see docs/python.md for plotting the trace")
        self._native = _native_env(task, 1, False, **kwargs)
        self._functions = _Functions(reward_fn, termination_fn)
        self.observation_space, self.action_space = _spaces(self._native)
        self.obs_names = list(self._native.obs_names)
        self._obs: np.ndarray | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        native_seed = seed if seed is not None else int(self.np_random.integers(0, 2**63))
        obs = self._native.reset(native_seed)
        self._obs = obs
        return obs[0].copy(), {"episode_time_s": 0.0}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._obs is None:
            raise RuntimeError("reset() the environment before stepping it")
        actions = _check_actions(action, self.action_space.shape)[None, :]
        next_obs, reward, terminated, truncated, reset_now = self._native.step(actions)
        self._functions.apply(self._native, self._obs, actions, next_obs, reward, terminated, truncated, reset_now)
        self._obs = next_obs
        info = {"episode_time_s": float(self._native.episode_time_s()[0])}
        return next_obs[0].copy(), float(reward[0]), bool(terminated[0]), bool(truncated[0]), info


class AcoVectorEnv(VectorEnv):
    """N environments stepped together in Rust (``gymnasium.make_vec(..., vectorization_mode=
    "vector_entry_point")``); autoreset in Gymnasium 1.x's next-step mode. Same keyword arguments as
    :class:`AcoEnv`."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        task: str = "hover",
        num_envs: int = 1,
        *,
        reward_fn: RewardFn | None = None,
        termination_fn: TerminationFn | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        if render_mode is not None:
            raise ValueError("aco_sim environments do not render; see docs/python.md for plotting the trace")
        self._native = _native_env(task, num_envs, True, **kwargs)
        self._functions = _Functions(reward_fn, termination_fn)
        self.num_envs = num_envs
        self.single_observation_space, self.single_action_space = _spaces(self._native)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.obs_names = list(self._native.obs_names)
        self._obs: np.ndarray | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self._np_random, self._np_random_seed = gymnasium.utils.seeding.np_random(seed)
        native_seed = seed if seed is not None else int(self.np_random.integers(0, 2**63))
        self._obs = self._native.reset(native_seed)
        return self._obs.copy(), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self._obs is None:
            raise RuntimeError("reset() the environments before stepping them")
        a = _check_actions(actions, (self.num_envs, 4))
        next_obs, reward, terminated, truncated, reset_now = self._native.step(a)
        self._functions.apply(self._native, self._obs, a, next_obs, reward, terminated, truncated, reset_now)
        self._obs = next_obs
        return next_obs, reward, terminated, truncated, {}


def _register() -> None:
    for env_id, task in (("aco_sim/Hover-v0", "hover"), ("aco_sim/Track-v0", "track")):
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="aco_sim.envs:AcoEnv",
                vector_entry_point="aco_sim.envs:AcoVectorEnv",
                kwargs={"task": task},
                disable_env_checker=False,
            )


_register()
