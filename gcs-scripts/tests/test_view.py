"""The live-view bridge `python -m aco_gcs.view`: frames in, a Rerun recording out that Rerun's own reader
finds every sample in (a malformed line skipped, not fatal), the .rrd under its final name only after a clean
end, a ULog shown as frames, and the web viewer in headless Chromium drawing the orange quadrotor in 3D and
plots whose time axis moves on (view_browser.check_live_view, which `sitl run --view`'s test reuses)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from aco_gcs.view_synth import frames

SECONDS = 4.0
RATE_HZ = 50.0
ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}


def bridge(*args: str, stderr: Any = subprocess.PIPE) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "aco_gcs.view", *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        env=ENV,
    )


def read_rrd(path: Path) -> Any:
    """The recording as one Arrow table on the `sim_time` index, read by Rerun's own server."""
    import rerun as rr

    with rr.server.Server(host="127.0.0.1", datasets={"d": [str(path)]}) as server:
        client = server.client()  # held while the query runs (its context goes out of scope otherwise)
        dataset = client.get_dataset("d")
        frame = dataset.reader(index="sim_time")
        return frame.to_arrow_table()


def samples(table: Any, column: str) -> int:
    col = table.column(column)
    return col.length() - col.null_count


def test_frames_become_a_recording_with_every_sample(tmp_path: Path) -> None:
    rrd = tmp_path / "x.rrd"
    lines = [json.dumps(f) for f in frames(["v0", "v1"], SECONDS, RATE_HZ)]
    lines.insert(len(lines) // 2, '{"kind": "truth", "src": "v0", "t_us": ')  # cut short
    lines.insert(10, '{"kind": "future_kind", "src": "v0", "t_us": 5, "whatever": [1]}')  # ignored
    proc = bridge("--no-viewer", "--record", str(rrd))
    out, err = proc.communicate("\n".join(lines) + "\n", timeout=120)
    assert proc.returncode == 0, err
    assert out.splitlines()[0] == f"ready {rrd}", out
    assert "1 malformed line(s) skipped" in err, err
    assert rrd.exists() and not rrd.with_name("x.rrd.tmp").exists()

    table = read_rrd(rrd)
    n = int(SECONDS * RATE_HZ) + 1  # every sample of both halves: the malformed line stopped nothing
    for src in ("v0", "v1"):
        assert samples(table, f"/world/{src}/truth:Transform3D:translation") == n
        assert samples(table, f"/world/{src}/setpoint:Points3D:positions") == n
        motors = table.column(f"/plots/motors/{src}:Scalars:scalars").drop_null().to_pylist()
        assert len(motors) == n and all(len(m) == 4 for m in motors), "four motors, every sample"
        assert samples(table, f"/plots/pos_err/{src}:Scalars:scalars") == n
        assert samples(table, f"/events/{src}:TextLog:text") >= 3, "the events and the synthesised mode changes"
    first = table.column("/world/v0/truth:Transform3D:translation").drop_null()[0].as_py()
    assert first == [[0.0, 0.0, 0.0]], first


def test_the_recording_gets_its_final_name_only_at_a_clean_end(tmp_path: Path) -> None:
    rrd = tmp_path / "y.rrd"
    tmp = tmp_path / "y.rrd.tmp"
    proc = bridge("--no-viewer", "--record", str(rrd))
    assert proc.stdin is not None and proc.stdout is not None
    assert proc.stdout.readline().strip() == f"ready {rrd}"
    for f in frames(["v0"], 1.0, RATE_HZ):
        proc.stdin.write(json.dumps(f) + "\n")
    proc.stdin.flush()
    assert tmp.exists() and not rrd.exists(), "written under .tmp while running"
    deadline = time.monotonic() + 30
    while tmp.stat().st_size < 20_000 and time.monotonic() < deadline:  # the frames are in (a pause flushes)
        time.sleep(0.1)
    assert not rrd.exists()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert rrd.exists() and not tmp.exists(), err
    assert samples(read_rrd(rrd), "/world/v0/truth:Transform3D:translation") > 0, "flushed before the rename"


def test_without_rerun_it_says_how_to_install_it(tmp_path: Path) -> None:
    (tmp_path / "rerun").mkdir()
    (tmp_path / "rerun" / "__init__.py").write_text("raise ImportError('no rerun here')\n")
    env = {**ENV, "PYTHONPATH": f"{tmp_path}{os.pathsep}{ENV['PYTHONPATH']}"}
    proc = subprocess.run(
        [sys.executable, "-m", "aco_gcs.view", "--no-viewer", "--record", str(tmp_path / "z.rrd")],
        input="",
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "pip install 'rerun-sdk[catalog]==0.41.0'" in proc.stderr


def test_a_ulog_becomes_frames_and_a_recording(tmp_path: Path) -> None:
    """Needs a ULog: $ACO_VIEW_ULOG, else one flown by `sitl run` (the binaries built by `cargo test`)."""
    from aco_gcs.view_ulog import ulog_frames

    path = os.environ.get("ACO_VIEW_ULOG")
    if path is None:
        from sitl_harness import start_sitl
        from test_ulog import fly, ulogs

        sitl = start_sitl(tmp_path, speed="10")
        try:
            fly(sitl)
        finally:
            sitl.stop()
        path = str(ulogs(tmp_path / "state")[0])
    fs = ulog_frames(path)
    vehicle = [f for f in fs if f["kind"] == "vehicle"]
    assert fs[0]["kind"] == "meta" and len(vehicle) > 100
    assert [f["t_us"] for f in fs[1:]] == sorted(f["t_us"] for f in fs[1:])
    assert {"Takeoff", "Hold", "Land"} <= {f["mode"] for f in vehicle}
    assert min(f["pos_ned_m"][2] for f in vehicle if f["pos_ned_m"]) < vehicle[0]["pos_ned_m"][2] - 1.5, "took off"
    assert any(f["pwm_us"] and f["pwm_us"][0] > 1300 for f in vehicle)
    assert any("aco.c_r_x" in f["telemetry"] for f in vehicle)
    assert any(f["kind"] == "event" for f in fs), "the logged messages"
    # One command: `sitl view FILE.ulg` (here recording, without a viewer).
    from sitl_harness import binary

    rrd = tmp_path / "u.rrd"
    proc = subprocess.run(
        [str(binary("sitl")), "view", path, "--view", "none", "--record", str(rrd)],
        capture_output=True,
        text=True,
        env=ENV,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    table = read_rrd(rrd)
    assert samples(table, "/world/v0/estimate:Transform3D:translation") == len(vehicle)
    assert not [c for c in table.column_names if "/truth" in c], "a flight log has no truth"
    assert samples(table, "/world/v0/setpoint:Points3D:positions") > 100


# The bridge with a SIGINT sent to itself from inside Rerun's exception-catching context at the 40th `rr.log`:
# where a real Ctrl-C lands when the bridge is busy logging.
SIGINT_INSIDE_RERUN = """
import os, signal, sys, time
import rerun
from rerun.error_utils import catch_and_log_exceptions
calls = 0
original = rerun.log
def log(*args, **kwargs):
    global calls
    calls += 1
    if calls == 40:
        with catch_and_log_exceptions("injected"):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
    return original(*args, **kwargs)
rerun.log = log
from aco_gcs.view import main
sys.exit(main())
"""


def test_a_ctrl_c_inside_a_rerun_call_stops_the_bridge_and_finalizes_the_recording(tmp_path: Path) -> None:
    """Rerun's logging calls turn any `Exception` raised inside them into a warning. CI once lost a Ctrl-C
    there: the bridge served on, was killed, and its .rrd stayed .tmp. The stream's writer stays open here
    (as `sitl` is until it stops), so the bridge ends only if it saw the signal."""
    rrd = tmp_path / "z.rrd"
    proc = subprocess.Popen(
        [sys.executable, "-c", SIGINT_INSIDE_RERUN, "--no-viewer", "--record", str(rrd)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    assert proc.stdin is not None and proc.stdout is not None and proc.stderr is not None
    try:
        assert proc.stdout.readline().startswith("ready ")
        for f in frames(["v0", "v1"], 2.0, RATE_HZ):
            proc.stdin.write(json.dumps(f) + "\n")
        proc.stdin.flush()
        assert proc.wait(timeout=60) == 0
    finally:
        proc.kill()
        proc.wait()
    err = proc.stderr.read()
    assert "SIGINT" in err and rrd.exists() and not rrd.with_name("z.rrd.tmp").exists(), err
    assert samples(read_rrd(rrd), "/world/v0/truth:Transform3D:translation") > 0, err
