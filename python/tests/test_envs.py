"""The Gymnasium environments: Gymnasium's own checker on every task and action mode, the native vector
environment's determinism and independence of N, next-step autoreset, and replaceable functions."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import aco_sim  # noqa: F401  (registers the environments)

ENV_IDS = ("aco_sim/Hover-v0", "aco_sim/Track-v0")
ACTIONS = ("motors", "ctbr", "attitude", "velocity")


def make_vec(n: int, env_id: str = "aco_sim/Hover-v0", **kwargs):
    return gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("action", ACTIONS)
def test_gymnasiums_env_checker_passes(env_id, action):
    env = gymnasium.make(env_id, action=action)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("action", ACTIONS)
def test_a_hover_action_keeps_the_vehicle_up(action):
    env = gymnasium.make("aco_sim/Hover-v0", action=action, randomize_start=False)
    obs, _ = env.reset(seed=3)
    hold = {
        "motors": [0.6, 0.6, 0.6, 0.6],
        "ctbr": [0.62, 0.0, 0.0, 0.0],
        "attitude": [0.62, 0.0, 0.0, 0.0],
        "velocity": [0.0, 0.0, 0.0, 0.0],
    }[action]
    # Velocity holds the point through the controller for 3 s; the others hold near hover for 0.3 s.
    steps = 300 if action == "velocity" else 30
    for _ in range(steps):
        obs, _, terminated, _, _ = env.step(np.asarray(hold, dtype=np.float32))
        assert not terminated
    if action == "velocity":
        assert np.linalg.norm(obs[:3]) < 1.0
    assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape


def rollout(envs, seed: int, steps: int, action_seed: int = 1) -> np.ndarray:
    obs, _ = envs.reset(seed=seed)
    rng = np.random.default_rng(action_seed)
    space = envs.single_action_space
    n = envs.num_envs
    out = [obs.copy()]
    for _ in range(steps):
        a = rng.uniform(space.low, space.high, size=(n, 4)).astype(np.float32)
        obs, *_ = envs.step(a)
        out.append(obs.copy())
    return np.stack(out)


def test_ten_runs_with_one_seed_are_bit_identical():
    first = rollout(make_vec(32, action="ctbr"), seed=11, steps=120)
    for _ in range(9):
        again = rollout(make_vec(32, action="ctbr"), seed=11, steps=120)
        assert np.array_equal(again.view(np.uint32), first.view(np.uint32))


def env7(n: int, action: str) -> np.ndarray:
    """Environment 7's observations with its own action stream, in a batch of n (others hover)."""
    envs = make_vec(n, action=action)
    obs, _ = envs.reset(seed=5)
    rng = np.random.default_rng(9)
    space = envs.single_action_space
    rows = [obs[7].copy()]
    for _ in range(150):
        a = np.tile((space.low + space.high) / 2, (n, 1)).astype(np.float32)
        a[7] = rng.uniform(space.low, space.high).astype(np.float32)
        obs, *_ = envs.step(a)
        rows.append(obs[7].copy())
    envs.close()
    return np.stack(rows)


@pytest.mark.parametrize("action", ["motors", "ctbr"])
def test_environment_7_is_the_same_for_8_and_1024_environments(action):
    assert np.array_equal(env7(8, action), env7(1024, action))


def test_autoreset_follows_gymnasiums_next_step_mode():
    envs = make_vec(4, action="motors", randomize_start=False)
    envs.reset(seed=2)
    off = np.zeros((4, 4), dtype=np.float32)  # motors off: the vehicles fall
    hover = np.full((4, 4), 0.6, dtype=np.float32)
    ended_at = None
    for step in range(400):
        obs, reward, terminated, truncated, _ = envs.step(off if ended_at is None else hover)
        if terminated[0]:
            ended_at = step
            break
    assert ended_at is not None, "motors off never ended an episode"
    # The next step resets env 0 (its action ignored): reward 0, not ended, a fresh observation.
    obs, reward, terminated, truncated, _ = envs.step(hover)
    assert reward[0] == 0.0 and not terminated[0] and not truncated[0]
    assert np.linalg.norm(obs[0, :3]) < 1e-3  # back on its hover point (no start randomization)


def test_replaceable_reward_and_termination():
    calls = []

    def reward_fn(obs, actions, next_obs):
        calls.append(obs.shape)
        return -np.abs(next_obs[:, 2])

    def termination_fn(next_obs):
        return np.abs(next_obs[:, 2]) > 0.05

    envs = make_vec(8, action="ctbr", reward_fn=reward_fn, termination_fn=termination_fn)
    envs.reset(seed=1)
    ended = False
    for _ in range(100):
        _, reward, terminated, _, _ = envs.step(np.tile([0.3, 0, 0, 0], (8, 1)).astype(np.float32))
        assert np.all(reward <= 0.0)
        if terminated.any():
            ended = True
            i = int(np.flatnonzero(terminated)[0])
            _obs, reward, terminated, _truncated, _ = envs.step(np.tile([0.62, 0, 0, 0], (8, 1)).astype(np.float32))
            assert reward[i] == 0.0  # reset now
            break
    assert ended and calls and calls[0] == (8, 13)


def test_bad_actions_are_refused_and_change_nothing():
    envs = make_vec(4, action="motors")
    envs.reset(seed=4)
    good = np.full((4, 4), 0.6, dtype=np.float32)
    with pytest.raises(ValueError, match=r"actions have shape \(4, 3\), expected \(4, 4\)"):
        envs.step(np.zeros((4, 3), dtype=np.float32))
    with pytest.raises(TypeError, match="floating-point"):
        envs.step(np.ones((4, 4), dtype=np.int64))
    bad = good.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="action for env 2, component 1 is NaN: actions must be finite"):
        envs.step(bad)
    bad[2, 1] = np.inf
    with pytest.raises(ValueError, match="is inf"):
        envs.step(bad)
    after_refusals = envs.step(good)[0]
    fresh = make_vec(4, action="motors")
    fresh.reset(seed=4)
    assert np.array_equal(after_refusals, fresh.step(good)[0])


def test_a_step_after_termination_is_an_error_in_a_single_env():
    env = gymnasium.make("aco_sim/Hover-v0", action="motors", randomize_start=False).unwrapped
    env.reset(seed=1)
    terminated = False
    for _ in range(400):
        *_, terminated, _truncated, _ = env.step(np.zeros(4, dtype=np.float32))
        if terminated:
            break
    assert terminated
    with pytest.raises(RuntimeError, match="env 0 has terminated: reset it before stepping"):
        env.step(np.zeros(4, dtype=np.float32))
    env.reset(seed=1)
    env.step(np.zeros(4, dtype=np.float32))


def test_unknown_names_and_bad_options_are_refused():
    with pytest.raises(KeyError, match=r"unknown action mode `thrust` \(known: motors, ctbr, attitude, velocity\)"):
        gymnasium.make("aco_sim/Hover-v0", action="thrust")
    with pytest.raises(ValueError, match="ctbr needs a controller with a rate loop; ca has none"):
        gymnasium.make("aco_sim/Hover-v0", action="ctbr", controller="ca")
    with pytest.raises(KeyError, match="unknown controller `lqr`"):
        gymnasium.make("aco_sim/Hover-v0", action="ctbr", controller="lqr")
    with pytest.raises(KeyError, match=r"unknown observation `state` \(known: truth, estimate\)"):
        gymnasium.make("aco_sim/Hover-v0", observe="state")
    with pytest.raises(KeyError, match="unknown key `mass`"):
        gymnasium.make("aco_sim/Hover-v0", randomize={"mass": {"uniform": [5.0, 5.4]}})
    with pytest.raises(ValueError, match="randomize"):
        gymnasium.make("aco_sim/Hover-v0", randomize={"mass_kg": {"gaussian": [5.0, 0.1]}})


def test_randomize_takes_the_sweeps_distributions():
    envs = make_vec(16, action="motors", randomize={"wind_speed_mps": {"uniform": [2.0, 4.0]}})
    obs, _ = envs.reset(seed=8)
    assert obs.shape == (16, 13)


def test_the_estimate_differs_from_the_truth():
    truth = make_vec(2, action="ctbr", observe="truth")
    est = make_vec(2, action="ctbr", observe="estimate")
    a = np.tile([0.62, 0, 0, 0], (2, 1)).astype(np.float32)
    _t0, _ = truth.reset(seed=3)
    _e0, _ = est.reset(seed=3)
    t1 = truth.step(a)[0]
    e1 = est.step(a)[0]
    assert not np.array_equal(t1, e1)
    assert np.abs(t1 - e1).max() < 0.5
