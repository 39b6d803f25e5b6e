"""Flying by hand through `sitl run`, as the field's ground stations do it: MAVSDK's ManualControl plugin
(its own example's order: the sticks streaming before `start_position_control`, arm, Position mode, climb
with the throttle stick, forward and back with the pitch stick, land with the throttle low), `aco-sticks
--script` and `aco-sticks --keyboard` (on a pseudo-terminal) as a user runs them, and the refusals: a
manual mode (Acro included) or arming without manual control, and the failsafe when the sticks stop in the air.
The autopilot runs with `--estimator truth`, so LOCAL_POSITION_NED is the plant's truth: every flight is
judged on where the vehicle really was.

Paced, because the vehicle loses the sticks after COM_RC_LOSS_T = 0.5 s of its own time and a client
stalled that long on a loaded machine lets them lapse: MAVSDK at real time (it streams on the wall clock,
every 50 ms here), aco-sticks at 2x (it streams on the vehicle's clock, but a reader stalled for 0.25 wall
seconds still falls 0.5 s behind), the loss timing at real time (a reader's backlog is counted in the
0.1 s it is held to, at 1x a few milliseconds), the refusals on the ground at 4x. Every wait is on the
vehicle's clock; a wall-clock limit only stops a hung run."""

import asyncio
import contextlib
import math
import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from sitl_harness import connect, mavsdk_ready, start_sitl

from aco_gcs import link
from aco_gcs.flight import wait_ready
from aco_gcs.link import PX4_MAIN_AUTO, Params, mavlink
from aco_gcs.sticks import CENTRED, PX4_MAIN_POSCTL, PilotVehicle, Sticks

ROOT = Path(__file__).resolve().parents[2]
PX4_MAIN_ACRO = 5
PX4_AUTO_RTL = 5
ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND


@pytest.fixture
def run_sitl(tmp_path):
    """Starts `sitl run --estimator truth` at a speed; stops it at the end."""
    running: list = []

    def start(speed):
        s = start_sitl(tmp_path, "--estimator", "truth", speed=speed)
        running.append(s)
        return s

    yield start
    for s in running:
        s.stop()
    if running:
        print(running[-1].log_tail())


def said(vehicle, text):
    """The vehicle times (s) at which STATUSTEXT `text` arrived."""
    return [t for (t, _, got) in vehicle.statustexts if got == text]


def forward_m(origin, pos, yaw_rad):
    """How far `pos` is from `origin` along the heading `yaw_rad` (NED, m)."""
    return (pos[0] - origin[0]) * math.cos(yaw_rad) + (pos[1] - origin[1]) * math.sin(yaw_rad)


# -- MAVSDK ManualControl ----------------------------------------------------------------------------------


class Watch:
    """MAVSDK telemetry with the vehicle time (ATTITUDE's timestamp, s) each value arrived at."""

    def __init__(self):
        self.now_s = 0.0
        self.yaw_rad: Any = None
        self.pos: Any = None  # (n, e, d) m: the truth (--estimator truth)
        self.vel: Any = None
        self.armed: Any = None
        self.landed: Any = None
        self.modes: list = []  # (t, name)
        self.landed_at: list = []  # (t, name)
        self.disarmed_at = None
        self.texts: list = []  # (t, text)

    def on_attitude(self, a):
        self.now_s = max(self.now_s, a.timestamp_us / 1e6)
        self.yaw_rad = math.radians(a.yaw_deg)

    def on_pos(self, p):
        self.pos = (p.position.north_m, p.position.east_m, p.position.down_m)
        self.vel = (p.velocity.north_m_s, p.velocity.east_m_s, p.velocity.down_m_s)

    def on_armed(self, armed):
        if self.armed and not armed:
            self.disarmed_at = self.now_s
        self.armed = armed

    def on_landed(self, state):
        if state.name != self.landed:
            self.landed_at.append((self.now_s, state.name))
        self.landed = state.name

    def on_mode(self, mode):
        if not self.modes or self.modes[-1][1] != mode.name:
            self.modes.append((self.now_s, mode.name))

    async def until(self, seconds, what, cond):
        """Until `cond()` holds, failing after `seconds` of vehicle time (a wall-clock guard of 10x that)."""
        start, wall_end = self.now_s, time.monotonic() + 10 * seconds + 30
        while not cond():
            assert self.now_s - start <= seconds, f"{what}: not within {seconds:g} s of vehicle time"
            assert time.monotonic() < wall_end, f"{what}: wall-clock guard"
            await asyncio.sleep(0.01)  # polling, not a timed wait: the limit is vehicle time
        return self.now_s - start

    async def hold(self, seconds):
        await self.until(seconds + 1.0, "time passing", lambda s=self.now_s: self.now_s - s >= seconds)

    def speed_mps(self):
        return math.hypot(self.vel[0], self.vel[1])


async def watch(stream, update):
    async for value in stream:
        update(value)


async def mavsdk_manual_flight(instance, disarm_land_s):
    drone = await mavsdk_ready(instance)
    w = Watch()
    t = drone.telemetry
    tasks = [
        asyncio.ensure_future(watch(t.attitude_euler(), w.on_attitude)),
        asyncio.ensure_future(watch(t.position_velocity_ned(), w.on_pos)),
        asyncio.ensure_future(watch(t.armed(), w.on_armed)),
        asyncio.ensure_future(watch(t.landed_state(), w.on_landed)),
        asyncio.ensure_future(watch(t.flight_mode(), w.on_mode)),
        asyncio.ensure_future(watch(t.status_text(), lambda s: w.texts.append((w.now_s, s.text)))),
    ]
    # The sticks as MAVSDK takes them: x forward, y right, z throttle 0..1 (0.5 holds), r yaw; streamed
    # every 50 ms from before the mode change to the end, as the plugin asks ("10 Hz at least").
    sticks = [0.0, 0.0, 0.5, 0.0]
    sent = [0]

    async def stream():
        while True:
            await drone.manual_control.set_manual_control_input(*sticks)
            sent[0] += 1
            await asyncio.sleep(0.05)

    tasks.append(asyncio.ensure_future(stream()))
    try:
        await w.until(10.0, "telemetry", lambda: w.pos is not None and w.yaw_rad is not None and sent[0] >= 3)
        ground, yaw = w.pos, w.yaw_rad
        await drone.action.arm()
        await drone.manual_control.start_position_control()
        await w.until(3.0, "Position mode", lambda: w.modes and w.modes[-1][1] == "POSCTL")
        position_from = len(w.modes) - 1
        # On the ground with the throttle centred the motors idle: it stays there.
        await w.hold(1.0)
        idle_rise_m = ground[2] - w.pos[2]
        # Climb with the throttle stick up; centred, the altitude holds.
        sticks[2] = 1.0
        climb_s = await w.until(20.0, "climb past 2 m", lambda: ground[2] - w.pos[2] > 2.0)
        sticks[2] = 0.5
        await w.until(10.0, "climb stopped", lambda: abs(w.vel[2]) < 0.05)
        hold_up_m = ground[2] - w.pos[2]
        await w.hold(2.0)
        held_up_m = ground[2] - w.pos[2]
        # Forward with the pitch stick for 3 s, released: it brakes to a hold.
        start = w.pos
        sticks[0] = 1.0
        await w.hold(3.0)
        top_speed_mps = w.speed_mps()
        sticks[0] = 0.0
        await w.until(10.0, "stopped after forward", lambda: w.speed_mps() < 0.05)
        out_m = forward_m(start, w.pos, yaw)
        # And back.
        sticks[0] = -1.0
        await w.hold(3.0)
        sticks[0] = 0.0
        await w.until(10.0, "stopped after back", lambda: w.speed_mps() < 0.05)
        back_m = forward_m(start, w.pos, yaw)
        # Throttle low: it descends, lands and disarms COM_DISARM_LAND after touchdown. The times are the
        # STATUSTEXTs' (sent as it happens); EXTENDED_SYS_STATE and HEARTBEAT come once a second.
        sticks[2] = 0.0
        await w.until(60.0, "landed (ON_GROUND)", lambda: w.landed == "ON_GROUND")
        await w.until(disarm_land_s + 5.0, "disarmed", lambda: w.disarmed_at is not None)
        await w.until(2.0, "the disarm's STATUSTEXT", lambda: any(t.startswith("Disarmed") for _, t in w.texts))
        touchdown_s = [at for (at, text) in w.texts if text == "Landing detected"][-1]
        disarmed_s = [at for (at, text) in w.texts if text.startswith("Disarmed")][-1]
        modes_in_flight = [name for (_, name) in w.modes[position_from:]]
        return {
            "idle_rise_m": idle_rise_m,
            "climb_s": climb_s,
            "hold_up_m": hold_up_m,
            "held_up_m": held_up_m,
            "top_speed_mps": top_speed_mps,
            "out_m": out_m,
            "back_m": back_m,
            "cross_m": abs(-(w.pos[0] - start[0]) * math.sin(yaw) + (w.pos[1] - start[1]) * math.cos(yaw)),
            "disarm_after_s": disarmed_s - touchdown_s,
            "modes": modes_in_flight,
            "texts": [text for (_, text) in w.texts],
        }
    finally:
        for task in tasks:
            task.cancel()


def test_mavsdk_manual_control_climbs_flies_forward_and_back_in_position_mode_and_lands_by_throttle(run_sitl):
    sitl = run_sitl("1")
    vehicle = connect(sitl)
    disarm_land_s = Params(vehicle, 1).get("COM_DISARM_LAND")
    vel_manual_mps = Params(vehicle, 1).get("MPC_VEL_MANUAL")
    vehicle.close()
    got = asyncio.run(asyncio.wait_for(mavsdk_manual_flight(sitl.instance, disarm_land_s), 600))
    print(f"MAVSDK manual flight: {got}")
    assert got["modes"] == ["POSCTL"], "Position mode throughout: no failsafe"
    assert got["idle_rise_m"] < 0.05, "armed with the throttle centred, it stays on the ground"
    assert got["hold_up_m"] > 1.0
    assert abs(got["held_up_m"] - got["hold_up_m"]) < 0.1, "the altitude holds with the throttle centred"
    assert got["top_speed_mps"] <= vel_manual_mps * 1.05
    assert got["out_m"] > 2.0
    # Back: 3 s at full stick each way, timed by MAVSDK's wall-clock stream; within 1 m of the start (it
    # ended 0.35 m short at most in ten runs: the legs' lengths differ by the stick's wall-time jitter).
    assert got["out_m"] - got["back_m"] > 2.0 and abs(got["back_m"]) < 1.0, "flown back to about the start"
    assert got["cross_m"] < 0.2, "no sideways drift with the roll stick centred"
    assert "Disarmed after landing" in got["texts"], "a landing after a flight, not a preflight disarm"
    assert abs(got["disarm_after_s"] - disarm_land_s) <= 0.1, "disarmed COM_DISARM_LAND after touchdown"


# -- aco-sticks --script -----------------------------------------------------------------------------------


def run_sticks(*args, timeout=300):
    """`python -m aco_gcs.sticks args...` in its own process group: (exit code, stdout, stderr)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "gcs-scripts"), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    proc = subprocess.Popen(
        [sys.executable, "-m", "aco_gcs.sticks", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"aco-sticks did not finish within {timeout} s of wall time\n{out}{err}")
    print(f"--- aco-sticks {' '.join(map(str, args))}: exit {proc.returncode}\n{out}{err}")
    return proc.returncode, out, err


def tlog_track(path, system_id):
    """From a `.tlog`: [(t_s, (n, e, d), (vn, ve, vd))] of LOCAL_POSITION_NED, [(t_s, main mode)] of the
    HEARTBEATs (at the telemetry time before each) and the first ATTITUDE yaw, of `system_id`'s autopilot."""
    log = link.mavutil.mavlink_connection(str(path))
    track, modes, yaw = [], [], None
    now_ms = 0
    while True:
        msg = log.recv_match()
        if msg is None:
            break
        if msg.get_type() == "BAD_DATA" or msg.get_srcSystem() != system_id or msg.get_srcComponent() != 1:
            continue
        now_ms = max(now_ms, getattr(msg, "time_boot_ms", 0))
        kind = msg.get_type()
        if kind == "LOCAL_POSITION_NED":
            track.append((msg.time_boot_ms / 1000, (msg.x, msg.y, msg.z), (msg.vx, msg.vy, msg.vz)))
        elif kind == "HEARTBEAT" and msg.autopilot == mavlink.MAV_AUTOPILOT_PX4:
            modes.append((now_ms / 1000, (msg.custom_mode >> 16) & 0xFF))
        elif kind == "ATTITUDE" and yaw is None:
            yaw = msg.yaw
    return track, modes, yaw


def test_sticks_script_flies_position_mode_forward_and_stops_within_0_1_m_on_the_truth(run_sitl, tmp_path):
    sitl = run_sitl("2")
    script = tmp_path / "forward.toml"
    script.write_text(
        "[[step]]\nfor_s = 3.0\nthrottle = 1.0\n"  # climb
        "[[step]]\nfor_s = 2.0\n"  # hold
        "[[step]]\nfor_s = 3.0\npitch = 1.0\n"  # forward
        "[[step]]\nfor_s = 4.0\n"  # sticks centred: brake and hold
    )
    # Refused first: with the joystick not a source (COM_RC_IN_MODE 0, the radio only) Position is denied,
    # and aco-sticks says why and exits 1 without arming.
    vehicle = connect(sitl)
    Params(vehicle, 1).require_set("COM_RC_IN_MODE", 0)
    vehicle.close()
    code, out, err = run_sticks("--instance", sitl.instance, "--script", script)
    assert code == 1 and "Position denied: no manual control" in err, err
    assert "armed at" not in out
    vehicle = connect(sitl)
    Params(vehicle, 1).require_set("COM_RC_IN_MODE", 3)
    vehicle.close()
    code, out, err = run_sticks("--instance", sitl.instance, "--script", script)
    assert code == 0, err
    assert "Position mode at t" in out and "armed at t" in out and "landed and disarmed" in out
    starts = [float(t) for t in re.findall(r"step \d/4 at t ([0-9.]+) s", out)]
    assert len(starts) == 4
    sitl.stop()  # the .tlog is whole once the autopilot has stopped
    (tlog,) = sitl.tlogs()
    track, modes, yaw = tlog_track(tlog, sitl.instance + 1)
    assert yaw is not None and track

    def at(t_s):
        return [sample for sample in track if sample[0] <= t_s][-1]

    ground = at(starts[0])[1]
    forward_from, forward_to, end = at(starts[2]), at(starts[3]), at(starts[3] + 4.0)
    settled = [s for s in track if starts[3] + 3.0 <= s[0] <= starts[3] + 4.0]
    out_m = forward_m(forward_from[1], forward_to[1], yaw)
    stopped_m = forward_m(forward_from[1], end[1], yaw)
    drift_m = max(math.dist(s[1][:2], settled[0][1][:2]) for s in settled)
    end_speed_mps = math.hypot(end[2][0], end[2][1])
    flown = [mode for (t, mode) in modes if starts[0] <= t <= starts[3] + 4.0]
    print(
        f"aco-sticks --script: up {ground[2] - forward_from[1][2]:.2f} m, forward {out_m:.2f} m in the 3 s step, "
        f"stopped {stopped_m:.2f} m out at {end_speed_mps:.3f} m/s, drift {drift_m:.3f} m over the last second"
    )
    assert set(flown) == {PX4_MAIN_POSCTL}, "Position mode throughout the steps"
    assert ground[2] - forward_from[1][2] > 1.0, "climbed with the throttle stick"
    assert out_m > 2.0
    assert end_speed_mps < 0.1 and drift_m < 0.1, "stopped and holding with the sticks centred"
    # The reference's jerk-limited stop from MPC_VEL_MANUAL 2 m/s (MPC_ACC_HOR_MAX 2 m/s², MPC_JERK_MAX
    # 4 m/s³) takes 1.5 m; the vehicle trails its reference a little (1.88 m measured on the truth).
    assert stopped_m - out_m < 2.5, "braked within the stopping distance"


class Terminal:
    """`python -m aco_gcs.sticks args...` on a pseudo-terminal, as a user at a keyboard runs it: keys are
    typed into it, and its output is read until a line says what the test waits for (no sleeps)."""

    def __init__(self, *args):
        import pty

        self.pid, self.fd = pty.fork()
        if self.pid == 0:  # the child: the script, its standard input a terminal
            os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT / "gcs-scripts"), os.environ.get("PYTHONPATH", "")])
            os.execv(sys.executable, [sys.executable, "-m", "aco_gcs.sticks", *map(str, args)])
        self.out = ""
        self.cursor = 0  # where the last match ended: the next one is looked for after it

    def type(self, keys):
        os.write(self.fd, keys.encode())

    def _read(self, timeout_s):
        """What the script printed within `timeout_s`; False once it has closed the terminal."""
        if not select.select([self.fd], [], [], timeout_s)[0]:
            return True
        try:
            self.out += os.read(self.fd, 65536).decode(errors="replace")
        except OSError:
            return False
        return True

    def read_until(self, pattern, wall_s=120.0):
        """The first match of regex `pattern` after the last match (a wall-clock hang guard only)."""
        regex, end = re.compile(pattern), time.monotonic() + wall_s
        while (m := regex.search(self.out, self.cursor)) is None:
            assert time.monotonic() < end, f"{pattern!r} not seen in:\n{self.out[-3000:]}"
            assert self._read(0.5), f"the script ended before {pattern!r}:\n{self.out[-3000:]}"
        self.cursor = m.end()
        return m

    def exit_code(self, wall_s=120.0):
        end = time.monotonic() + wall_s
        while time.monotonic() < end:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                return os.waitstatus_to_exitcode(status)
            self._read(0.2)
        pytest.fail(f"aco-sticks --keyboard did not exit:\n{self.out[-3000:]}")


def test_sticks_keyboard_arms_by_the_gesture_climbs_and_on_x_lands_before_quitting(run_sitl):
    sitl = run_sitl("2")
    term = Terminal("--instance", sitl.instance, "--keyboard", "--arm", "gesture", "--track", "0.5")
    try:
        term.read_until(r"Position mode at t")
        term.read_until(r"keys \(each press")  # the terminal reads single keys from here on
        term.type("t")  # the gesture: throttle low, yaw right, for COM_RC_ARM_HYST
        term.read_until(r"armed at t")
        term.type("rrr")  # throttle 0.8: climbs
        term.read_until(r"throttle 0\.80")
        term.read_until(r"D +-1\.[5-9]\d m")  # 1.5 m up
        term.type(" ")  # centred: holds
        term.read_until(r"throttle 0\.50")
        term.type("x")  # in the air: lands first, then quits
        term.read_until(r"in the air: landing before quitting")
        term.read_until(r"landed and disarmed after")
        code = term.exit_code()
    finally:
        with contextlib.suppress(ProcessLookupError, ChildProcessError):  # already exited and reaped
            os.kill(term.pid, signal.SIGKILL)
            os.waitpid(term.pid, 0)
        os.close(term.fd)
    print(term.out[-2000:])
    assert code == 0, term.out[-3000:]
    assert "[vehicle] Armed" in term.out, "armed by the gesture, as the vehicle says"
    assert "Failsafe" not in term.out, "the sticks never lapsed"


# -- refusals ----------------------------------------------------------------------------------------------


def pilot(sitl):
    """A stick-streaming pymavlink link to the vehicle of `sitl`, as aco-sticks connects."""
    vehicle = PilotVehicle(
        f"udpin:127.0.0.1:{link.api_port(sitl.instance)}", f"127.0.0.1:{link.AUTOPILOT_PORT + sitl.instance}", 240
    )
    vehicle.wait_heartbeat(30.0, sitl.instance)
    return vehicle


def test_manual_modes_acro_included_and_arming_without_manual_control_are_refused_with_their_reasons(run_sitl):
    vehicle = pilot(run_sitl("4"))
    wait_ready(vehicle)
    loss_s = Params(vehicle, 1).get("COM_RC_LOSS_T")
    custom = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED

    def refused(main, text):
        """The ACK of DO_SET_MODE to PX4 main mode `main`, once the STATUSTEXT `text` came."""
        since = vehicle.now_s()
        result = vehicle.command(mavlink.MAV_CMD_DO_SET_MODE, custom, main, 0)
        vehicle.wait_until(2.0, f"STATUSTEXT {text!r}", lambda: text in vehicle.texts_since(since))
        return result

    # No manual control ever: each manual mode is refused by name, and the mode stays.
    before = vehicle.px4_mode()
    manual_modes = (
        (PX4_MAIN_POSCTL, "Position"),
        (2, "Altitude"),
        (7, "Stabilized"),
        (1, "Manual"),
        (PX4_MAIN_ACRO, "Acro"),
    )
    for main, name in manual_modes:
        assert refused(main, f"{name} denied: no manual control") == mavlink.MAV_RESULT_DENIED, name
    assert vehicle.px4_mode() == before
    # The sticks start: a few of them must reach the vehicle before a manual mode is asked for.
    vehicle.sticks = CENTRED
    started_s = vehicle.now_s()
    vehicle.wait_until(2.0, "the sticks flowing", lambda: vehicle.now_s() - started_s > 0.3)
    # With the sticks flowing Position is taken; once they stop, arming in it is refused.
    vehicle.set_px4_mode(PX4_MAIN_POSCTL, 0, "Position mode")
    vehicle.sticks = None
    stopped_s = vehicle.now_s()
    vehicle.wait_until(loss_s + 1.0, "time passing", lambda: vehicle.now_s() - stopped_s > loss_s + 0.2)
    since = vehicle.now_s()
    assert vehicle.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_DENIED
    vehicle.wait_until(
        2.0, "the arming refusal", lambda: "Arming denied: no manual control" in vehicle.texts_since(since)
    )
    assert not vehicle.armed
    vehicle.close()


def test_sticks_stopping_in_position_mode_in_the_air_return_within_com_rc_loss_t_plus_0_1_s(run_sitl):
    vehicle = pilot(run_sitl("1"))
    params = Params(vehicle, 1)
    loss_s = params.get("COM_RC_LOSS_T")
    assert params.get("NAV_RCL_ACT") == 2, "the default: return"
    ground, _ = wait_ready(vehicle)
    vehicle.sticks = CENTRED
    vehicle.wait_until(1.0, "sticks out", lambda: vehicle.sent >= 3)
    vehicle.set_px4_mode(PX4_MAIN_POSCTL, 0, "Position mode")
    vehicle.require("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    vehicle.sticks = Sticks(throttle=1.0)
    vehicle.wait_until(20.0, "climb past 2 m", lambda: ground[2] - vehicle.pos[2] > 2.0)
    vehicle.sticks = CENTRED
    vehicle.wait_until(10.0, "climb stopped", lambda: abs(vehicle.vel[2]) < 0.05)
    # The sticks stop: the vehicle time of the last MANUAL_CONTROL is the client's clock when it went out.
    vehicle.sticks = None
    last_sent_s = vehicle.last_sent_s
    text = "Failsafe: manual control lost, returning"
    vehicle.wait_until(
        5.0, "RTL, announced", lambda: said(vehicle, text) and vehicle.px4_mode() == (PX4_MAIN_AUTO, PX4_AUTO_RTL)
    )
    after_s = said(vehicle, text)[0] - last_sent_s
    # The sticks come back: announced, and the return goes on (the pilot switches modes to take over).
    vehicle.sticks = CENTRED
    vehicle.wait_until(3.0, "regained", lambda: said(vehicle, "Manual control regained"))
    print(f"manual control loss through sitl run: RTL announced {after_s:.3f} s after the last MANUAL_CONTROL")
    assert len(said(vehicle, text)) == 1
    assert loss_s <= after_s + 0.05 and after_s <= loss_s + 0.1, (
        f"{after_s:.3f} s (the telemetry clock the stamps are read on is 20 ms coarse at 50 Hz)"
    )
    assert vehicle.px4_mode() == (PX4_MAIN_AUTO, PX4_AUTO_RTL)
    vehicle.close()
