#!/usr/bin/env python3
"""Measures `sitl line` from outside, as two processes on its ends see it (standard library only: the two
ends are opened raw with os/tty, no pyserial). Each measurement starts its own `sitl line` in a temporary
directory and prints one JSON line:

  throughput   a writer keeps end A full for --seconds s at --baud; bytes/s received at B between its first
               and last byte, against baud / 10; and the CPU time `sitl line` used meanwhile (utime +
               stime from /proc, so Linux only), as a percentage of one core
  idle_cpu     the CPU time of a `sitl line` that carries nothing, over --seconds s
  delay        one byte at a time A to B (the next one written once the last arrived), --samples of them:
               min / median / max of write-to-read time, at 115200 baud with no latency and with 100 ms
  loss         --loss-bytes bytes (i % 251) at 1 Mbaud with 1 % loss in bursts of 16: the fraction lost and
               the lengths of the lost runs (a run of 32 is two runs back to back)

Usage: measure-serial-line.py --sitl target/release/sitl [--seconds 10] [--samples 50] [--loss-bytes 1000000]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import select
import statistics
import subprocess
import tempfile
import threading
import time
import tty


class Line:
    """A `sitl line` between two raw ends, stopped (SIGTERM) on exit."""

    def __init__(self, sitl: str, *args: str):
        self.dir = tempfile.TemporaryDirectory()
        self.a_path, self.b_path = os.path.join(self.dir.name, "a"), os.path.join(self.dir.name, "b")
        self.stats_path = os.path.join(self.dir.name, "stats.json")
        self.stats = None
        self.proc = subprocess.Popen(
            [sitl, "line", "--link-a", self.a_path, "--link-b", self.b_path, "--stats", self.stats_path, *args],
            stderr=subprocess.PIPE,
        )
        self.ready = self.proc.stderr.readline().decode()
        assert self.ready.startswith("sitl line: A"), self.ready
        self.a, self.b = (os.open(p, os.O_RDWR | os.O_NOCTTY) for p in (self.a_path, self.b_path))
        for fd in (self.a, self.b):
            tty.setraw(fd)
            os.set_blocking(fd, False)

    def write_until(self, data: bytes, stop: float):
        """Write `data` into end A (once; over and over if `stop` is set) until it is all taken or `stop`."""
        view = memoryview(data)
        while view and time.monotonic() < stop:
            if select.select([], [self.a], [], 0.1)[1]:
                try:
                    view = view[os.write(self.a, view[:4096]):]
                except BlockingIOError:
                    pass
            if not view and stop != float("inf"):
                view = memoryview(data)

    def cpu_s(self) -> float:
        with open(f"/proc/{self.proc.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def __enter__(self):
        return self

    def __exit__(self, *_):
        os.close(self.a)
        os.close(self.b)
        self.proc.terminate()
        self.proc.communicate(timeout=30)
        with open(self.stats_path) as f:
            self.stats = json.load(f)
        self.dir.cleanup()


def throughput(sitl: str, baud: int, seconds: float) -> dict:
    with Line(sitl, "--baud", str(baud)) as line:
        stop = time.monotonic() + seconds
        writer = threading.Thread(target=line.write_until, args=(bytes(range(256)) * 16, stop))
        cpu0 = line.cpu_s()
        wall0 = time.monotonic()
        writer.start()
        first = last = None
        received = 0
        while time.monotonic() < stop:
            if not select.select([line.b], [], [], 0.1)[0]:
                continue
            n = len(os.read(line.b, 65536))
            now = time.monotonic()
            if first is None:
                first, first_n = now, n
            last = now
            received += n
        cpu = line.cpu_s() - cpu0
        wall = time.monotonic() - wall0
        writer.join()
        rate = (received - first_n) / (last - first)
        return {
            "measure": "throughput",
            "baud": baud,
            "bytes_per_s": round(rate, 1),
            "wire_bytes_per_s": baud / 10,
            "cpu_pct_of_one_core": round(100 * cpu / wall, 2),
        }


def idle_cpu(sitl: str, seconds: float) -> dict:
    with Line(sitl) as line:
        cpu0 = line.cpu_s()
        time.sleep(seconds)
        cpu_pct = 100 * (line.cpu_s() - cpu0) / seconds
        return {"measure": "idle_cpu", "seconds": seconds, "cpu_pct_of_one_core": round(cpu_pct, 3)}


def delay(sitl: str, latency_ms: float, samples: int) -> dict:
    with Line(sitl, "--baud", "115200", "--latency-ms", str(latency_ms)) as line:
        delays_ms = []
        for i in range(samples):
            t = time.monotonic()
            while not select.select([], [line.a], [], 10)[1]:
                pass
            os.write(line.a, bytes([i % 256]))
            assert select.select([line.b], [], [], 10)[0], "no byte"
            os.read(line.b, 16)
            delays_ms.append(1000 * (time.monotonic() - t))
            time.sleep(0.01)
        return {
            "measure": "delay",
            "baud": 115200,
            "latency_ms": latency_ms,
            "samples": samples,
            "min_ms": round(min(delays_ms), 3),
            "median_ms": round(statistics.median(delays_ms), 3),
            "max_ms": round(max(delays_ms), 3),
        }


def loss(sitl: str, total: int) -> dict:
    with Line(sitl, "--baud", "1000000", "--loss", "1", "--burst", "16") as line:
        sent = bytes(i % 251 for i in range(total))
        writer = threading.Thread(target=line.write_until, args=(sent, float("inf")))
        writer.start()
        got = bytearray()
        while True:
            if not select.select([line.b], [], [], 2.0)[0]:
                break  # nothing for 2 s: all that will come came
            got += os.read(line.b, 65536)
        writer.join()
        runs = collections.Counter()
        at = 0
        for byte in got:
            gap = (byte - at) % 251
            if gap:
                runs[gap] += 1
            at += gap + 1
        if at < total:
            runs[total - at] += 1
    return {
        "measure": "loss",
        "baud": 1000000,
        "loss_pct": 1,
        "burst_bytes": 16,
        "sent_bytes": total,
        "received_bytes": len(got),
        "lost_fraction": round(1 - len(got) / total, 5),
        "runs_by_length": dict(sorted(runs.items())),
        "line_stats_a_to_b": line.stats["a_to_b"],
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sitl", required=True)
    parser.add_argument("--seconds", type=float, default=10)
    parser.add_argument("--samples", type=int, default=50)
    parser.add_argument("--loss-bytes", type=int, default=1_000_000)
    args = parser.parse_args()
    print(json.dumps(idle_cpu(args.sitl, args.seconds)), flush=True)
    for baud in (115200, 921600):
        print(json.dumps(throughput(args.sitl, baud, args.seconds)), flush=True)
    for latency_ms in (0, 100):
        print(json.dumps(delay(args.sitl, latency_ms, args.samples)), flush=True)
    print(json.dumps(loss(args.sitl, args.loss_bytes)), flush=True)


if __name__ == "__main__":
    main()
