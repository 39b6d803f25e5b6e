"""What the ground-station tests share: the binaries `cargo test` built, a free SITL instance (or a free
run of them for a swarm), starting `sitl run` (its own state directory and log) and stopping its whole
process group, and the QGroundControl port 14550 held by one test at a time."""

import asyncio
import os
import random
import signal
import socket
import subprocess
import time
import warnings
from pathlib import Path

import pytest

from aco_gcs.link import AUTOPILOT_PORT, GCS_COMPONENT, GCS_SYSTEM, QGC_PORT, Vehicle, api_port, mavutil

ROOT = Path(__file__).resolve().parents[2]


def binary(name):
    """The `name` binary of the workspace (the test profile's, else release)."""
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for profile in (os.environ.get("SITL_PROFILE", "debug"), "release"):
        path = target / profile / name
        if path.exists():
            return path
    pytest.fail(f"{name} is not built: run `cargo build -p sitl -p autopilot` first")


def ports_free(n):
    """Whether every port of instance n is free on 127.0.0.1 (UDP plant, autopilot, API, SIM_; TCP)."""
    for kind, port in [(socket.SOCK_DGRAM, p) for p in (4560 + n, 18570 + n, api_port(n), 19550 + n)] + [
        (socket.SOCK_STREAM, 5760 + n)
    ]:
        s = socket.socket(socket.AF_INET, kind)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
        finally:
            s.close()
    return True


def free_instance(low=61, high=99, count=1):
    """A random instance n in low..=high whose ports are all free, and those of the `count` - 1 instances
    after it (a swarm of `count` from n stays within low..=high)."""
    for _ in range(100):
        n = random.randint(low, high - count + 1)
        if all(ports_free(k) for k in range(n, n + count)):
            return n
    pytest.fail(f"no free run of {count} SITL instance(s) in {low}..={high}")


def qgc_connection(wait_s=120.0):
    """A pymavlink ground station on UDP 127.0.0.1:14550, where QGroundControl listens and every instance
    sends its telemetry, holding the port alone: bound without SO_REUSEADDR, so a second ground station
    (another test of a concurrent run, QGroundControl) cannot share it and silently take datagrams from it.
    Waits up to `wait_s` wall seconds for the port while someone else holds it."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    # Eight vehicles' telemetry while Python is busy elsewhere: room for a few seconds of it.
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    deadline = time.monotonic() + wait_s
    while True:
        try:
            sock.bind(("127.0.0.1", QGC_PORT))
            break
        except OSError as e:
            if time.monotonic() > deadline:
                sock.close()
                pytest.fail(f"udp {QGC_PORT} stayed taken for {wait_s:.0f} s (QGroundControl or another test?): {e}")
            time.sleep(0.5)
    # pymavlink's udpin binds with SO_REUSEADDR; it gets a throwaway port and then this socket in its place.
    conn = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=GCS_SYSTEM, source_component=GCS_COMPONENT)
    conn.port.close()
    sock.setblocking(False)
    conn.port, conn.fd = sock, sock.fileno()
    return conn


def stop_group(proc, timeout=10):
    """SIGINT to the process group (every process closes its logs), SIGKILL if that is not enough."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


class Sitl:
    """A running `sitl run -i N`."""

    def __init__(self, instance, log_dir, proc, log_path):
        self.instance, self.log_dir, self.proc, self.log_path = instance, log_dir, proc, log_path

    def stop(self):
        stop_group(self.proc)

    def tlogs(self):
        return sorted(self.log_dir.glob("*.tlog"))

    def log_tail(self, chars=3000):
        return self.log_path.read_text()[-chars:]


def start_sitl(tmp_path, *extra, speed, instance=None):
    """`sitl run --speed SPEED` on a free instance with its own state directory (what a test sets must not
    outlive it) and `.tlog` directory under `tmp_path`, its standard error in `tmp_path/sitl-run.log`.
    Every test says its speed: `sitl run` alone paces at real time, "max" is lockstep as fast as possible."""
    n = instance if instance is not None else free_instance()
    log_dir = tmp_path / "logs"
    log_dir.mkdir(exist_ok=True)
    log_path = tmp_path / "sitl-run.log"
    # The child keeps its own copy of the file descriptor; this process closes its one at once.
    with open(log_path, "w") as stderr:
        proc = subprocess.Popen(
            [
                str(binary("sitl")),
                "run",
                "-i",
                str(n),
                "--speed",
                str(speed),
                "--log-dir",
                str(log_dir),
                "--state-dir",
                str(tmp_path / "state"),
                *extra,
            ],
            stdout=subprocess.DEVNULL,
            stderr=stderr,
            start_new_session=True,
        )
    return Sitl(n, log_dir, proc, log_path)


def connect(sitl, wall_limit_s=240.0):
    """A pymavlink link to the vehicle of `sitl`, as a script connects: listening on the instance's API port,
    sending to its autopilot's port; returned once its HEARTBEAT and timed telemetry have come."""
    vehicle = Vehicle(
        f"udpin:127.0.0.1:{api_port(sitl.instance)}", f"127.0.0.1:{AUTOPILOT_PORT + sitl.instance}", wall_limit_s
    )
    vehicle.wait_heartbeat(30.0, sitl.instance)
    return vehicle


async def first(stream, cond=lambda _: True, what="telemetry", timeout_s=120.0):
    """The first item of a MAVSDK stream for which `cond` holds (a wall-clock hang guard only)."""

    async def scan():
        async for item in stream:
            if cond(item):
                return item

    try:
        return await asyncio.wait_for(scan(), timeout_s)
    except TimeoutError:
        pytest.fail(f"MAVSDK: {what} not within {timeout_s:g} s of wall time")


def mavsdk_module(name):
    """A module of the mavsdk package (`mavsdk`, `mavsdk.offboard`), its 4.x rename warning silenced:
    mavsdk 3.17.4 warns that the name moves to a new binding in 4.x; requirements.txt pins `mavsdk<4`."""
    import importlib

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="The 'mavsdk' package has been renamed", category=FutureWarning)
        return importlib.import_module(name)


async def mavsdk_ready(instance):
    """A MAVSDK System on the instance's API port, once connected and healthy (global position, home,
    armable), with its own mavsdk_server on a random port so several tests run at once."""
    drone = mavsdk_module("mavsdk").System(port=random.randint(50100, 50900))
    await drone.connect(system_address=f"udpin://0.0.0.0:{api_port(instance)}")
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection")
    await first(
        drone.telemetry.health(),
        lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
        "health (global position, home, armable)",
    )
    return drone


def assert_generated_doc(generator, doc, tmp_path):
    """Runs `scripts/GENERATOR SITL OUT` and requires its stdout to be `docs/DOC` byte for byte: a hand edit, a
    stale table or a changed generator fails, naming the first lines that differ."""
    run = subprocess.run(
        [str(ROOT / "scripts" / generator), str(binary("sitl")), str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    committed = (ROOT / "docs" / doc).read_text()
    generated = run.stdout
    if generated != committed:
        diff = [
            f"line {i + 1}:\n  docs:      {a[:300]}\n  generated: {b[:300]}"
            for i, (a, b) in enumerate(zip(committed.splitlines(), generated.splitlines(), strict=False))
            if a != b
        ]
        raise AssertionError(
            f"docs/{doc} is stale or was edited by hand (regenerate it with scripts/reproduce):\n"
            + "\n".join(diff[:10])
            + (f"\n({len(committed.splitlines())} lines in docs, {len(generated.splitlines())} generated)")
        )
