"""``python -m aco_sim.bench``: environment steps per second of the native vector environment, and the
memory each environment takes.

For N = 1, 64 and 1,024 hovers (``aco_sim/Hover-v0``) with a 100 Hz policy over the 500 Hz plant, per
action mode (``motors`` and ``ctbr`` by default), actions drawn uniformly from the action space before
timing (so crashes and autoresets are part of the figure), it times ``step`` for about ``--seconds`` after
a warm-up and prints N x steps / elapsed. The memory per environment is the growth of the resident set
when 4,096 more environments are made and reset, divided by 4,096. When RotorPy's batched environment is
installed (``aco_sim.bench_rotorpy``), its figure on its own hover task is printed beside ours.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import gymnasium
import numpy as np

import aco_sim  # noqa: F401  (registers the environments)

from . import bench_rotorpy


def rss_bytes() -> int:
    """The resident set now (Linux: /proc/self/statm), else the peak (getrusage)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def steps_per_second(num_envs: int, action: str, seconds: float, seed: int = 0) -> float:
    envs = gymnasium.make_vec(
        "aco_sim/Hover-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", action=action
    )
    envs.reset(seed=seed)
    rng = np.random.default_rng(seed)
    low, high = envs.single_action_space.low, envs.single_action_space.high
    pool = rng.uniform(low, high, size=(64, num_envs, 4)).astype(np.float32)
    for k in range(10):
        envs.step(pool[k % len(pool)])
    steps, start = 0, time.perf_counter()
    while True:
        for _ in range(10):
            envs.step(pool[steps % len(pool)])
            steps += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            break
    envs.close()
    return num_envs * steps / elapsed


def bytes_per_env(action: str, num_envs: int = 4096) -> float:
    before = rss_bytes()
    envs = gymnasium.make_vec(
        "aco_sim/Hover-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", action=action
    )
    envs.reset(seed=0)
    envs.step(np.zeros((num_envs, 4), dtype=np.float32) + envs.single_action_space.low)
    grown = rss_bytes() - before
    envs.close()
    return grown / num_envs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="1,64,1024", help="numbers of environments, comma-separated")
    parser.add_argument("--actions", default="motors,ctbr", help="action modes, comma-separated")
    parser.add_argument("--seconds", type=float, default=3.0, help="timed seconds per figure")
    parser.add_argument("--no-rotorpy", action="store_true", help="skip RotorPy even when it is installed")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    actions = args.actions.split(",")
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.python_implementation()} "
        f"{platform.python_version()}, aco_sim Hover-v0 at a 100 Hz policy over the 500 Hz plant"
    )
    print(f"{'env':<24} {'N':>6} {'env steps/s':>14} {'x real time':>12}")
    for action in actions:
        for n in sizes:
            sps = steps_per_second(n, action, args.seconds)
            print(f"{'aco_sim ' + action:<24} {n:>6} {sps:>14,.0f} {sps / 100:>12,.0f}")
    if not args.no_rotorpy and bench_rotorpy.available():
        print(f"# {bench_rotorpy.describe()}")
        for n in sizes:
            sps = bench_rotorpy.steps_per_second(n, args.seconds)
            print(f"{'rotorpy cmd_motor_speeds':<24} {n:>6} {sps:>14,.0f} {sps / 100:>12,.0f}")
    elif not args.no_rotorpy:
        print("# RotorPy's batched environment is not installed (pip install './python[rotorpy]')")
    for action in actions:
        print(
            f"memory per environment ({action}): {bytes_per_env(action) / 1024:.1f} KiB "
            "(resident set growth over 4,096)"
        )


if __name__ == "__main__":
    main()
