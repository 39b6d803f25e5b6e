"""The onboard ULog flight log, read as PX4's users read it: a flight through `sitl run` (take off to 2 m,
hold, land; paced at 10x real time) leaves exactly one `.ulg` under the state directory's
`log/<date>/`, which pyulog parses (its library, and its `ulog_info` and `ulog2csv` commands), with the
format version and flag bits PX4 writes, the parameters, the topics of the estimator, the setpoints, the
controller (the ACO weights included), the motors, the battery and the vehicle status, and the mode changes
as logged messages; `aco-ulog-plot` draws it. A flight cut short by SIGTERM in the air is finalized all the same;
nothing is written with `--no-ulog`."""

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sitl_harness import connect, start_sitl

from aco_gcs.flight import land, takeoff, wait_ready

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
TOPICS = [
    "vehicle_status",
    "vehicle_attitude",
    "vehicle_local_position",
    "vehicle_local_position_setpoint",
    "vehicle_attitude_setpoint",
    "actuator_outputs",
    "controller_status",
    "estimator_innovations",
    "battery_status",
    "aco_weights",
]
TAKEOFF_M = 2.0


def fly(sitl):
    """Arm, take off to TAKEOFF_M, hold 5 s, land and wait for the auto-disarm; returns the vehicle."""
    vehicle = connect(sitl)
    ground, _ = wait_ready(vehicle)
    takeoff(vehicle, TAKEOFF_M, ground)
    end = vehicle.now_s() + 5.0
    vehicle.wait_until(6.0, "a 5 s hold", lambda: vehicle.now_s() >= end)
    land(vehicle)
    return vehicle


def pid_alive(pid):
    """Whether process `pid` still runs (a zombie counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def ulogs(state):
    return sorted((state / "log").glob("*/*.ulg"))


def tool(name):
    """A pyulog command of the venv running the tests."""
    return str(Path(sys.executable).with_name(name))


@pytest.fixture
def flown(tmp_path):
    sitl = start_sitl(tmp_path, speed="10")
    try:
        fly(sitl)
    finally:
        sitl.stop()
        print(sitl.log_tail())
    return tmp_path


def test_a_flight_leaves_one_ulog_that_pyulog_reads_with_px4s_topics(flown):
    from pyulog import ULog

    files = ulogs(flown / "state")
    assert len(files) == 1, files
    path = files[0]
    assert path.parent.name.count("-") == 2 and len(path.parent.name) == 10, "log/<YYYY-MM-DD>/"
    assert not list((flown / "state" / "log").glob("*/*.tmp")), "finalized"
    raw = path.read_bytes()
    assert raw[:8] == b"ULog\x01\x12\x35\x01", "magic and file version 1"
    assert raw[16:19] == bytes([40, 0, ord("B")]) and raw[19] == 1, "flag bits first, DEFAULT_PARAMETERS set"

    log = ULog(str(path))
    assert log.has_default_parameters and not log.has_data_appended and not log.file_corruption
    assert log.msg_info_dict["sys_name"] == "ACO autopilot"
    assert log.msg_info_dict["controller"] == "aco"
    params = log.initial_parameters
    assert params["SDLOG_MODE"] == 0 and isinstance(params["SDLOG_MODE"], int)
    assert isinstance(params["MPC_XY_CRUISE"], float)
    assert len(params) >= 80, len(params)
    data = {d.name: d.data for d in log.data_list}
    missing = [t for t in TOPICS if t not in data]
    assert not missing, f"missing topics {missing}; have {sorted(data)}"
    duration_s = (log.last_timestamp - log.start_timestamp) / 1e6
    assert duration_s > 8, duration_s

    pos = data["vehicle_local_position"]
    ground_z = pos["z"][0]
    top_m = ground_z - min(pos["z"])
    assert abs(top_m - TAKEOFF_M) < 0.15, f"highest point {top_m:.2f} m above the ground, commanded {TAKEOFF_M} m"
    rate_hz = len(pos["timestamp"]) / duration_s
    assert 45 < rate_hz < 55, rate_hz
    sp = data["vehicle_local_position_setpoint"]
    assert abs((ground_z - min(z for z in sp["z"] if z == z)) - TAKEOFF_M) < 0.1, "the setpoint climbs to 2 m"
    status = data["vehicle_status"]
    assert status["arming_state"][0] == 2 and status["arming_state"][-1] == 1, "armed, then disarmed at the end"
    assert {17, 4, 18} <= set(status["nav_state"]), f"takeoff, hold, land: {set(status['nav_state'])}"
    out = data["actuator_outputs"]
    assert out["noutputs"][0] == 4
    assert max(out["output[0]"]) > 1300 and all(1000 <= v <= 2000 for v in out["output[0]"])
    w = data["aco_weights"]
    assert len(w["timestamp"]) > 50 and any(abs(v) > 1e-6 for v in w["c_r[0]"]), "the weights adapt in flight"
    bat = data["battery_status"]
    assert all(bat["connected"]) and 18 < bat["voltage_v"][0] < 25.5, "the plant's 6S pack"
    assert "gps_hpos[0]" in data["estimator_innovations"]
    texts = [m.message for m in log.logged_messages]
    assert texts[0] == "Armed", texts
    # Takeoff mode was set before arming, so the flight starts in it (vehicle_status says so).
    for want in ("Takeoff complete", "Mode: Hold", "Mode: Land", "Disarmed after landing"):
        assert any(want in t for t in texts), f"{want!r} not in {texts}"

    size = path.stat().st_size
    print(
        f"{path.name}: {size} bytes over {duration_s:.1f} s of flight, {size / duration_s * 60 / 1e6:.2f} MB per minute"
    )

    info = subprocess.run([tool("ulog_info"), str(path)], capture_output=True, text=True, timeout=60)
    assert info.returncode == 0, info.stderr
    assert "vehicle_local_position" in info.stdout and "aco_weights" in info.stdout, info.stdout
    csv_dir = flown / "csv"
    csv_dir.mkdir()
    conv = subprocess.run([tool("ulog2csv"), "-o", str(csv_dir), str(path)], capture_output=True, text=True, timeout=60)
    assert conv.returncode == 0, conv.stderr
    csvs = sorted(p.name for p in csv_dir.glob("*.csv"))
    assert any(n.endswith("_vehicle_local_position_0.csv") for n in csvs), csvs
    header = next(csv_dir.glob("*_aco_weights_0.csv")).read_text().splitlines()[0]
    assert header.startswith("timestamp,") and "w_t[0]" in header, header

    png = flown / "flight.png"
    plot = subprocess.run(
        [sys.executable, "-m", "aco_gcs.ulog_plot", str(path), "--png", str(png)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert plot.returncode == 0, plot.stderr
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_a_flight_stopped_in_the_air_by_sigterm_is_still_finalized(tmp_path):
    sitl = start_sitl(tmp_path, speed="10")
    try:
        vehicle = connect(sitl)
        ground, _ = wait_ready(vehicle)
        takeoff(vehicle, 1.0, ground)
        assert vehicle.armed
        found = re.search(r"autopilot pid (\d+)", sitl.log_path.read_text())
        assert found is not None, "sitl run's banner names the autopilot's pid"
        autopilot_pid = int(found.group(1))
        # SIGTERM to the group: `sitl` dies at once (it has no handler), the autopilot finalizes its log.
        os.killpg(sitl.proc.pid, signal.SIGTERM)
        sitl.proc.wait(timeout=20)
        deadline = time.monotonic() + 20
        while pid_alive(autopilot_pid):
            assert time.monotonic() < deadline, "the autopilot did not stop on SIGTERM"
            time.sleep(0.05)
    finally:
        sitl.stop()
    print(sitl.log_tail())
    files = ulogs(tmp_path / "state")
    assert len(files) == 1 and not list((tmp_path / "state" / "log").glob("*/*.tmp")), list(
        (tmp_path / "state").rglob("*")
    )
    from pyulog import ULog

    status = ULog(str(files[0]), message_name_filter_list=["vehicle_status"]).data_list[0].data
    assert all(a == 2 for a in status["arming_state"]), "it ended armed, in the air"


def test_no_ulog_writes_no_flight_log(tmp_path):
    sitl = start_sitl(tmp_path, "--no-ulog", speed="10")
    try:
        vehicle = connect(sitl)
        ground, _ = wait_ready(vehicle)
        takeoff(vehicle, 1.0, ground)
    finally:
        sitl.stop()
    assert ulogs(tmp_path / "state") == []
    assert not (tmp_path / "state" / "log").exists()


def test_ulog_plot_exits_2_on_a_file_that_is_not_a_ulog(tmp_path):
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"not a ulog at all")
    for path in (bad, tmp_path / "missing.ulg"):
        run = subprocess.run(
            [sys.executable, "-m", "aco_gcs.ulog_plot", str(path)],
            capture_output=True,
            text=True,
            timeout=60,
            cwd=Path(__file__).resolve().parents[1],
        )
        assert run.returncode == 2, run.stderr
        assert "aco-ulog-plot: error:" in run.stderr
