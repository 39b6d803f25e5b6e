"""The SITL flown with pymavlink as a user scripts it: connect, wait for the estimator, take off to 1.5 m,
then judged on the plant's truth against the commanded point (home + 1.5 m): the autopilot runs with
`--estimator truth`, so LOCAL_POSITION_NED is the plant's truth. The climb overshoots by at most 0.03 m,
the 20 s hover that follows stays within 0.05 m of home + 1.5 m; then it lands and disarms by itself.
Twice: with `sitl run` (plant and autopilot over UDP), and with the plant and the autopilot on the two
ends of a socat pty pair (the serial plant link of the real airframe), paced at 20x real time. Every
wait is measured on the vehicle's clock (time_boot_ms), never on the wall clock; a wall-clock deadline
only stops a hung run."""

import math
import os
import random
import shutil
import subprocess
import time
from typing import Any

import pytest
from sitl_harness import binary, qgc_connection, stop_group

os.environ["MAVLINK20"] = "1"  # pymavlink speaks MAVLink 1 unless told otherwise
from pymavlink import mavutil

WALL_LIMIT_S = 120.0
MAV_SYS_STATUS_PREARM_CHECK = 0x10000000
MAV_LANDED_STATE_ON_GROUND = 1


class Gcs:
    """A pymavlink ground station where QGroundControl listens: UDP 14550, which every instance sends to
    (PX4's multi-vehicle convention), held by this test alone; it takes only instance N's system id, N+1."""

    def __init__(self, instance):
        self.conn = qgc_connection()
        self.autopilot = ("127.0.0.1", 18570 + instance)
        self.deadline = time.monotonic() + WALL_LIMIT_S
        self.now_ms = 0
        self.target_system = instance + 1
        # (n, e, d) m once a LOCAL_POSITION_NED came; None before.
        self.pos: Any = None
        self.vel: Any = None
        self.converged = False
        self.armed = False
        self.landed_state = None
        self.acks = {}
        self.home: Any = None  # HOME_POSITION local (x, y, z), and the vehicle time it came at
        self.home_ms = None

    def pump(self):
        assert time.monotonic() < self.deadline, "wall-clock limit reached: the SITL hung"
        msg = self.conn.recv_match(blocking=True, timeout=0.5)
        if msg is None or msg.get_srcSystem() != self.target_system:
            return
        kind = msg.get_type()
        if hasattr(msg, "time_boot_ms"):
            self.now_ms = max(self.now_ms, msg.time_boot_ms)
        if kind == "HEARTBEAT" and msg.get_srcComponent() == 1:
            self.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "SYS_STATUS":
            self.converged = bool(msg.onboard_control_sensors_health & MAV_SYS_STATUS_PREARM_CHECK)
        elif kind == "LOCAL_POSITION_NED":
            self.pos = (msg.x, msg.y, msg.z)
            self.vel = (msg.vx, msg.vy, msg.vz)
        elif kind == "EXTENDED_SYS_STATE":
            self.landed_state = msg.landed_state
        elif kind == "HOME_POSITION":
            self.home, self.home_ms = (msg.x, msg.y, msg.z), self.now_ms
        elif kind == "COMMAND_ACK":
            self.acks[msg.command] = msg.result

    def wait_until(self, vehicle_s, what, cond):
        # Read the vehicle's clock first: in fast lockstep it may be well past zero when this reader starts.
        while self.now_ms == 0:
            self.pump()
        start = self.now_ms
        while not cond():
            assert self.now_ms - start <= vehicle_s * 1000, f"{what}: not within {vehicle_s} s of vehicle time"
            self.pump()
        return (self.now_ms - start) / 1000.0

    def command(self, command, *params):
        values = [*params, *[0.0] * (7 - len(params))]
        self.acks.pop(command, None)
        # pymavlink answers the last sender; the autopilot listens on 18570+N, so address it explicitly.
        self.conn.port.sendto(
            self.conn.mav.command_long_encode(self.target_system, 1, command, 0, *values).pack(self.conn.mav),
            self.autopilot,
        )
        self.wait_until(5.0, f"ACK of command {command}", lambda: command in self.acks)
        return self.acks[command]


def log_file(tmp_path, name):
    """Where a child's standard error goes (kept with the test's temporary files, shown on failure)."""
    return open(tmp_path / f"{name}.log", "w")


def start_udp(instance, tmp_path):
    """`sitl run -i N`: the plant and the autopilot over UDP."""
    proc = subprocess.Popen(
        # Paced at 20x: unpaced lockstep sends about 11 000 messages per wall second, more than a pymavlink
        # reader keeps up with (its socket drops datagrams, an ACK among them).
        [
            str(binary("sitl")),
            "run",
            "-i",
            str(instance),
            "--estimator",
            "truth",
            "--speed",
            "20",
            "--state-dir",
            str(tmp_path / "state"),
        ],
        stdout=subprocess.DEVNULL,
        stderr=log_file(tmp_path, "sitl-run"),
        start_new_session=True,
    )
    return [proc]


def start_serial(instance, tmp_path):
    """The plant (`sitl serve --serial`) and the autopilot (`--plant serial:`) on the two ends of a socat
    pty pair, as the autopilot attaches to the airframe's ARM board; the ground station still on UDP."""
    socat = shutil.which("socat")
    if socat is None:
        pytest.fail("socat is not installed (scripts/test installs it: apt-get install socat)")
    plant_tty, autopilot_tty = tmp_path / "plant-tty", tmp_path / "autopilot-tty"
    pty = subprocess.Popen(
        [socat, f"pty,raw,echo=0,link={plant_tty}", f"pty,raw,echo=0,link={autopilot_tty}"],
        stderr=log_file(tmp_path, "socat"),
        start_new_session=True,
    )
    deadline = time.monotonic() + 10
    while not (plant_tty.exists() and autopilot_tty.exists()):
        assert time.monotonic() < deadline and pty.poll() is None, "socat made no pty pair"
        time.sleep(0.05)
    plant = subprocess.Popen(
        # --truth: the autopilot flies on the plant's truth here, which a serial link carries only when asked.
        [
            str(binary("sitl")),
            "serve",
            "--serial",
            f"{plant_tty}:921600",
            "--truth",
            "-i",
            str(instance),
            "--speed",
            "20",
        ],
        stdout=subprocess.DEVNULL,
        stderr=log_file(tmp_path, "sitl-serve"),
        start_new_session=True,
    )
    autopilot = subprocess.Popen(
        [
            str(binary("autopilot")),
            "--plant",
            f"serial:{autopilot_tty}:921600",
            "-i",
            str(instance),
            "--state-dir",
            str(tmp_path / "state"),
            "--estimator",
            "truth",
            "--stop-on-stdin-eof",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=log_file(tmp_path, "autopilot"),
        start_new_session=True,
    )
    return [autopilot, plant, pty]


@pytest.fixture(params=["udp", "serial"])
def sitl(request, tmp_path):
    instance = random.randint(20, 60)
    procs = {"udp": start_udp, "serial": start_serial}[request.param](instance, tmp_path)
    try:
        yield instance
    finally:
        for proc in procs:
            stop_group(proc)


@pytest.fixture
def gcs(sitl):
    """The ground station on 14550, closed after the test: it holds the port alone."""
    g = Gcs(sitl)
    try:
        yield g
    finally:
        g.conn.close()


def test_pymavlink_takes_off_holds_and_lands(sitl, gcs):
    hb = None
    end = time.monotonic() + 30
    while hb is None and time.monotonic() < end:
        msg = gcs.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
        if msg is not None and msg.get_srcSystem() == sitl + 1 and msg.get_srcComponent() == 1:
            hb = msg
            gcs.conn.target_system = sitl + 1
    assert hb is not None, "no HEARTBEAT from the autopilot on 14550"
    assert hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4 and hb.type == mavutil.mavlink.MAV_TYPE_QUADROTOR
    gcs.target_system = gcs.conn.target_system
    assert gcs.target_system == sitl + 1, "instance N is system N+1"
    assert "LOITER" in gcs.conn.mode_mapping(), "pymavlink sees PX4 modes"

    converge_s = gcs.wait_until(30.0, "estimator convergence", lambda: gcs.converged and gcs.pos is not None)
    accepted = mavutil.mavlink.MAV_RESULT_ACCEPTED
    nan = float("nan")
    assert gcs.command(mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, 1.5) == accepted
    assert gcs.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == accepted
    gcs.wait_until(2.0, "armed HEARTBEAT", lambda: gcs.armed)
    armed_ms = gcs.now_ms

    # The takeoff is 1.5 m above home, which the vehicle sets where it arms (HOME_POSITION follows): not
    # where this reader saw it converge, which in fast lockstep can be many vehicle seconds earlier.
    gcs.wait_until(2.0, "HOME_POSITION after arming", lambda: gcs.home_ms is not None and gcs.home_ms >= armed_ms)
    hover = (gcs.home[0], gcs.home[1], gcs.home[2] - 1.5)
    # The climb, and then 20 s of hover, all against home + 1.5 m: the highest point of the climb is the
    # overshoot, and the hover window starts when the vehicle is first within 5 cm of the point.
    top = [gcs.pos[2]]

    def climbed():
        top[0] = min(top[0], gcs.pos[2])
        return abs(gcs.pos[2] - hover[2]) < 0.05

    climb_s = gcs.wait_until(15.0, "climb to within 5 cm of home + 1.5 m", climbed)
    worst = 0.0
    end = gcs.now_ms + 20_000
    while gcs.now_ms < end:
        gcs.pump()
        top[0] = min(top[0], gcs.pos[2])
        worst = max(worst, math.dist(gcs.pos, hover))
    overshoot = hover[2] - top[0]
    assert gcs.armed, "disarmed during the hover"
    assert overshoot <= 0.03, f"takeoff overshoot {overshoot:.3f} m > 0.03 m"
    assert worst <= 0.05, f"hover error {worst:.3f} m > 0.05 m (truth against home + 1.5 m)"

    assert gcs.command(mavutil.mavlink.MAV_CMD_NAV_LAND) == accepted
    land_s = gcs.wait_until(
        30.0, "landed and disarmed", lambda: gcs.landed_state == MAV_LANDED_STATE_ON_GROUND and not gcs.armed
    )
    print(
        f"converge {converge_s:.1f} s, climb {climb_s:.1f} s, overshoot {overshoot:.3f} m, "
        f"hover error max {worst:.3f} m (truth), land {land_s:.1f} s (vehicle time)"
    )
