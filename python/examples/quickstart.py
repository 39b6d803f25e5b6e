"""The five-minute tour of aco_sim (docs/python.md), as a script: fly a scenario, plot its trace, write a
controller in Python, compare it with a built-in one, and step a vector environment.

    python python/examples/quickstart.py [--out DIR]

Each `# %%` cell runs on its own in an editor that knows cells (VS Code, Jupyter's jupytext); the tests run
the whole script (python/tests/test_examples.py).
"""

# %% Imports and where the figures go
from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import aco_sim
from aco_sim.pd import PdHover

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", type=Path, default=Path("out/python"))
out = parser.parse_args().out
out.mkdir(parents=True, exist_ok=True)

# %% What is built in
print("scenarios:", ", ".join(aco_sim.scenarios()))
print("controllers:", ", ".join(aco_sim.controllers()))

# %% Fly the paper's gust hover with ACO: the metrics `sitl scenario gust-hover --json` prints
sim = aco_sim.Sim("gust-hover", controller="aco", seed=1)
metrics = sim.run()
print(f"ACO: gust peak {metrics['gust']['peak_m']:.3f} m, {metrics['realtime_factor']:.0f}x real time")

# %% Plot its trace: the CSV's columns as numpy arrays
trace = sim.trace
fig, ax = plt.subplots(figsize=(7, 3))
ax.plot(trace["t"], np.hypot(trace["pN"] - trace["refN"], trace["pE"] - trace["refE"]), label="ACO")
ax.set_xlabel("t (s)")
ax.set_ylabel("horizontal error (m)")
ax.set_title("gust-hover")

# %% A controller in Python: (input, reference) -> four PWM (µs), called every 2 ms
pd = aco_sim.Sim("gust-hover", controller=PdHover(), seed=1)
pd_metrics = pd.run()
pd_trace = pd.trace
ax.plot(pd_trace["t"], np.hypot(pd_trace["pN"] - pd_trace["refN"], pd_trace["pE"] - pd_trace["refE"]), label="PD")
ax.legend()
fig.tight_layout()
fig.savefig(out / "gust-hover.png", dpi=100)
print(f"PD (Python): gust peak {pd_metrics['gust']['peak_m']:.3f} m; figure {out / 'gust-hover.png'}")

# %% The same law in Rust flies the identical run
twin = aco_sim.run_scenario("gust-hover", controller="example_pd", seed=1)
assert twin["gust"] == pd_metrics["gust"], "the Python law and its Rust twin differ"

# %% Step by step: the state, and a parameter set mid-flight (rotor 1 loses 5 % at 5 s, as the gust rises)
sim = aco_sim.Sim("gust-hover", controller="aco")
sim.step(2500)
sim.set_param("SIM_MOT1_EFF", 0.95)
sim.step(2500)
state = sim.state
print("at", state["t_s"], "s: truth", state["truth"]["pos_ned_m"].round(3), "estimate", state["estimate"]["pos_ned_m"])


# %% A vector environment: 64 hovers stepped in Rust; the action is collective thrust and body rates (ctbr),
# flown by ACO's rate loop. The policy here is a hand-written cascade on the observation (position and
# velocity error -> tilt -> rates); a learned one takes its place.
def policy(obs: np.ndarray) -> np.ndarray:
    dp, dv, q = obs[:, 0:3], obs[:, 3:6], obs[:, 6:10]
    acc = -1.0 * dp - 1.8 * dv  # NED m/s²
    roll, pitch, yaw = 2 * q[:, 1], 2 * q[:, 2], 2 * q[:, 3]  # small angles from the quaternion
    a = np.empty((len(obs), 4), dtype=np.float32)
    a[:, 0] = 0.65 - 0.25 * acc[:, 2]  # normalized collective; about 0.65 hovers the mismatch airframe
    a[:, 1] = 6.0 * (acc[:, 1] / 9.81 - roll)
    a[:, 2] = 6.0 * (-acc[:, 0] / 9.81 - pitch)
    a[:, 3] = -2.0 * yaw
    return a


envs = gymnasium.make_vec("aco_sim/Hover-v0", num_envs=64, vectorization_mode="vector_entry_point", action="ctbr")
obs, info = envs.reset(seed=7)
returns, crashes = np.zeros(64), 0
for _ in range(200):  # 2 s at the 100 Hz policy rate
    obs, reward, terminated, truncated, info = envs.step(policy(obs))
    returns += reward
    crashes += int(terminated.sum())
distance_m = np.linalg.norm(obs[:, :3], axis=1).mean()
print(f"64 hovers, 2 s: mean return {returns.mean():.1f}, {crashes} ended, mean distance {distance_m:.3f} m")
envs.close()
