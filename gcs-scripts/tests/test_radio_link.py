"""A ground station over a telemetry radio's serial line: `sitl run` (plant and autopilot over UDP, at real
time) with the autopilot's serial ground-station link (`[gcs] serial = "DEV:BAUD"`) on end A of an emulated
serial line (`sitl line`, docs/serial-line.md) and pymavlink on end B. The acceptance test of:

    Ground station over an emulated 57600 line with 1 % byte loss: HEARTBEAT never below 0.9 Hz, every
    command ACKed, the full parameter list downloads and a 20-item mission uploads and reads back
    identical, each within a time the docs state; the same at 115200 and 921600 with streams at their
    full rate. A RADIO_STATUS with txbuf at 20 % halves the stream rates within 1 s and they recover when
    it rises.

The line: 57600 (a SiK radio), 115200 and 921600 baud, each with 1 % of the bytes lost, in runs of 32
bytes, both ways; no corruption, no latency; seed 11, fixed. Which bytes of each direction's stream are
lost depends on the seed only (which frames they fall in still depends on timing). The ground station
sends only 2-3 kB a session, and seed 1 loses none of its first 4 kB toward the vehicle; seed 11 loses
bytes 1239-1270 and 2115-2146 of that direction (`sitl line` measured with a counting pattern): the first
falls in the mission upload, the second after the download, at 57600 only (the other sessions send
less). So both directions lose frames in every run. It carries baud / 10 bytes/s each way (8N1); the
autopilot fits its output to that (`core::mavlink::link_rate`: streams thinned by PX4's rate multiplier,
HEARTBEAT, COMMAND_ACK and STATUSTEXT first).

Why runs of 32 bytes: a telemetry radio sends the serial stream in air packets (a SiK packet holds up to
252 bytes) and loses a whole packet when it loses anything; a UART loses single bytes. With independent
single-byte loss at 1 % (`--burst 1`) a 21-byte HEARTBEAT frame is hit 19 % of the time (1 - 0.99^21), and
more often still, because a frame cut short is read to its declared length and takes the next frame's
start with it (pymavlink, as the C library): measured, 55 % of the vehicle's frames do not arrive whole,
HEARTBEAT arrives at 0.47-0.57 Hz, and the mission upload fails (the vehicle gives an item up after 5
re-requests). So 1 Hz heartbeats cannot arrive at 0.9 Hz over that line whatever the vehicle does; it is
measured (`python tests/test_radio_link.py --burst 1`), not asserted. 32 bytes is a short air packet (a
radio sends what it has when the serial input pauses, and the vehicle's frames come a few tens of bytes at
a time): a lost run starts about once in 3200 bytes, a 21-byte HEARTBEAT is hit about (21 + 31) / 3200 =
1.6 % of the time; measured, 1.3-4.1 % of the frames the vehicle sends do not arrive whole, 1 HEARTBEAT
in about 36.

Lost bytes mean lost frames both ways, so the ground station here retries as QGroundControl and MAVSDK
do: a COMMAND_LONG is resent after 1.5 s without its ACK (the resends counted: "every command ACKed" is
every command acknowledged in the end, within 10 s); the parameter list is PARAM_REQUEST_LIST (resent if
nothing came for 1 s), then PARAM_REQUEST_READ by index for each missing value once the list has been
quiet for 1 s, as QGroundControl resumes; a mission upload resends MISSION_COUNT when no request came for
1.5 s and the last item when the final MISSION_ACK did not come for 1.5 s, while the vehicle re-requests
an item it did not get on its own 1.5 s time-out (vehicle time), which the ground station answers; a
download resends MISSION_REQUEST_LIST and each MISSION_REQUEST_INT after 1.5 s without the answer.

Over each line, measured and then checked:
- the line paced and lost what it was told: the bytes it delivered each way between two of its stats
  snapshots (every 0.5 s) 1 s or more apart at most baud / 10 per second (+ 1 %); 0.4-2 % of the bytes
  toward the ground station lost; no overrun (the ground station kept up); and the bytes the ground
  station received in any 1 s window of arrival within baud / 10 + one frame + 5 % for its scheduling;
- HEARTBEAT never below 0.9 Hz, from the vehicle: every gap between two received HEARTBEATs within 0.25 s
  of a whole number of seconds (none late), and each one missing from a gap of k s (k - 1 of them) lost
  on the line: a frame of the vehicle's link sequence is missing within 0.25 s of its time (the link
  numbers the frames it sends, so a frame not sent leaves no hole); counting those, at least 9 in every
  10 s window of arrival (windows every 1 s over the whole session, transfers included). What the
  ground station receives is reported: the fewest in a 10 s window, the longest gap, the mean rate; only
  the mean is asserted, at least 0.8 Hz, as a sanity bound. It is not "never below 0.9 Hz": one lost
  HEARTBEAT makes a 10 s window read 9, two within 10 s read 0.8 Hz, and this line loses 1 HEARTBEAT in
  about 36 (1 in 16 at 57600 with seed 11), whatever the vehicle does. Measured: a window read 8 (0.8 Hz)
  in 2 of the 6 runs at 57600 with seed 11 (3 heartbeats lost, 0.903-0.904 Hz), 9 or 10 in every other
  run;
- streams at their full rate: ATTITUDE, 20 Hz of vehicle time (`time_boot_ms`), not thinned while nothing
  else is sent: every gap of 75 ms or more between two received has a hole in the link's sequence
  numbers within it (a frame lost on the line, not one not sent), and at least 18 Hz arrive;
- every COMMAND_LONG acknowledged (REQUEST_MESSAGE AUTOPILOT_VERSION: one sent just after the parameter
  request and one just before each mission transfer, so that their ACKs race the transfers, three more
  after), each within 10 s with its resends, and each ACK within 0.5 s of the (re)send it answers;
- the full parameter list (219 values), timed from the request to the last value, within PARAMS_S;
- a 20-item mission (NAV_TAKEOFF, 18 NAV_WAYPOINT, NAV_LAND) uploaded, then read back identical: every
  field of every MISSION_ITEM_INT (seq, frame, command, current, autocontinue, param1-4, x, y, z,
  mission_type, and the targets being this ground station; `current` is 1 on item 0, the vehicle's
  current item after an upload, as the mission service says); each direction within MISSION_S;
- at 57600, a RADIO_STATUS written as the radio would (system 51, component 68) with txbuf 20 halves
  ATTITUDE within 1 s of vehicle time (from the report to the first of the ATTITUDEs 90 ms or more apart
  from then on), then txbuf 40 ("hold") once a second keeps it at 10 Hz (from 1 s to 4 s after the
  report: no two ATTITUDEs closer than 90 ms, no gap of 150 ms without a hole in the sequence numbers, at
  least 8 Hz arriving), and txbuf 100 once a second for 7 s brings it back to 20 Hz (0.5 * 1.25^4 > 1: by
  the fourth report; the last 2 s not thinned, at least 15 Hz arriving). A real radio makes RADIO_STATUS
  itself on the vehicle's side (it crosses no air); here it crosses the lossy line and is lost about 1.6 %
  of the time, so when ATTITUDE has not halved 1 s after the report and the line lost bytes toward the
  vehicle since then, the report is sent again, as the radio's next one, at most twice (counted, 0 in
  every measured run); without such a loss, no halving fails.

Measured on a 2-core VM shared with other builds, debug build: 6 runs of this test (seed 11), and, by
`python tests/test_radio_link.py --baud B --seeds 1 2 3 4 [--radio]` and earlier runs of this test with
seed 1, 12 runs per baud with seeds 1-4 (the full table with the link governor's notes, "Measured"):

| baud, seeds (runs) | parameter list (219) | mission up / down | command resends | HEARTBEAT: fewest per 10 s, gap |
|---|---|---|---|---|
| 57600, 11 (6) | 2.51-2.56 s (3-4 re-reads) | 3.64-3.69 / 0.69-0.76 s | 0-1 a run | 8-9, 1.99-2.02 s |
| 57600, 1-4 (12) | 2.52-4.64 s (2-16) | 0.63-2.19 / 0.65-2.27 s | 0-1 | 9-10, 1.03-2.02 s |
| 115200, 11 (6) | 1.75-1.78 s (3-4) | 1.98-3.50 / 0.51-2.07 s | 0 | 10, 1.01-1.02 s |
| 115200, 1-4 (12) | 1.76-3.84 s (2-14) | 0.49-3.48 / 0.50-0.53 s | 0-1 | 9-10, 1.01-2.02 s |
| 921600, 11 (6) | 1.14-1.18 s (3) | 1.83-3.48 / 0.35-0.42 s | 0-1 | 9, 1.98-2.00 s |
| 921600, 1-4 (12) | 1.14-3.23 s (2-20) | 0.35-1.95 / 0.34-0.43 s | 0-1 | 9-10, 1.01-2.01 s |

A list takes the line's time, plus 1 s of quiet and a round of re-reads (each further round another
~1.05 s); a mission transfer loses 1.5 s to each frame lost on it. Bounds (s of wall time): PARAMS_S 7 / 6
/ 6 s at 57600 / 115200 / 921600 (about four rounds of re-reads), MISSION_S 6 s each way (three frames
lost on one transfer). About 65 s of wall time for the three."""

import argparse
import itertools
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from sitl_harness import binary, start_sitl, stop_group

os.environ["MAVLINK20"] = "1"  # pymavlink speaks MAVLink 1 unless told otherwise
from pymavlink import mavutil

mavlink = mavutil.mavlink

GCS_SYSTEM, GCS_COMPONENT = 255, 190
RADIO_SYSTEM, RADIO_COMPONENT = 51, 68  # a SiK radio's own ids
AUTOPILOT_VERSION = 148
COMMAND_RESEND_S = 1.5
COMMAND_ACK_LIMIT_S = 10.0
# What the transfers wait for (kept in order for `Gcs.next`).
TRANSFER_KINDS = (
    "PARAM_VALUE",
    "MISSION_COUNT",
    "MISSION_REQUEST",
    "MISSION_REQUEST_INT",
    "MISSION_ITEM_INT",
    "MISSION_ACK",
)
PARAM_QUIET_S = 1.0
MISSION_RESEND_S = 1.5
MISSION_ITEMS = 20
STREAM_WINDOW_S = 10.0
# The largest MAVLink 2 frame: the pacer's bucket.
MAX_FRAME_BYTES = 280
# The line of the asserted runs.
LOSS_PCT = 1.0
BURST_BYTES = 32
SEED = 11
# Bounds on the transfers (s of wall time) with that line; see the module's docstring.
PARAMS_S = {57600: 7.0, 115200: 6.0, 921600: 6.0}
MISSION_S = 6.0


@dataclass
class Line:
    """`sitl line`: the autopilot's end A, the ground station's end B, the counters in `stats_path`."""

    proc: subprocess.Popen
    a: Path
    b: Path
    stats_path: Path
    log_path: Path

    def stop(self):
        stop_group(self.proc)

    def stats(self):
        """The last counters written (the final ones once stopped), or None before the first."""
        try:
            return json.loads(self.stats_path.read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            return None


def start_line(tmp_path, baud, loss_pct=LOSS_PCT, burst=BURST_BYTES, seed=SEED):
    """`sitl line` between the autopilot (end A) and the ground station (end B) at `baud`, losing `loss_pct`
    % of the bytes in runs of `burst`, the draws seeded with `seed`; returned once it says it is ready."""
    a, b = tmp_path / f"line-a-{baud}", tmp_path / f"line-b-{baud}"
    stats_path, log_path = tmp_path / f"line-{baud}.json", tmp_path / f"line-{baud}.log"
    args = [
        str(binary("sitl")),
        "line",
        *("--link-a", str(a), "--link-b", str(b), "--baud", str(baud)),
        *("--loss", str(loss_pct), "--burst", str(burst), "--seed", str(seed), "--stats", str(stats_path)),
    ]
    with open(log_path, "w") as stderr:
        proc = subprocess.Popen(
            args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr, start_new_session=True
        )
    line = Line(proc, a, b, stats_path, log_path)
    deadline = time.monotonic() + 10
    while not (a.exists() and b.exists() and "sitl line: A " in log_path.read_text()):
        if time.monotonic() > deadline or proc.poll() is not None:
            line.stop()
            pytest.fail(f"`sitl line` did not start: {log_path.read_text()}")
        time.sleep(0.05)
    return line


@dataclass
class Received:
    wall_s: float
    kind: str
    nbytes: int
    time_boot_ms: int | None
    seq: int  # the link's frame sequence number


@dataclass
class Pending:
    """A COMMAND_LONG waiting for its ACK."""

    params: tuple
    sent_s: float
    first_s: float
    resends: int = 0


@dataclass
class Acked:
    command: int
    total_s: float  # from the first send
    last_s: float  # from the send it answered (the last one)
    resends: int


@dataclass
class Gcs:
    """pymavlink on end B: everything the vehicle sends is recorded (arrival, size, vehicle time, link
    sequence number); a GCS HEARTBEAT goes once a second; commands are resent after 1.5 s without their ACK
    (one of each command id at a time, as QGroundControl queues them); the line's counters are sampled."""

    conn: Any
    sysid: int
    line: Line | None = None
    start_s: float = field(default_factory=time.monotonic)
    received: list[Received] = field(default_factory=list)
    now_ms: int = 0
    last_heartbeat_s: float = -1.0
    pending: dict[int, Pending] = field(default_factory=dict)
    queued: list[tuple[int, tuple]] = field(default_factory=list)
    acked: list[Acked] = field(default_factory=list)
    messages: list = field(default_factory=list)  # the vehicle's messages other than streams, for the waits
    line_samples: list[tuple[float, int, int]] = field(default_factory=list)  # (elapsed, A->B out, B->A out)
    last_sample_s: float = -1.0

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
        if self.line is not None and now - self.last_sample_s >= 0.2:
            self.last_sample_s = now
            s = self.line.stats()
            if s is not None and (not self.line_samples or s["elapsed_s"] > self.line_samples[-1][0]):
                self.line_samples.append((s["elapsed_s"], s["a_to_b"]["bytes_out"], s["b_to_a"]["bytes_out"]))
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
        self.received.append(Received(self.wall_s(), kind, len(msg.get_msgbuf()), t, msg.get_seq()))
        if kind == "COMMAND_ACK" and msg.command in self.pending:
            p = self.pending.pop(msg.command)
            assert msg.result == mavlink.MAV_RESULT_ACCEPTED, f"command {msg.command}: result {msg.result}"
            now = time.monotonic()
            self.acked.append(Acked(msg.command, now - p.first_s, now - p.sent_s, p.resends))
            waiting = next((q for q in self.queued if q[0] == msg.command), None)
            if waiting is not None:
                self.queued.remove(waiting)
                self.start_command(*waiting)
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

    def start_command(self, command, params):
        if command in self.pending:
            self.queued.append((command, params))
            return
        now = time.monotonic()
        self.pending[command] = Pending(params, now, now)
        self.conn.mav.command_long_send(self.sysid, 1, command, 0, *params)

    def request_version(self):
        self.start_command(mavlink.MAV_CMD_REQUEST_MESSAGE, (float(AUTOPILOT_VERSION), *[0.0] * 6))

    def settle_commands(self):
        self.wait(COMMAND_ACK_LIMIT_S, "every COMMAND_LONG acknowledged", lambda: not self.pending and not self.queued)

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

    def line_peak_Bps(self):
        """The most bytes/s the line delivered each way (A to B, B to A) between two of its snapshots at
        least 1 s apart (the nearest such)."""
        peak = [0.0, 0.0]
        for i, (t0, a0, b0) in enumerate(self.line_samples):
            later = next((s for s in self.line_samples[i + 1 :] if s[0] - t0 >= 1.0), None)
            if later is not None:
                t1, a1, b1 = later
                peak = [max(peak[0], (a1 - a0) / (t1 - t0)), max(peak[1], (b1 - b0) / (t1 - t0))]
        return peak

    def attitude(self, from_ms, to_ms, period_ms=50):
        """ATTITUDE received with `time_boot_ms` in [from_ms, to_ms), expected every `period_ms` of vehicle
        time: (Hz received, gaps shorter than 0.9 periods: faster than expected, gaps of 1.5 periods or more
        with contiguous link sequence numbers within: not sent (thinned), such gaps with a sequence gap
        within: frames lost on the line; the link numbers only the frames it sends)."""
        seen = [
            (i, r.time_boot_ms)
            for i, r in enumerate(self.received)
            if r.kind == "ATTITUDE" and r.time_boot_ms is not None and from_ms <= r.time_boot_ms < to_ms
        ]
        faster = thinned = lost = 0
        for (i, t0), (j, t1) in itertools.pairwise(seen):
            if t1 - t0 < 0.9 * period_ms:
                faster += 1
            elif t1 - t0 >= 1.5 * period_ms:
                seqs = [r.seq for r in self.received[i : j + 1]]
                if all((b - a) % 256 == 1 for a, b in itertools.pairwise(seqs)):
                    thinned += 1
                else:
                    lost += 1
        return len(seen) * 1000.0 / (to_ms - from_ms), faster, thinned, lost

    def frames_lost_pct(self):
        """Of the frames the vehicle's link sent (by their sequence numbers, from the first received to the
        last), the percentage not received whole: lost on the line, or with their neighbours by the parser
        (a frame cut short is read to its declared length, taking the next frame's start with it)."""
        sent = 1 + sum((b.seq - a.seq) % 256 for a, b in itertools.pairwise(self.received))
        return 100.0 * (1 - len(self.received) / sent)

    def seq_gap_between(self, from_s, to_s):
        """Whether a frame the vehicle's link numbered is missing between the last frame received before
        `from_s` and the first received after `to_s` (arrival, wall time)."""
        inside = [r.seq for r in self.received if from_s <= r.wall_s <= to_s]
        before = [r.seq for r in self.received if r.wall_s < from_s][-1:]
        after = next(([r.seq] for r in self.received if r.wall_s > to_s), [])
        return any((b - a) % 256 != 1 for a, b in itertools.pairwise(before + inside + after))

    def heartbeats(self, window_s=STREAM_WINDOW_S):
        """The vehicle's HEARTBEATs as received: how many, the mean rate (Hz) from the first to the last, the
        fewest in any `window_s` window of arrival (windows every 1 s, starting half a second after the
        first, so that a beat's jitter does not move it out of a window aligned on it), the longest gap (s).
        Then what the gaps say: "off_grid", the gaps not within 0.25 s of a whole number of seconds (a late
        heartbeat); each missing heartbeat (a gap of k s holds k - 1) is "lost_on_line" when a frame of the
        vehicle's link sequence is missing within 0.25 s of its time (the heartbeat, or the frame before it
        that took it along in the parser), else "not_sent"; "fewest_sent", the fewest per window counting
        the ones lost on the line."""
        beats = [r.wall_s for r in self.received if r.kind == "HEARTBEAT"]
        assert len(beats) > 1, "no HEARTBEATs"
        gaps = [b - a for a, b in itertools.pairwise(beats)]
        off_grid = [round(g, 2) for g in gaps if abs(g - round(g)) > 0.25 or round(g) == 0]
        lost: list[float] = []
        not_sent = 0
        for a, g in zip(beats, gaps, strict=False):
            for m in range(1, round(g)):
                if self.seq_gap_between(a + m - 0.25, a + m + 0.25):
                    lost.append(a + m)
                else:
                    not_sent += 1

        def fewest(times):
            least, t = len(times), beats[0] + 0.5
            while t + window_s <= self.wall_s():
                least = min(least, sum(1 for b in times if t <= b < t + window_s))
                t += 1.0
            return least

        return {
            "received": len(beats),
            "hz": round((len(beats) - 1) / (beats[-1] - beats[0]), 3),
            "fewest_10s": fewest(beats),
            "longest_gap_s": round(max(gaps), 2),
            "off_grid": off_grid,
            "lost_on_line": len(lost),
            "not_sent": not_sent,
            "fewest_sent_10s": fewest(sorted(beats + lost)),
        }


def fetch_params(gcs):
    """PARAM_REQUEST_LIST (resent while no value comes for 1 s), then, each time the list has been quiet for
    1 s, PARAM_REQUEST_READ by index for every missing value; a COMMAND_LONG sent right after the request.
    Returns (seconds to the last value, count, reads by index, list requests resent)."""
    start = time.monotonic()
    gcs.conn.mav.param_request_list_send(gcs.sysid, 1)
    gcs.request_version()
    values: dict[int, float] = {}
    count = None
    reads = list_resends = rounds = 0
    last = start
    while count is None or len(values) < count:
        msg = gcs.next(PARAM_QUIET_S, lambda m: m.get_type() == "PARAM_VALUE")
        if msg is not None:
            if msg.param_index < msg.param_count:
                count = msg.param_count
                values[msg.param_index] = msg.param_value
                last = time.monotonic()
            continue
        if count is None:
            list_resends += 1
            assert list_resends <= 5, "no PARAM_VALUE at all"
            gcs.conn.mav.param_request_list_send(gcs.sysid, 1)
            continue
        rounds += 1
        assert rounds <= 8, f"{len(values)} of {count} parameters after {rounds - 1} rounds of reads"
        for index in range(count):
            if index not in values:
                gcs.conn.mav.param_request_read_send(gcs.sysid, 1, b"", index)
                reads += 1
    return last - start, count, reads, list_resends


def mission_items(sysid, lat_e7, lon_e7):
    """NAV_TAKEOFF, 18 waypoints on a 20 m circle, NAV_LAND, at 10 m relative: every field of each
    MISSION_ITEM_INT as this ground station sends it to vehicle `sysid`."""
    rel = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    dlat_per_m = 1e7 / 111_319.5
    dlon_per_m = dlat_per_m / math.cos(math.radians(lat_e7 / 1e7))
    points = [(mavlink.MAV_CMD_NAV_TAKEOFF, (0.0, 0.0, 0.0, 0.0), lat_e7, lon_e7, 10.0)]
    for k in range(MISSION_ITEMS - 2):
        a = 2 * math.pi * k / (MISSION_ITEMS - 2)
        x = lat_e7 + round(20 * math.cos(a) * dlat_per_m)
        y = lon_e7 + round(20 * math.sin(a) * dlon_per_m)
        points.append((mavlink.MAV_CMD_NAV_WAYPOINT, (0.0, 1.0, 0.0, 0.0), x, y, 10.0))
    points.append((mavlink.MAV_CMD_NAV_LAND, (0.0, 0.0, 0.0, 0.0), lat_e7, lon_e7, 0.0))
    return [
        {
            "target_system": sysid,
            "target_component": 1,
            "seq": seq,
            "frame": rel,
            "command": command,
            "current": 0,
            "autocontinue": 1,
            **{f"param{k + 1}": p for k, p in enumerate(params)},
            "x": x,
            "y": y,
            "z": z,
            "mission_type": mavlink.MAV_MISSION_TYPE_MISSION,
        }
        for seq, (command, params, x, y, z) in enumerate(points)
    ]


def read_back_expected(items):
    """What the vehicle sends back for `items`: the same fields, to this ground station, with `current` on
    item 0 (the current item of a new mission)."""
    return [
        {**item, "target_system": GCS_SYSTEM, "target_component": GCS_COMPONENT, "current": int(item["seq"] == 0)}
        for item in items
    ]


def send_item(gcs, item):
    gcs.conn.mav.send(mavlink.MAVLink_mission_item_int_message(**item))


def upload(gcs, items):
    """MISSION_COUNT, answering each MISSION_REQUEST(_INT) (the vehicle re-requests on its own time-out), to
    MISSION_ACK; MISSION_COUNT resent after 1.5 s without any request, the last item after 1.5 s without
    the ACK. Returns (seconds, resends by the ground station, the vehicle's re-requests: requests that came
    1 s or more after the ground station last sent anything of the upload, which only the vehicle's 1.5 s
    time-out makes, whether its request or the item before it was lost)."""
    start = time.monotonic()
    gcs.request_version()
    gcs.conn.mav.mission_count_send(gcs.sysid, 1, len(items), mavlink.MAV_MISSION_TYPE_MISSION)
    last_sent = time.monotonic()
    requested: set[int] = set()
    resends = rerequests = silences = 0
    kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
    while True:
        msg = gcs.next(MISSION_RESEND_S, lambda m: m.get_type() in kinds)
        if msg is None:
            silences += 1
            assert silences <= 8, f"mission upload: silent for 8 waits after requests for {sorted(requested)}"
            if not requested:
                gcs.conn.mav.mission_count_send(gcs.sysid, 1, len(items), mavlink.MAV_MISSION_TYPE_MISSION)
                resends, last_sent = resends + 1, time.monotonic()
            elif len(items) - 1 in requested:
                send_item(gcs, items[-1])
                resends, last_sent = resends + 1, time.monotonic()
            continue
        if msg.get_type() == "MISSION_ACK":
            assert msg.type == mavlink.MAV_MISSION_ACCEPTED, f"mission refused: {msg.type}"
            return time.monotonic() - start, resends, rerequests
        silences = 0
        if time.monotonic() - last_sent >= 1.0:
            rerequests += 1
        requested.add(msg.seq)
        send_item(gcs, items[msg.seq])
        last_sent = time.monotonic()


def download(gcs):
    """MISSION_REQUEST_LIST, MISSION_REQUEST_INT for each item (each resent after 1.5 s without its answer),
    MISSION_ACK. Returns (every field of each item, seconds, resends)."""
    start = time.monotonic()
    gcs.request_version()
    resends = tries = 0
    count = None
    while count is None:
        gcs.conn.mav.mission_request_list_send(gcs.sysid, 1, mavlink.MAV_MISSION_TYPE_MISSION)
        msg = gcs.next(MISSION_RESEND_S, lambda m: m.get_type() == "MISSION_COUNT")
        if msg is None:
            resends, tries = resends + 1, tries + 1
            assert tries <= 8, "mission download: no MISSION_COUNT"
        else:
            count = msg.count
    items = []
    for seq in range(count):
        tries = 0
        while True:
            gcs.conn.mav.mission_request_int_send(gcs.sysid, 1, seq, mavlink.MAV_MISSION_TYPE_MISSION)
            msg = gcs.next(MISSION_RESEND_S, lambda m, s=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == s)
            if msg is not None:
                fields = msg.to_dict()
                del fields["mavpackettype"]
                items.append(fields)
                break
            resends, tries = resends + 1, tries + 1
            assert tries <= 8, f"mission download: no item {seq}"
    gcs.conn.mav.mission_ack_send(gcs.sysid, 1, mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_TYPE_MISSION)
    return items, time.monotonic() - start, resends


def settle(gcs):
    """Every command acknowledged (within 10 s)."""
    gcs.settle_commands()
    return ()


def pump_for(gcs, seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        gcs.pump()


def fresh_line_lost_b_to_a(gcs):
    """The line's B-to-A lost bytes from a snapshot taken after this call began (waits for the next one)."""
    assert gcs.line is not None
    first = gcs.line.stats()
    while True:
        s = gcs.line.stats()
        if s is not None and (first is None or s["elapsed_s"] > first["elapsed_s"]):
            return s["b_to_a"]["lost"]
        gcs.pump(timeout=0.01)


def radio_phase(gcs):
    """3 s for the streams to recover from the transfers, then txbuf 20 (again a second later, at most
    twice, only if it did not halve ATTITUDE and the line lost bytes toward the vehicle meanwhile), then 40
    (hold) once a second for 3 s, then 100 once a second for 7 s. Returns a dict: the ATTITUDE rates (Hz of
    vehicle time) and thinned gaps over the 2 s before the report that halved it, from 1 s to 4 s after
    it, and over the last 2 s; the vehicle time (ms) from that report to the first of the ATTITUDEs 90 ms
    or more apart from then to 4 s after it; the reports of txbuf 20 sent again."""
    pump_for(gcs, 3.0)
    repeats = 0
    while True:
        lost_before = fresh_line_lost_b_to_a(gcs)
        v0 = gcs.now_ms
        gcs.radio_status(20)
        pump_for(gcs, 1.0)
        spaced = [
            r.time_boot_ms
            for r in gcs.received
            if r.kind == "ATTITUDE" and r.time_boot_ms is not None and r.time_boot_ms >= gcs.now_ms - 450
        ]
        if len(spaced) >= 3 and all(b - a >= 90 for a, b in itertools.pairwise(spaced)):
            break
        lost_after = fresh_line_lost_b_to_a(gcs)
        assert lost_after > lost_before, "RADIO_STATUS txbuf 20 crossed the line whole and ATTITUDE did not halve"
        repeats += 1
        assert repeats <= 2, "RADIO_STATUS txbuf 20 lost three times"
    for txbuf in [40, 40, 40, 100, 100, 100, 100, 100, 100, 100]:
        gcs.radio_status(txbuf)
        pump_for(gcs, 1.0)
    attitude = sorted(
        r.time_boot_ms
        for r in gcs.received
        if r.kind == "ATTITUDE" and r.time_boot_ms is not None and v0 <= r.time_boot_ms < v0 + 4000
    )
    short = [k for k in range(1, len(attitude)) if attitude[k] - attitude[k - 1] < 90]
    halved_from = short[-1] + 1 if short else 1
    halved_after_ms = attitude[halved_from] - v0 if halved_from < len(attitude) else math.inf
    return {
        "before": gcs.attitude(v0 - 2000, v0),
        "halved": gcs.attitude(v0 + 1000, v0 + 4000, period_ms=100),
        "back": gcs.attitude(gcs.now_ms - 2000, gcs.now_ms),
        "halved_after_ms": halved_after_ms,
        "repeats": repeats,
    }


def session(tmp_path, baud, radio, loss_pct=LOSS_PCT, burst=BURST_BYTES, seed=SEED, strict=True):
    """One `sitl run` with its serial link on a `baud` line; returns what was measured. Not `strict` (to
    measure a line too lossy for the test), a transfer that fails is recorded in "failures" and the session
    goes on."""
    line = start_line(tmp_path, baud, loss_pct, burst, seed)
    config = tmp_path / "autopilot.toml"
    config.write_text(f'[gcs]\nserial = "{line.a}:{baud}"\n')
    try:
        sitl = start_sitl(tmp_path, "--autopilot-config", str(config), speed=1)
    except BaseException:
        line.stop()
        raise
    r: dict[str, Any] = {"baud": baud, "line": f"loss {loss_pct} % in bursts of {burst} B, seed {seed}"}
    failures: list[str] = []

    def phase(name, run, *args):
        try:
            r.update(zip(name, run(*args), strict=True))
        except AssertionError as e:
            if strict:
                raise
            failures.append(f"{name[0] if name else run.__name__}: {e}")

    try:
        conn = mavutil.mavlink_connection(
            str(line.b), baud=baud, source_system=GCS_SYSTEM, source_component=GCS_COMPONENT
        )
        gcs = Gcs(conn, sitl.instance + 1, line)
        gcs.wait(30.0, "the vehicle's HEARTBEAT and timed telemetry on the line", lambda: gcs.now_ms > 0)
        # The streams alone.
        stream_start = gcs.wall_s()
        pump_for(gcs, STREAM_WINDOW_S)
        streams = [x for x in gcs.received if x.wall_s >= stream_start]
        r["stream_Bps"] = round(sum(x.nbytes for x in streams) / STREAM_WINDOW_S)
        r["attitude"] = gcs.attitude(gcs.now_ms - 8000, gcs.now_ms)
        position = gcs.conn.messages.get("GPS_RAW_INT")
        assert position is not None, "no GPS_RAW_INT within the stream window"
        phase(("params_s", "params", "param_reads", "param_list_resends"), fetch_params, gcs)
        items = mission_items(gcs.sysid, position.lat, position.lon)
        r["mission_sent"] = items
        phase(("upload_s", "upload_resends", "upload_rerequests"), upload, gcs, items)
        phase(("mission_back", "download_s", "download_resends"), download, gcs)
        r["mission_same"] = r.get("mission_back") == read_back_expected(items)
        for _ in range(3):
            gcs.request_version()
            phase((), settle, gcs)
        phase((), settle, gcs)
        r["radio"] = radio_phase(gcs) if radio else None
        r["heartbeat"] = gcs.heartbeats()
        r["commands"] = len(gcs.acked)
        r["command_resends"] = sum(a.resends for a in gcs.acked)
        r["slowest_ack_s"] = round(max(a.last_s for a in gcs.acked), 3)
        r["slowest_command_s"] = round(max(a.total_s for a in gcs.acked), 2)
        r["worst_1s_B"] = gcs.bytes_per_window()
        r["frames_lost_pct"] = round(gcs.frames_lost_pct(), 2)
        r["line_peak_Bps"] = [round(x) for x in gcs.line_peak_Bps()]
        r["session_s"] = round(gcs.wall_s(), 1)
        conn.close()
    finally:
        sitl.stop()
        line.stop()
    wire = line.stats()
    assert wire is not None, "no stats from `sitl line`"
    r["line_stats"] = wire
    r["line_mean_Bps"] = [round(wire[d]["bytes_out"] / wire["elapsed_s"]) for d in ("a_to_b", "b_to_a")]
    r["failures"] = failures
    for k in ("params_s", "upload_s", "download_s"):
        if k in r:
            r[k] = round(r[k], 2)
    return r


def summary(r):
    """`r` without the missions' items (printed apart if they differ)."""
    return {k: v for k, v in r.items() if k not in ("mission_back", "mission_sent")}


@pytest.mark.parametrize("baud", [57600, 115200, 921600])
def test_a_ground_station_over_a_lossy_radio_line_gets_heartbeats_acks_parameters_and_missions(tmp_path, baud):
    r = session(tmp_path, baud, radio=baud == 57600)
    print(f"\n  radio line {summary(r)}", flush=True)
    data_rate = baud / 10
    wire = r["line_stats"]
    for d in ("a_to_b", "b_to_a"):
        assert wire[d]["overrun"] == 0, f"{d}: the reader fell behind"
    assert 0.4 <= 100 * wire["a_to_b"]["lost"] / wire["a_to_b"]["bytes_in"] <= 2.0, "the line's loss, to the GCS"
    assert max(r["line_peak_Bps"]) <= data_rate * 1.01, "the line delivered more than baud / 10"
    assert r["worst_1s_B"] <= data_rate * 1.05 + MAX_FRAME_BYTES, "more than baud / 10 received in 1 s"
    beats = r["heartbeat"]
    assert beats["off_grid"] == [] and beats["not_sent"] == 0, "a HEARTBEAT late or not sent"
    assert beats["fewest_sent_10s"] >= 9, "the vehicle's HEARTBEAT below 0.9 Hz in some 10 s window"
    assert beats["hz"] >= 0.8, "HEARTBEAT received below 0.8 Hz over the session"
    hz, _, thinned, _ = r["attitude"]
    assert thinned == 0 and hz >= 18.0, "the streams at their full rate"
    assert r["commands"] == 6, "every command acknowledged"
    assert r["slowest_ack_s"] < 0.5, "an ACK waited behind a transfer"
    if not r["mission_same"]:
        pytest.fail(f"the mission read back differs:\n{r['mission_back']}\nsent:\n{r['mission_sent']}")
    assert r["params"] >= 200 and r["params_s"] < PARAMS_S[baud], "the parameter list took too long"
    assert r["upload_s"] < MISSION_S and r["download_s"] < MISSION_S, "a mission transfer took too long"
    if r["radio"] is not None:
        radio = r["radio"]
        assert radio["before"][2] == 0 and radio["before"][0] >= 15.0, "20 Hz before the report"
        assert radio["halved_after_ms"] <= 1000, "halved within 1 s of vehicle time"
        hz, faster, thinned, _ = radio["halved"]
        assert faster == 0 and thinned == 0 and hz >= 8.0, "10 Hz from 1 s to 4 s after the report"
        assert radio["back"][2] == 0 and radio["back"][0] >= 15.0, "20 Hz again after txbuf 100"


def main():
    """Measure sessions without asserting: `python tests/test_radio_link.py --baud 57600 --burst 1`."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--baud", type=int, default=57600)
    parser.add_argument("--loss", type=float, default=LOSS_PCT)
    parser.add_argument("--burst", type=int, default=BURST_BYTES)
    parser.add_argument("--seeds", type=int, nargs="+", default=[SEED])
    parser.add_argument("--radio", action="store_true", help="with the RADIO_STATUS phase")
    args = parser.parse_args()
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            r = session(Path(tmp), args.baud, args.radio, args.loss, args.burst, seed, strict=False)
        print("result", json.dumps(summary(r)), flush=True)


if __name__ == "__main__":
    sys.exit(main())
