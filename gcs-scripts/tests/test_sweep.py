"""Sweeps split across processes and machines give the single-process result row for row: `sitl sweep`
shards merged with `--merge`, and `aco-sweep` on a local Ray cluster (a head started with `ray start`,
as a cluster's would be)."""

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sitl_harness import binary

# A 6 s gust hover, so 24 runs take a few seconds.
SCENARIO = """
name = "short-gust"
duration_s = 6.0
plant = "mismatch"
state_noise = "paper"
metrics = ["gust"]
[initial]
pos_ned_m = [0.0, 0.0, -1.5]
[reference]
kind = "position"
steps = [{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.5] }]
[wind.gust]
amplitude_mps = 5.0
onset_s = 1.0
rise_s = 0.5
release_s = 3.0
fall_s = 0.5
"""

SPEC = """
name = "split"
scenario = "short-gust.toml"
samples = 4
seed = 11
[vary]
mass_kg = { scale = [0.85, 1.15] }
gust_amplitude_mps = { uniform = [0.0, 10.0] }
gust_azimuth_deg = { values = [0.0, 90.0] }
state_noise_scale = { choice = [0.5, 1.0, 2.0] }
[bounds]
gust_peak_m = 0.5
"""

RUNS = 2 * 4 * 3


def sweep(spec, out, *extra):
    cmd = [str(binary("sitl")), "sweep", str(spec), "--out", str(out), "--no-plots", *extra]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture
def spec(tmp_path):
    (tmp_path / "short-gust.toml").write_text(SCENARIO)
    path = tmp_path / "split.toml"
    path.write_text(SPEC)
    return path


@pytest.fixture
def single(spec, tmp_path):
    """The whole sweep in one process: its rows file."""
    done = sweep(spec, tmp_path / "single")
    assert "gust_peak_m" in done.stdout and "within bound" in done.stdout, done.stdout
    rows = (tmp_path / "single" / "runs.csv").read_text()
    assert len(rows.splitlines()) == 1 + RUNS
    return rows


def test_shards_concatenated_and_merged_equal_the_unsharded_sweep(spec, single, tmp_path):
    out = tmp_path / "sharded"
    files = []
    for k in (1, 2, 3):
        sweep(spec, out, "--shard", f"{k}/3", "--jobs", "1")
        files.append(out / f"runs-shard-{k}-of-3.csv")
    # Concatenated (headers dropped) and put in run order, the shards are the unsharded rows.
    _header, *rows = single.splitlines()
    shard_rows = [line for f in files for line in f.read_text().splitlines()[1:]]
    assert sorted(shard_rows, key=lambda line: int(line.split(",")[0])) == rows
    # `--merge` checks them against the spec and writes the same file, byte for byte.
    sweep(spec, tmp_path / "merged", "--merge", *map(str, files))
    assert (tmp_path / "merged" / "runs.csv").read_text() == single
    # A missing shard is refused and writes nothing.
    cmd = [str(binary("sitl")), "sweep", str(spec), "--out", str(tmp_path / "bad"), "--merge", *map(str, files[:2])]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "missing" in done.stderr, done.stderr
    assert not (tmp_path / "bad" / "runs.csv").exists()


def free_tcp_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_aco_sweep_on_a_ray_cluster_equals_the_single_process_sweep(spec, single, tmp_path):
    ray_cli = Path(sys.executable).with_name("ray")
    port = free_tcp_port()
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    head = [str(ray_cli), "start", "--head", f"--port={port}", "--num-cpus=2", "--include-dashboard=false"]
    started = subprocess.run([*head, "--disable-usage-stats"], capture_output=True, text=True, env=env, timeout=180)
    assert started.returncode == 0, started.stdout + started.stderr
    try:
        start = time.monotonic()
        cmd = [sys.executable, "-m", "aco_gcs.sweep", str(spec), "--ray-address", f"127.0.0.1:{port}"]
        cmd += ["--shards", "3", "--out", str(tmp_path / "ray"), "--sitl", str(binary("sitl")), "--no-plots"]
        done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stdout + done.stderr
        print(f"aco-sweep on Ray: {RUNS} runs in 3 shards, {time.monotonic() - start:.1f} s")
        # Three tasks ran, each returned its shard, and the merge equals the single-process rows.
        for k in (1, 2, 3):
            assert f"shard {k}/3 done" in done.stderr, done.stderr
            assert (tmp_path / "ray" / "shards" / f"runs-shard-{k}-of-3.csv").exists()
        assert (tmp_path / "ray" / "runs.csv").read_text() == single
        assert "gust_peak_m" in done.stdout, done.stdout
    finally:
        subprocess.run([str(ray_cli), "stop", "--force"], capture_output=True, env=env, timeout=120)
