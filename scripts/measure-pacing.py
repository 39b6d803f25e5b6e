#!/usr/bin/env python3
"""Measures, from outside as a ground station does, how vehicle time follows wall time over the first
seconds of a `sitl run`: starts it (fresh process each time), listens on the instance's API port
14540+N with a plain UDP socket and pymavlink's parser, and reads `time_boot_ms` of every ATTITUDE,
LOCAL_POSITION_NED and SYSTEM_TIME against this process's monotonic clock.

Per start it prints one JSON line:
  spawn_to_banner_s  the startup line ("sitl: instance N running ...") after the spawn
  banner_to_first_s  the vehicle's first message after the startup line
  first_ms           time_boot_ms of that first message
  ratio_first        vehicle time / wall time over WINDOW s of wall time from the first message (the
                     acceptance measure; endpoints are the earliest-arriving samples, see below)
  ratio_banner       vehicle time / wall time since the startup line, at WINDOW s after it (the
                     vehicle's clock starts at 0, so the start-up delay counts against it)
  max_lag_ms, max_lead_ms  the largest wall-minus-vehicle and vehicle-minus-wall excursion in the window
  worst_1s           the lowest and highest ratio over any 1 s of wall time in the window

A sample's arrival is late by the delivery delay (the receiver may be descheduled); the end points are
taken as the minimum of (arrival - vehicle time) over the first and the last 0.25 s of the window, so a
late read at either end does not bias the ratio. With no sample in the last 0.25 s (a stall at the
end), the end is the window's end and the vehicle time last heard.

Usage: measure-pacing.py --sitl target/release/sitl --runs 20 [--window 10] [-- extra sitl run args]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time

from pymavlink.dialects.v20 import common as mavlink2


def measure(sitl: str, instance: int, window_s: float, extra: list[str]) -> dict[str, object]:
    api_port = 14540 + instance if instance < 10 else 14541 + instance
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    sock.bind(("127.0.0.1", api_port))
    sock.settimeout(0.05)
    args = [sitl, "run", *(["-i", str(instance)] if instance else []), *extra]
    spawn = time.monotonic()
    proc = subprocess.Popen(args, stderr=subprocess.PIPE, text=True, start_new_session=True)
    banner: list[float] = []
    lines: list[str] = []

    def read_stderr() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append(line.rstrip())
            if line.startswith("sitl: instance") and not banner:
                banner.append(time.monotonic())

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    samples: list[tuple[float, int]] = []  # (arrival monotonic s, time_boot_ms)
    sysid = instance + 1
    try:
        deadline = spawn + 60.0
        while time.monotonic() < deadline:
            if samples and time.monotonic() - samples[0][0] > window_s + 0.5:
                break
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            now = time.monotonic()
            for msg in parser.parse_buffer(data) or []:
                if msg.get_srcSystem() != sysid:
                    continue
                if msg.get_type() in ("ATTITUDE", "LOCAL_POSITION_NED", "SYSTEM_TIME"):
                    samples.append((now, int(msg.time_boot_ms)))
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        reader.join(2)
        sock.close()
    if not samples:
        return {"error": "no vehicle time", "stderr": lines[-5:]}
    t0, ms0 = samples[0]
    win = [(t - t0, (ms - ms0) * 1e-3) for t, ms in samples if t - t0 <= window_s]
    head = [w - v for w, v in win if w <= 0.25]
    tail = [w - v for w, v in win if w >= window_s - 0.25]
    # offset = wall - vehicle; the earliest arrival has the smallest offset.
    off0 = min(head)
    if tail:
        off1 = min(tail)
        end_vehicle = max(v for w, v in win if w >= window_s - 0.25)
        ratio_first = end_vehicle / (end_vehicle + off1 - off0)
    else:
        # Nothing in the window's last 0.25 s: the vehicle's clock as last heard, at the window's end.
        ratio_first = max(v for _, v in win) / (window_s - off0)
    lags = [w - v - off0 for w, v in win]
    worst = []
    for k in range(int(window_s)):
        seg = [(w, v) for w, v in win if k <= w <= k + 1]
        if len(seg) > 2:
            (wa, va), (wb, vb) = seg[0], seg[-1]
            if wb > wa:
                worst.append((vb - va) / (wb - wa))
    out: dict[str, object] = {
        "first_ms": ms0,
        "ratio_first": round(ratio_first, 4),
        "max_lag_ms": round(1e3 * max(lags), 1),
        "max_lead_ms": round(-1e3 * min(lags), 1),
        "worst_1s": [round(min(worst), 3), round(max(worst), 3)] if worst else None,
        "samples": len(win),
    }
    if banner:
        b = banner[0]
        out["spawn_to_banner_s"] = round(b - spawn, 3)
        out["banner_to_first_s"] = round(t0 - b, 3)
        at = [(t, ms) for t, ms in samples if window_s - 0.25 <= t - b <= window_s]
        if at:
            # The sample of the window's last 0.25 s that arrived earliest for its vehicle time.
            t, ms = min(at, key=lambda s: s[0] - s[1] * 1e-3)
            out["ratio_banner"] = round(ms * 1e-3 / (t - b), 4)
    summary = [line for line in lines if "sim s in" in line]
    if summary:
        out["summary"] = summary[-1][:160]
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sitl", default="target/release/sitl")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--window", type=float, default=10.0)
    ap.add_argument("-i", "--instance", type=int, default=0)
    ap.add_argument("--label", default="")
    ap.add_argument("extra", nargs="*")
    a = ap.parse_args()
    ratios: list[float] = []
    banner_ratios: list[float] = []
    for k in range(a.runs):
        # `{run}` in an argument is replaced by the run's number and a timestamp (a fresh --state-dir each).
        extra = [x.replace("{run}", f"{k}-{time.time_ns()}") for x in a.extra]
        r = measure(a.sitl, a.instance, a.window, extra)
        r["run"] = k
        r["label"] = a.label
        print(json.dumps(r), flush=True)
        if "ratio_first" in r:
            ratios.append(float(r["ratio_first"]))  # type: ignore[arg-type]
        if "ratio_banner" in r:
            banner_ratios.append(float(r["ratio_banner"]))  # type: ignore[arg-type]
        time.sleep(0.5)
    for name, xs in (("ratio_first", ratios), ("ratio_banner", banner_ratios)):
        if xs:
            print(
                f"# {a.label} {name}: n={len(xs)} min={min(xs):.4f} median={statistics.median(xs):.4f} "
                f"max={max(xs):.4f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
