"""Measure the step throughput of RotorPy's batched quadrotor environment, for comparison with aco_sim.

RotorPy (3.x) ships one environment, ``rotorpy.learning.quadrotor_environments.QuadrotorEnv``, and it is
already batched: a Stable-Baselines3 ``VecEnv`` over ``num_envs`` drones whose dynamics
(``BatchedMultirotor``) are stepped together in PyTorch, with SB3-style autoreset inside ``step``. It needs
RotorPy's ``batched`` and ``learning`` extras (torch, torchdiffeq, roma, opt-einsum, stable-baselines3).

The task timed is RotorPy's own hover task: hover at the origin (``vec_hover_reward``), start at a random
position within 2 m, no wind, crazyflie parameters, 10 s episodes, out-of-bounds termination, on the CPU
(torch limited to ``_TORCH_THREADS`` intra-op threads while timing).
The policy acts at 100 Hz (``sim_rate=100``) with direct motor-speed commands (``cmd_motor_speeds``, the
analogue of aco_sim's default ``action="motors"``); each step integrates the dynamics over 10 ms with one
fixed-step RK4 step (torchdiffeq ``rk4``), so the integration rate is also 100 Hz. Actions are uniform in
the action space ([-1, 1]^4), drawn before timing. rotorpy is imported lazily so that this module imports
without it.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

_CONTROL_MODE = "cmd_motor_speeds"
_RATE_HZ = 100
_MAX_TIME_S = 10.0
_WARMUP_STEPS = 20
# torch's intra-op threads while timing. One, because on a small machine shared with other work (builds),
# torch's default (one per core) oversubscribes the cores and its step time swings by up to 10x; in a quiet
# moment on a 2-core machine two threads were only ~5-10% faster at 1024 drones. None keeps torch's default.
_TORCH_THREADS: int | None = 1
_ACTION_POOL_STEPS = 256


def available() -> bool:
    """Whether rotorpy and its batched environment (with torch and stable-baselines3) can be imported."""
    try:
        import rotorpy  # noqa: F401
        from rotorpy.learning import quadrotor_environments  # noqa: F401
    except ImportError:
        return False
    return True


def _rotorpy_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rotorpy")
    except PackageNotFoundError:
        return "unknown"


def describe() -> str:
    """One line: the rotorpy version, which environment is timed, its control mode and its rates."""
    torch_part = ""
    try:
        import torch

        threads = _TORCH_THREADS if _TORCH_THREADS is not None else torch.get_num_threads()
        torch_part = f", torch {torch.__version__} on cpu with {threads} thread(s)"
    except ImportError:
        pass
    return (
        f"rotorpy {_rotorpy_version()}: batched QuadrotorEnv (rotorpy.learning.quadrotor_environments, an SB3 VecEnv "
        f"over BatchedMultirotor{torch_part}), hover task, control_mode={_CONTROL_MODE}, policy {_RATE_HZ} Hz, "
        f"integration one RK4 step per policy step ({_RATE_HZ} Hz), {_MAX_TIME_S:g} s episodes, SB3-style autoreset"
    )


def _make_env(num_envs: int) -> Any:
    import torch
    from rotorpy.learning.quadrotor_environments import QuadrotorEnv
    from rotorpy.vehicles.crazyflie_params import quad_params

    device = torch.device("cpu")
    init_rotor_speed = 1788.53  # crazyflie hover speed, as in rotorpy's make_default_vec_env
    initial_states = {
        "x": torch.zeros(num_envs, 3, device=device).double(),
        "v": torch.zeros(num_envs, 3, device=device).double(),
        "q": torch.tensor([0, 0, 0, 1], device=device).repeat(num_envs, 1).double(),
        "w": torch.zeros(num_envs, 3, device=device).double(),
        "wind": torch.zeros(num_envs, 3, device=device).double(),
        "rotor_speeds": torch.full((num_envs, 4), init_rotor_speed, device=device).double(),
    }
    return QuadrotorEnv(
        num_envs,
        initial_states=initial_states,
        control_mode=_CONTROL_MODE,
        quad_params=quad_params,
        device=device,
        max_time=_MAX_TIME_S,
        sim_rate=_RATE_HZ,
        render_mode="None",  # rotorpy's "no rendering" (the string): no plots, no per-step printing
    )


def steps_per_second(num_envs: int, seconds: float = 2.0, seed: int = 0) -> float:
    """Environment steps per second (num_envs * steps / elapsed) of `num_envs` batched RotorPy hover environments.

    Times calls to the batched ``step`` for about `seconds` of wall-clock time after a warm-up, with random
    actions drawn beforehand (a pool of them, cycled) and RotorPy's own autoreset.
    """
    if num_envs < 1:
        raise ValueError(f"num_envs must be at least 1 (got {num_envs})")
    import torch

    threads_before = torch.get_num_threads()
    if _TORCH_THREADS is not None:
        torch.set_num_threads(_TORCH_THREADS)
    env = _make_env(num_envs)
    try:
        env.reset(seed=seed)  # seeds numpy's and torch's global generators, as rotorpy does
        rng = np.random.default_rng(seed)
        low = np.broadcast_to(env.action_space.low, (num_envs, *env.action_space.shape))
        high = np.broadcast_to(env.action_space.high, (num_envs, *env.action_space.shape))
        pool = rng.uniform(low, high, size=(_ACTION_POOL_STEPS, *low.shape)).astype(env.action_space.dtype)

        for i in range(_WARMUP_STEPS):
            env.step(pool[i % _ACTION_POOL_STEPS])

        steps = 0
        start = time.perf_counter()
        deadline = start + seconds
        while True:
            env.step(pool[steps % _ACTION_POOL_STEPS])
            steps += 1
            now = time.perf_counter()
            if now >= deadline:
                break
        return num_envs * steps / (now - start)
    finally:
        env.close()
        torch.set_num_threads(threads_before)
