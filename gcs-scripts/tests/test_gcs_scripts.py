"""Every ground-station script run as a user runs it: a subprocess against the real binaries (`sitl run
-i N` on a random free instance, paced at 20x (`--speed 20`) so that a Python reader keeps up, except the
MAVSDK offboard flight which needs real time, `--speed 1`),
checking exit codes and outputs; plus `--help`, the exit code 2 with a clear message when no vehicle is
there, and the package's console entry points."""

import importlib
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest
from sitl_harness import free_instance, start_sitl

from aco_gcs import link

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "gcs-scripts"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SCRIPTS = [
    "takeoff_hover_land",
    "figure8_mission",
    "offboard_square",
    "gust_hover",
    "params",
    "tlog_plot",
    "ulog_plot",
    "sweep",
    "sticks",
    "view",
]
# Wall-clock limits of a script run (a hang guard: the scripts' own waits are on vehicle time).
FLIGHT_WALL_S = 300


def script_env():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(PACKAGE), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["MPLBACKEND"] = "Agg"
    return env


def run_script(name, *args, timeout=FLIGHT_WALL_S, cwd=None):
    """`python -m aco_gcs.<name> args...` in its own process group (so a hung run takes its children, such
    as MAVSDK's mavsdk_server, with it): (exit code, stdout, stderr)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", f"aco_gcs.{name}", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=script_env(),
        cwd=cwd,
        start_new_session=True,
    )
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        print(f"--- {name}: killed after {timeout} s\n{out}{err}")
        pytest.fail(f"{name} did not finish within {timeout} s of wall time")
    print(f"--- {name} {' '.join(map(str, args))}: exit {proc.returncode}\n{out}{err}")
    return proc.returncode, out, err


@pytest.fixture
def sitl(tmp_path):
    """Paced at 20x (`--speed 20`). Unpaced (`--speed max`), the vehicle sends about 11 000 messages per wall
    second on a fast machine, more than a pymavlink script sharing two cores with the two polling SITL
    processes parses: it then misses events (MISSION_ITEM_REACHED) or reads an ACK more than its 5 s of
    vehicle time late.
    The client tests (test_clients.py) run unpaced (`--speed max`)."""
    s = start_sitl(tmp_path, speed="20")
    try:
        yield s
    finally:
        s.stop()
        print(s.log_tail())


@pytest.fixture
def sitl_realtime(tmp_path):
    s = start_sitl(tmp_path, speed="1")
    try:
        yield s
    finally:
        s.stop()
        print(s.log_tail())


def is_png(path):
    return path.exists() and path.read_bytes()[:8] == PNG_MAGIC


# -- without a vehicle ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SCRIPTS)
def test_every_script_has_help(name):
    code, out, _ = run_script(name, "--help", timeout=60)
    assert code == 0
    assert out.startswith("usage: aco-") and "--help" in out


def test_every_console_entry_point_names_a_main_function():
    project = tomllib.loads((PACKAGE / "pyproject.toml").read_text())["project"]
    assert project["name"] == "aco-gcs-scripts"
    scripts = project["scripts"]
    assert sorted(target.split(":")[0].split(".")[1] for target in scripts.values()) == sorted(SCRIPTS)
    for command, target in scripts.items():
        module, function = target.split(":")
        assert command == "aco-" + module.split(".")[1].replace("_", "-")
        assert callable(getattr(importlib.import_module(module), function)), target


@pytest.mark.parametrize(
    "name, args",
    [
        ("takeoff_hover_land", []),
        ("figure8_mission", []),
        ("gust_hover", []),
        ("params", ["get", "MIS_TAKEOFF_ALT"]),
        ("params", ["--plant", "get", "SIM_GUST_SPD"]),
    ],
)
def test_pymavlink_scripts_exit_2_without_a_vehicle(name, args, tmp_path):
    n = free_instance(200, 254)
    started = time.monotonic()
    code, _, err = run_script(name, "--instance", n, "--heartbeat-timeout", 2, *args, timeout=60, cwd=tmp_path)
    assert code == 2, err
    assert "no vehicle HEARTBEAT" in err or "no plant HEARTBEAT" in err, err
    assert str(link.api_port(n)) in err or str(19550 + n) in err, "the message names the port it listened on"
    assert time.monotonic() - started < 30


def test_offboard_square_exits_2_without_a_vehicle(tmp_path):
    n = free_instance(200, 254)
    code, _, err = run_script("offboard_square", "--instance", n, "--heartbeat-timeout", 5, timeout=90, cwd=tmp_path)
    assert code == 2, err
    assert f"no vehicle HEARTBEAT on udpin://0.0.0.0:{link.api_port(n)}" in err, err


def test_tlog_plot_exits_2_on_a_log_without_a_vehicle(tmp_path):
    empty = tmp_path / "empty.tlog"
    empty.write_bytes(b"")
    code, _, err = run_script("tlog_plot", empty, timeout=60)
    assert code == 2 and "no vehicle HEARTBEAT" in err, err
    code, _, err = run_script("tlog_plot", tmp_path / "missing.tlog", timeout=60)
    assert code == 2 and "no such file" in err, err


# -- flights against `sitl run` ---------------------------------------------------------------------


def wait_vehicle_time(instance, seconds, wall_s=60):
    """Listen on the API port (14540 + N) until the vehicle's time_boot_ms passes `seconds`."""
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{link.api_port(instance)}")
    try:
        end = time.monotonic() + wall_s
        while time.monotonic() < end:
            msg = conn.recv_match(type="ATTITUDE", blocking=True, timeout=1)
            if msg is not None and msg.time_boot_ms > seconds * 1000:
                return
        pytest.fail(f"vehicle time did not pass {seconds} s within {wall_s} s of wall time")
    finally:
        conn.close()


def test_takeoff_hover_land_joining_a_vehicle_up_for_a_minute_holds_the_truth_within_0_10_m_then_tlog_plot(
    sitl, tmp_path
):
    # A script started against a SITL that has run for a while: its 30 s waits start from the vehicle's
    # clock as it is then, not from zero. Graded on the plant's truth from its SIM_ port (SIM_STATE)
    # against the commanded point: the true ground point before the takeoff + 1.5 m up.
    wait_vehicle_time(sitl.instance, 60)
    code, out, err = run_script("takeoff_hover_land", "--instance", sitl.instance, "--hold", 10, "--truth")
    assert code == 0, err
    assert "hover error over 10 s: max" in out and "landed and disarmed" in out
    assert f"truth from udpout:127.0.0.1:{19550 + sitl.instance}" in out, out
    truth_line = next(line for line in out.splitlines() if line.startswith("truth hover error over 10 s: max"))
    truth_err_m = float(truth_line.split("max ")[1].split(" m")[0])
    samples = int(truth_line.split("(")[1].split(" samples")[0])
    assert truth_err_m <= 0.10, truth_line
    assert samples >= 450, f"50 Hz of plant time over the 10 s hold: {truth_line}"
    sitl.stop()  # the autopilot closes its .tlog
    tlogs = sitl.tlogs()
    assert len(tlogs) == 1, list(sitl.log_dir.iterdir())
    code, out, err = run_script("tlog_plot", tlogs[0], "--list", timeout=120)
    assert code == 0, err
    assert "LOCAL_POSITION_NED" in out and "ATTITUDE" in out and "HEARTBEAT" in out
    png = tmp_path / "track.png"
    code, out, err = run_script("tlog_plot", tlogs[0], "--png", png, timeout=120)
    assert code == 0, err
    assert is_png(png), out
    assert "positions and" in out


def test_figure8_mission_flies_every_waypoint_and_plots_the_track(sitl, tmp_path):
    png, csv = tmp_path / "f8.png", tmp_path / "f8.csv"
    code, out, err = run_script("figure8_mission", "--instance", sitl.instance, "--png", png, "--csv", csv)
    assert code == 0, err
    assert "downloaded 12 items: identical" in out
    assert "items reached:" in out
    assert is_png(png)
    rows = csv.read_text().splitlines()
    assert rows[0] == "t_s,north_m,east_m,down_m,mission_seq" and len(rows) > 100


def test_gust_hover_blows_a_beaufort_4_gust_through_the_plant(sitl, tmp_path):
    png, csv = tmp_path / "gust.png", tmp_path / "gust.csv"
    code, out, err = run_script("gust_hover", "--instance", sitl.instance, "--png", png, "--csv", csv)
    assert code == 0, err
    assert "gust on at t=" in out and "gust released at t=" in out
    peak = float(out.split("peak horizontal error ")[1].split(" m")[0])
    assert 0.02 < peak < 1.0, f"a 6.7 m/s gust moves the vehicle, and it holds on: peak {peak} m"
    assert "from release" in out
    assert is_png(png)
    rows = csv.read_text().splitlines()
    assert rows[0].startswith("t_s,err_xy_m") and any(r.endswith(",1") for r in rows[1:])


def test_params_dump_load_get_set(sitl, tmp_path):
    n = sitl.instance
    dump = tmp_path / "params.txt"
    code, out, err = run_script("params", "--instance", n, "dump", dump)
    assert code == 0, err
    lines = [line for line in dump.read_text().splitlines() if line and not line.startswith("#")]
    assert len(lines) > 50, lines
    names = {line.split()[0] for line in lines}
    assert {"MIS_TAKEOFF_ALT", "NAV_ACC_RAD"} <= names
    code, out, err = run_script("params", "--instance", n, "load", dump)
    assert code == 0, out + err
    assert f"{len(lines)} of {len(lines)} parameters set, 0 refused" in out

    code, out, err = run_script("params", "--instance", n, "set", "MIS_TAKEOFF_ALT", 3.25)
    assert code == 0, out + err
    code, out, err = run_script("params", "--instance", n, "get", "MIS_TAKEOFF_ALT")
    assert code == 0 and out.strip() == "MIS_TAKEOFF_ALT 3.25", out + err
    code, out, err = run_script("params", "--instance", n, "set", "MIS_TAKEOFF_ALT", 1e6)
    assert code == 1 and "refused: MIS_TAKEOFF_ALT" in out, out + err
    code, out, err = run_script("params", "--instance", n, "get", "NO_SUCH_PARAM")
    # The vehicle's own reason, at once, not a time-out's guess.
    assert code == 1 and "NO_SUCH_PARAM: unknown parameter NO_SUCH_PARAM" in out + err, out + err
    bad = tmp_path / "bad.txt"
    bad.write_text("MIS_TAKEOFF_ALT 2.5\nNAV_ACC_RAD -5\n")
    code, out, err = run_script("params", "--instance", n, "load", bad)
    assert code == 1 and "1 of 2 parameters set, 1 refused" in out and "refused: NAV_ACC_RAD" in out, out + err


def test_params_talk_to_the_plant_sim_parameters(sitl, tmp_path):
    n = sitl.instance
    code, out, err = run_script("params", "--instance", n, "--plant", "dump", "-")
    assert code == 0, err
    lines = [line for line in out.splitlines() if line.startswith("SIM_")]
    assert [line.split()[0] for line in lines] == [
        "SIM_WIND_N",
        "SIM_WIND_E",
        "SIM_WIND_D",
        "SIM_GUST_SPD",
        "SIM_GUST_DIR",
        "SIM_GUST_RISE",
        "SIM_GUST_ON",
        "SIM_TURB",
        "SIM_BEAUFORT",
        "SIM_BAT_DRAIN",
        "SIM_BAT_MIN_PCT",
        "SIM_RC_FAIL",
        "SIM_GPS_FAIL",
        "SIM_BARO_FAIL",
        "SIM_MAG_FAIL",
        "SIM_ACC_FAIL",
        "SIM_GYRO_FAIL",
        "SIM_GPS_JUMP_N",
        "SIM_GPS_JUMP_E",
        "SIM_BAT_FAIL",
        "SIM_MOT_WRNG_EFF",
        "SIM_LINK_DELAY",
        "SIM_LINK_LOSS",
        "SIM_MOT1_EFF",
        "SIM_MOT2_EFF",
        "SIM_MOT3_EFF",
        "SIM_MOT4_EFF",
        "SIM_PAYLOAD_KG",
        "SIM_CG_OFS_X",
        "SIM_CG_OFS_Y",
    ]
    code, out, err = run_script("params", "--instance", n, "--plant", "set", "SIM_BEAUFORT", 6)
    assert code == 0, out + err
    code, out, err = run_script("params", "--instance", n, "--plant", "get", "SIM_GUST_SPD")
    assert code == 0 and out.strip() == "SIM_GUST_SPD 12.3", out + err
    code, out, err = run_script("params", "--instance", n, "--plant", "set", "SIM_GUST_SPD", 40)
    # The autopilot's refusal wording: both tables are served by the same parameter service.
    assert code == 1 and "SIM_GUST_SPD: 40 not in 0..30" in out, out + err


def test_offboard_square_with_mavsdk_at_real_time(sitl_realtime, tmp_path):
    code, out, err = run_script("offboard_square", "--instance", sitl_realtime.instance, timeout=FLIGHT_WALL_S)
    assert code == 0, err
    for k in range(1, 5):
        assert f"corner {k}" in out
    assert "landed and disarmed" in out
