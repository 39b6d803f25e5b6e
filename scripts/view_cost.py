#!/usr/bin/env python3
"""What the live view costs: CPU seconds per simulated second of `sitl run -n N` paced at real time, without
the view and with `--view web` (the bridge logging to Rerun and serving the web viewer, no browser open),
for each N; the difference per vehicle is the view's cost (the autopilots' view taps, the truth frames,
the forwarder and the bridge). A browser showing the view costs on top, in the browser.

Usage: scripts/view_cost.py [--vehicles 1,4] [--seconds 30] [--bin target/release]
Needs the release binaries (cargo build --release) and the .venv with rerun-sdk (scripts/test makes it).
Prints a Markdown table (docs/view.md quotes it)."""

import argparse
import os
import re
import resource
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]


def free_tcp_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tree_cpu_s(proc):
    """CPU seconds of `proc`, its waited-for children and its live descendants."""
    t = proc.cpu_times()
    total = t.user + t.system + t.children_user + t.children_system
    for child in proc.children(recursive=True):
        try:
            c = child.cpu_times()
            total += c.user + c.system
        except psutil.NoSuchProcess:
            pass
    return total


def children_cpu_s():
    """CPU seconds of this process's finished and waited-for children, and theirs."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(binary, vehicles, seconds, view, instance):
    """CPU seconds of one `sitl run -n vehicles --duration seconds`, and the frames its view dropped. Without
    the view: the finished run's (sitl and its autopilots). With `--view web`: counted when the run is over,
    before the served view is closed (sitl, its finished autopilots and the live bridge)."""
    args = [str(binary), "run", "-i", str(instance), "-n", str(vehicles), "--duration", str(seconds)]
    args += ["--speed", "1", "--state-dir", "off", "--no-ulog"]
    if view:
        args += ["--view", "web", "--view-web-port", str(free_tcp_port()), "--view-grpc-port", str(free_tcp_port())]
    before = children_cpu_s()
    with tempfile.TemporaryFile("w+") as log:
        p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=log, start_new_session=True, cwd=ROOT)
        proc = psutil.Process(p.pid)
        cpu = None
        deadline = time.monotonic() + seconds * 3 + 120
        while p.poll() is None and time.monotonic() < deadline:
            log.seek(0)
            if view and "the run ended" in log.read():
                cpu = tree_cpu_s(proc)
                os.killpg(p.pid, signal.SIGINT)
                break
            time.sleep(0.2)
        p.wait(60)
        log.seek(0)
        text = log.read()
    if cpu is None:
        if p.returncode != 0 or view:
            sys.exit(f"sitl run failed ({p.returncode}):\n{text[-3000:]}")
        cpu = children_cpu_s() - before
    dropped = re.search(r"dropped (\d+) of (\d+) frames", text)
    return cpu, (int(dropped.group(1)) if dropped else 0)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vehicles", default="1,4")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--bin", default=str(ROOT / "target" / "release"))
    args = ap.parse_args()
    binary = Path(args.bin) / "sitl"
    if not binary.exists():
        sys.exit(f"{binary}: build it first (cargo build --release)")
    rows = []
    for n in [int(v) for v in args.vehicles.split(",")]:
        plain, _ = run(binary, n, args.seconds, False, 150)
        viewed, dropped = run(binary, n, args.seconds, True, 150)
        rows.append((n, plain / args.seconds, viewed / args.seconds, dropped))
        print(f"n={n}: without {plain:.2f} s, with the view {viewed:.2f} s of CPU over {args.seconds:g} s", file=sys.stderr)
    print("| vehicles | CPU without the view (cores) | with `--view web` (cores) | the view, per vehicle (cores) | frames dropped |")
    print("|---:|---:|---:|---:|---:|")
    for n, plain, viewed, dropped in rows:
        print(f"| {n} | {plain:.3f} | {viewed:.3f} | {(viewed - plain) / n:.3f} | {dropped} |")
    if len(rows) >= 2:
        (n1, p1, v1, _), (n2, p2, v2, _) = rows[0], rows[-1]
        per = ((v2 - p2) - (v1 - p1)) / (n2 - n1)
        fixed = (v1 - p1) - per * n1
        print(
            f"\nThe view's cost as a fixed part and a part per vehicle (from {n1} and {n2} vehicles): "
            f"{fixed:.3f} cores plus {per:.3f} cores per vehicle."
        )


if __name__ == "__main__":
    main()
