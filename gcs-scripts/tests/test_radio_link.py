"""A ground station over a telemetry radio's serial line: `sitl run` (plant and autopilot over UDP, at real
time) with the autopilot's serial ground-station link (`[gcs] serial = "DEV:BAUD"`) on end A of an emulated
serial line, and pymavlink on end B, at 57600 baud (a SiK radio), 115200 and 921600. The autopilot fits its
output to the line (`core::mavlink::link_rate`: baud / 10 bytes/s, streams thinned by PX4's rate
multiplier, HEARTBEAT, COMMAND_ACK and STATUSTEXT first).

Over each line, measured and then checked:
- the bytes the ground station receives: every 1 s window (of arrival, wall time) within the line's
  baud / 10 bytes/s, plus one frame and 5 % for the reader's scheduling;
- HEARTBEAT never below 0.9 Hz: at least 9 in every 10 s window of arrival (wall time, which is the
  vehicle's at real time; windows every second over the whole session, transfers included), and no gap
  between two of 1.25 s or more;
- ATTITUDE at 20 Hz of vehicle time (its `time_boot_ms`) while nothing else is sent: the streams fit whole
  even at 57600;
- every COMMAND_LONG acknowledged (REQUEST_MESSAGE AUTOPILOT_VERSION, one sent just after the parameter
  request and one just before each mission transfer, so that their ACKs race the transfers); the script
  resends a command after 1.5 s without its ACK, as MAVSDK and QGroundControl do, and counts the resends;
- the full parameter list: PARAM_REQUEST_LIST, then PARAM_REQUEST_READ by index for whatever is missing
  after 1 s of silence, as QGroundControl resumes; timed from the request to the last value;
- a 20-item mission (NAV_TAKEOFF, 18 NAV_WAYPOINT, NAV_LAND) uploaded and read back identical, with
  the mission protocol's resends on 1.5 s time-outs; each direction timed;
- at 57600, a RADIO_STATUS written as the radio would (system 51, component 68) with txbuf 20 halves the
  ATTITUDE rate within 1 s of vehicle time (then txbuf 40, "hold", once a second keeps it there), and
  txbuf 100 once a second brings it back to 20 Hz (0.5 * 1.25^4 > 1: by the fourth report).

The line is made by `start_line`: a socat pty pair today (which carries bytes as fast as they come: the
pacing measured here is the autopilot's own), to become `sitl line` (which paces at the baud rate and can
lose and corrupt bytes). About 50 s of wall time."""

import itertools
import math
import os
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from sitl_harness import start_sitl, stop_group

os.environ["MAVLINK20"] = "1"  # pymavlink speaks MAVLink 1 unless told otherwise
from pymavlink import mavutil

mavlink = mavutil.mavlink

GCS_SYSTEM, GCS_COMPONENT = 255, 190
RADIO_SYSTEM, RADIO_COMPONENT = 51, 68  # a SiK radio's own ids
AUTOPILOT_VERSION = 148
COMMAND_RESEND_S = 1.5
# What the transfers wait for (kept in order for `Gcs.next`).
TRANSFER_KINDS = (
    "PARAM_VALUE",
    "MISSION_COUNT",
    "MISSION_REQUEST",
    "MISSION_REQUEST_INT",
    "MISSION_ITEM_INT",
    "MISSION_ACK",
)
MISSION_RESEND_S = 1.5
MISSION_ITEMS = 20
STREAM_WINDOW_S = 10.0
# The largest MAVLink 2 frame: the pacer's bucket.
MAX_FRAME_BYTES = 280
# Bounds on the transfers (s of wall time), about twice what was measured over a socat pty pair (the
# parameter list of 219 values: 1.43 s at 57600, 0.70 s at 115200, 0.12 s at 921600; a 20-item mission
# 0.33-0.48 s each way at every baud, bound by the round trips, not the bytes).
PARAMS_S = {57600: 3.0, 115200: 1.5, 921600: 0.5}
MISSION_S = 2.0


@dataclass
class Line:
    """An emulated serial line: the autopilot's end A, the ground station's end B."""

    proc: subprocess.Popen
    a: Path
    b: Path

    def stop(self):
        stop_group(self.proc)


def start_line(tmp_path, baud, loss_pct=0.0, burst=0):
    """The line between the autopilot (end A) and the ground station (end B) at `baud`, losing `loss_pct` %
    of the bytes in bursts of `burst`. Today a socat pty pair: no pacing and no loss (so `loss_pct` must be
    0); `sitl line --link-a A --link-b B --baud BAUD --loss PCT --burst BYTES` takes its place."""
    assert loss_pct == 0 and burst == 0, "a socat pty pair loses nothing"
    socat = shutil.which("socat")
    if socat is None:
        pytest.fail("socat is not installed (scripts/test installs it: apt-get install socat)")
    a, b = tmp_path / f"line-a-{baud}", tmp_path / f"line-b-{baud}"
    with open(tmp_path / f"line-{baud}.log", "w") as stderr:
        proc = subprocess.Popen(
            [socat, f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
            stderr=stderr,
            start_new_session=True,
        )
    deadline = time.monotonic() + 10
    while not (a.exists() and b.exists()):
        assert time.monotonic() < deadline and proc.poll() is None, "no serial line"
        time.sleep(0.05)
    return Line(proc, a, b)


@dataclass
class Received:
    wall_s: float
    kind: str
    nbytes: int
    time_boot_ms: int | None


@dataclass
class Pending:
    """A COMMAND_LONG waiting for its ACK."""

    params: tuple
    sent_s: float
    first_s: float
    resends: int = 0


@dataclass
class Gcs:
    """pymavlink on end B: everything the vehicle sends is recorded (arrival, size, vehicle time); a GCS
    HEARTBEAT goes once a second; commands are resent after 1.5 s without their ACK."""

    conn: Any
    sysid: int
    start_s: float = field(default_factory=time.monotonic)
    received: list[Received] = field(default_factory=list)
    now_ms: int = 0
    last_heartbeat_s: float = -1.0
    pending: dict[int, Pending] = field(default_factory=dict)
    acked: list[tuple[int, float, int]] = field(default_factory=list)  # (command, seconds to ACK, resends)
    messages: list = field(default_factory=list)  # the vehicle's messages other than streams, for the waits

    def wall_s(self):
        return time.monotonic() - self.start_s

    def pump(self, timeout=0.05):
        """Receive what there is (up to `timeout` s for the first message), keeping the GCS's duties."""
        now = time.monotonic()
        if now - self.last_heartbeat_s >= 1.0:
            self.last_heartbeat_s = now
            self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        for command, p in self.pending.items():
            if now - p.sent_s >= COMMAND_RESEND_S:
                p.sent_s, p.resends = now, p.resends + 1
                self.conn.mav.command_long_send(self.sysid, 1, command, p.resends, *p.params)
        msg = self.conn.recv_match(blocking=True, timeout=timeout)
        while msg is not None:
            self.take(msg)
            msg = self.conn.recv_match(blocking=False)

    def take(self, msg):
        kind = msg.get_type()
        if kind == "BAD_DATA" or msg.get_srcSystem() != self.sysid or msg.get_srcComponent() != 1:
            return
        t = getattr(msg, "time_boot_ms", None)
        if t is not None:
            self.now_ms = max(self.now_ms, t)
        self.received.append(Received(self.wall_s(), kind, len(msg.get_msgbuf()), t))
        if kind == "COMMAND_ACK" and msg.command in self.pending:
            p = self.pending.pop(msg.command)
            assert msg.result == mavlink.MAV_RESULT_ACCEPTED, f"command {msg.command}: result {msg.result}"
            self.acked.append((msg.command, time.monotonic() - p.first_s, p.resends))
        if kind in TRANSFER_KINDS:
            self.messages.append(msg)
        elif kind == "STATUSTEXT":
            print(f"  [vehicle] {msg.text}", flush=True)

    def wait(self, seconds, what, cond):
        end = time.monotonic() + seconds
        while not cond():
            assert time.monotonic() < end, f"{what}: not within {seconds:g} s"
            self.pump()

    def next(self, seconds, match):
        """The next recorded non-stream message for which `match` holds within `seconds`, or None."""
        end = time.monotonic() + seconds
        while True:
            while self.messages:
                msg = self.messages.pop(0)
                if match(msg):
                    return msg
            if time.monotonic() >= end:
                return None
            self.pump()

    def start_command(self, command, *params):
        values = (*params, *[0.0] * (7 - len(params)))
        now = time.monotonic()
        self.pending[command] = Pending(values, now, now)
        self.conn.mav.command_long_send(self.sysid, 1, command, 0, *values)

    def request_version(self):
        self.start_command(mavlink.MAV_CMD_REQUEST_MESSAGE, AUTOPILOT_VERSION)

    def settle_commands(self, seconds=10.0):
        self.wait(seconds, "every COMMAND_LONG acknowledged", lambda: not self.pending)

    def radio_status(self, txbuf):
        """A RADIO_STATUS as the radio sends it: its own system and component."""
        radio = mavlink.MAVLink(None, srcSystem=RADIO_SYSTEM, srcComponent=RADIO_COMPONENT)
        msg = radio.radio_status_encode(200, 190, txbuf, 40, 42, 0, 0)
        self.conn.write(msg.pack(radio))

    # -- what was received ------------------------------------------------------------------------------
    def bytes_per_window(self, window_s=1.0, step_s=0.1):
        """The most bytes received in any `window_s` window of arrival."""
        last = self.received[-1].wall_s if self.received else 0.0
        worst = 0
        t = self.received[0].wall_s if self.received else 0.0
        while t + window_s <= last:
            worst = max(worst, sum(r.nbytes for r in self.received if t <= r.wall_s < t + window_s))
            t += step_s
        return worst

    def rate(self, kind, from_ms, to_ms):
        n = sum(
            1
            for r in self.received
            if r.kind == kind and r.time_boot_ms is not None and from_ms <= r.time_boot_ms < to_ms
        )
        return n * 1000.0 / (to_ms - from_ms)

    def heartbeats(self, window_s=STREAM_WINDOW_S):
        """The fewest vehicle HEARTBEATs in any `window_s` window of arrival (windows every 1 s, starting
        half a second after the first HEARTBEAT, so that a beat's jitter does not move it out of a window
        aligned on it), and the longest gap between two (s)."""
        beats = [r.wall_s for r in self.received if r.kind == "HEARTBEAT"]
        assert len(beats) > 1, "no HEARTBEATs"
        fewest = len(beats)
        t = beats[0] + 0.5
        while t + window_s <= self.wall_s():
            fewest = min(fewest, sum(1 for b in beats if t <= b < t + window_s))
            t += 1.0
        return fewest, max(b - a for a, b in itertools.pairwise(beats))


def fetch_params(gcs):
    """PARAM_REQUEST_LIST, then PARAM_REQUEST_READ by index for the missing ones after 1 s of silence (three
    rounds at most); a COMMAND_LONG sent right after the request. Returns (seconds, count, reads)."""
    start = time.monotonic()
    gcs.conn.mav.param_request_list_send(gcs.sysid, 1)
    gcs.request_version()
    values: dict[int, float] = {}
    count = None
    reads = 0
    last = time.monotonic()
    for _ in range(4):
        while True:
            msg = gcs.next(1.0, lambda m: m.get_type() == "PARAM_VALUE")
            if msg is None:
                break
            count = msg.param_count
            values[msg.param_index] = msg.param_value
            last = time.monotonic()
            if len(values) == count:
                break
        assert count is not None, "no PARAM_VALUE at all"
        missing = [i for i in range(count) if i not in values]
        if not missing:
            break
        for index in missing:
            gcs.conn.mav.param_request_read_send(gcs.sysid, 1, b"", index)
            reads += 1
    assert count is not None and len(values) == count, f"{len(values)} of {count} parameters"
    return last - start, count, reads


def mission_items(lat_e7, lon_e7):
    """NAV_TAKEOFF, 18 waypoints on a 20 m circle, NAV_LAND, at 10 m relative."""
    rel = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    dlat_per_m = 1e7 / 111_319.5
    dlon_per_m = dlat_per_m / math.cos(math.radians(lat_e7 / 1e7))
    items = [(mavlink.MAV_CMD_NAV_TAKEOFF, rel, (0.0, 0.0, 0.0, 0.0), lat_e7, lon_e7, 10.0)]
    for k in range(MISSION_ITEMS - 2):
        a = 2 * math.pi * k / (MISSION_ITEMS - 2)
        x = lat_e7 + round(20 * math.cos(a) * dlat_per_m)
        y = lon_e7 + round(20 * math.sin(a) * dlon_per_m)
        items.append((mavlink.MAV_CMD_NAV_WAYPOINT, rel, (0.0, 1.0, 0.0, 0.0), x, y, 10.0))
    items.append((mavlink.MAV_CMD_NAV_LAND, rel, (0.0, 0.0, 0.0, 0.0), lat_e7, lon_e7, 0.0))
    return items


def send_item(gcs, seq, item):
    command, frame, params, x, y, z = item
    gcs.conn.mav.mission_item_int_send(gcs.sysid, 1, seq, frame, command, 0, 1, *params, x, y, z)


def upload(gcs, items):
    """MISSION_COUNT, answering each MISSION_REQUEST_INT, to MISSION_ACK; the last thing sent is resent after
    1.5 s of silence. Returns (seconds, resends)."""
    start = time.monotonic()
    gcs.request_version()
    gcs.conn.mav.mission_count_send(gcs.sysid, 1, len(items))
    last_sent = None
    resends = 0
    kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
    while True:
        msg = gcs.next(MISSION_RESEND_S, lambda m: m.get_type() in kinds)
        if msg is None:
            resends += 1
            assert resends <= 10, "mission upload: no answer"
            if last_sent is None:
                gcs.conn.mav.mission_count_send(gcs.sysid, 1, len(items))
            else:
                send_item(gcs, last_sent, items[last_sent])
            continue
        if msg.get_type() == "MISSION_ACK":
            assert msg.type == mavlink.MAV_MISSION_ACCEPTED, f"mission refused: {msg.type}"
            return time.monotonic() - start, resends
        send_item(gcs, msg.seq, items[msg.seq])
        last_sent = msg.seq


def download(gcs):
    """MISSION_REQUEST_LIST, MISSION_REQUEST_INT for each item (resent after 1.5 s), MISSION_ACK. Returns
    (items, seconds, resends)."""
    start = time.monotonic()
    gcs.request_version()
    resends = 0
    count = None
    while count is None:
        gcs.conn.mav.mission_request_list_send(gcs.sysid, 1)
        msg = gcs.next(MISSION_RESEND_S, lambda m: m.get_type() == "MISSION_COUNT")
        if msg is None:
            resends += 1
            assert resends <= 10, "mission download: no MISSION_COUNT"
        else:
            count = msg.count
    items = []
    for seq in range(count):
        while True:
            gcs.conn.mav.mission_request_int_send(gcs.sysid, 1, seq)
            msg = gcs.next(MISSION_RESEND_S, lambda m, s=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == s)
            if msg is not None:
                params = (msg.param1, msg.param2, msg.param3, msg.param4)
                items.append((msg.command, msg.frame, params, msg.x, msg.y, msg.z))
                break
            resends += 1
            assert resends <= 10, f"mission download: no item {seq}"
    gcs.conn.mav.mission_ack_send(gcs.sysid, 1, mavlink.MAV_MISSION_ACCEPTED)
    return items, time.monotonic() - start, resends


def radio_phase(gcs):
    """3 s for the streams to recover from the transfers, then txbuf 20, then 40 (hold) once a second for
    3 s, then 100 once a second for 6 s. Returns the ATTITUDE rates (Hz of vehicle time): over the 2 s
    before the first report, from 1 s to 4 s after it, and over the last 2 s; and the vehicle time (ms) from
    the report to the first ATTITUDE gap of 100 ms."""
    # The streams come back from the transfers first.
    end = time.monotonic() + 3.0
    while time.monotonic() < end:
        gcs.pump()
    v0 = gcs.now_ms
    before = gcs.rate("ATTITUDE", v0 - 2000, v0)
    schedule = [20, 40, 40, 40, 100, 100, 100, 100, 100, 100]
    for txbuf in schedule:
        gcs.radio_status(txbuf)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            gcs.pump()
    attitude = sorted(
        r.time_boot_ms
        for r in gcs.received
        if r.kind == "ATTITUDE" and r.time_boot_ms is not None and r.time_boot_ms >= v0
    )
    halved_after_ms = next((b for a, b in itertools.pairwise(attitude) if b - a >= 90), math.inf) - v0
    halved = gcs.rate("ATTITUDE", v0 + 1000, v0 + 4000)
    back = gcs.rate("ATTITUDE", gcs.now_ms - 2000, gcs.now_ms)
    return before, halved, back, halved_after_ms


def session(tmp_path, baud, radio):
    """One `sitl run` with its serial link on a `baud` line; returns what was measured."""
    line = start_line(tmp_path, baud)
    config = tmp_path / "autopilot.toml"
    config.write_text(f'[gcs]\nserial = "{line.a}:{baud}"\n')
    sitl = start_sitl(tmp_path, "--autopilot-config", str(config), speed=1)
    try:
        conn = mavutil.mavlink_connection(
            str(line.b), baud=baud, source_system=GCS_SYSTEM, source_component=GCS_COMPONENT
        )
        gcs = Gcs(conn, sitl.instance + 1)
        gcs.wait(30.0, "the vehicle's HEARTBEAT and timed telemetry on the line", lambda: gcs.now_ms > 0)
        position = None
        # The streams alone.
        stream_start = gcs.wall_s()
        while gcs.wall_s() - stream_start < STREAM_WINDOW_S:
            gcs.pump()
        streams = [r for r in gcs.received if r.wall_s >= stream_start]
        stream_rate = sum(r.nbytes for r in streams) / STREAM_WINDOW_S
        attitude_hz = gcs.rate("ATTITUDE", gcs.now_ms - 8000, gcs.now_ms)
        position = gcs.conn.messages.get("GPS_RAW_INT")
        assert position is not None, "no GPS_RAW_INT within the stream window"
        params_s, params, reads = fetch_params(gcs)
        items = mission_items(position.lat, position.lon)
        up_s, up_resends = upload(gcs, items)
        back, down_s, down_resends = download(gcs)
        for _ in range(3):
            gcs.request_version()
            gcs.settle_commands()
        gcs.settle_commands()
        radio_rates = radio_phase(gcs) if radio else None
        heartbeats = gcs.heartbeats()
        result = {
            "baud": baud,
            "stream_Bps": stream_rate,
            "attitude_hz": attitude_hz,
            "worst_1s_B": gcs.bytes_per_window(),
            "mean_Bps": sum(r.nbytes for r in gcs.received) / (gcs.received[-1].wall_s - gcs.received[0].wall_s),
            "heartbeats_10s_min": heartbeats[0],
            "heartbeat_gap_s": heartbeats[1],
            "params": params,
            "params_s": params_s,
            "param_reads": reads,
            "upload_s": up_s,
            "download_s": down_s,
            "mission_resends": up_resends + down_resends,
            "mission_same": back == items,
            "commands": len(gcs.acked),
            "command_resends": sum(r for (_, _, r) in gcs.acked),
            "slowest_ack_s": max(s for (_, s, _) in gcs.acked),
            "radio": radio_rates,
            "session_s": gcs.wall_s(),
        }
        conn.close()
        return result
    finally:
        sitl.stop()
        line.stop()


@pytest.mark.parametrize("baud", [57600, 115200, 921600])
def test_a_ground_station_over_a_radio_line_gets_heartbeats_acks_parameters_and_missions(tmp_path, baud):
    r = session(tmp_path, baud, radio=baud == 57600)
    print(f"\n  radio line {r}", flush=True)
    data_rate = baud / 10
    assert r["worst_1s_B"] <= data_rate * 1.05 + MAX_FRAME_BYTES, r
    assert r["heartbeats_10s_min"] >= 9, "HEARTBEAT below 0.9 Hz in some 10 s window"
    assert r["heartbeat_gap_s"] < 1.25, "a HEARTBEAT came late"
    assert 19.0 <= r["attitude_hz"] <= 21.0, "the streams fit whole"
    assert r["commands"] == 6 and r["command_resends"] == 0, "every command acknowledged, first time"
    assert r["slowest_ack_s"] < 0.5, "an ACK waited behind a transfer"
    assert r["mission_same"], "the mission read back differs"
    assert r["mission_resends"] == 0
    assert r["params_s"] < PARAMS_S[baud], "the parameter list took too long"
    assert r["upload_s"] < MISSION_S and r["download_s"] < MISSION_S, "a mission transfer took too long"
    if r["radio"] is not None:
        before, halved, back, halved_after_ms = r["radio"]
        assert 19.0 <= before <= 21.0, r["radio"]
        assert halved_after_ms <= 1000, "halved within 1 s of vehicle time"
        assert 9.0 <= halved <= 11.0, r["radio"]
        assert 19.0 <= back <= 21.0, r["radio"]
