"""Synthetic live-view frames, the same stream the `sitl` binary writes to `aco_gcs.view`: for each source a
vehicle that arms on the ground, takes off to 2 m (Takeoff), then holds and circles slowly (Hold), with
truth and vehicle frames at `rate_hz`, the trajectory ahead at 5 Hz, a plan (home, a mission, a geofence,
a rally point) at 1 Hz, and an event at each mode change. For the tests and to measure the bridge:

    python -m aco_gcs.view_synth --seconds 60 | python -m aco_gcs.view --no-viewer --record /tmp/x.rrd
    python -m aco_gcs.view_synth --seconds 600 --pace | python -m aco_gcs.view --web
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Iterator
from typing import Any

TAKEOFF_AT_S = 1.0
CLIMB_S = 3.0
ALT_M = 2.0


def _state(t: float, k: int) -> tuple[list[float], list[float], list[float], list[float]]:
    """Source k's position, velocity, Euler angles and setpoint at time t (NED)."""
    north = 1.5 * k
    if t < TAKEOFF_AT_S:
        return [north, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [north, 0.0, 0.0]
    climb = min(1.0, (t - TAKEOFF_AT_S) / CLIMB_S)
    s = 0.5 - 0.5 * math.cos(math.pi * climb)
    d = -ALT_M * s
    vd = -ALT_M * 0.5 * math.pi / CLIMB_S * math.sin(math.pi * climb) if climb < 1 else 0.0
    w = 0.3
    hold = max(0.0, t - TAKEOFF_AT_S - CLIMB_S)
    n, e = north + 0.5 * math.sin(w * hold), 0.5 * (1 - math.cos(w * hold))
    vn, ve = 0.5 * w * math.cos(w * hold), 0.5 * w * math.sin(w * hold)
    yaw = 0.2 * math.sin(0.5 * t)
    euler = [0.03 * math.sin(2.1 * t), 0.04 * math.sin(1.7 * t), yaw]
    return [n, e, d], [vn, ve, vd], euler, [n + 0.05, e - 0.03, -ALT_M * min(1.0, climb * 1.2)]


def quat_of_euler(roll: float, pitch: float, yaw: float) -> list[float]:
    """Hamilton [w, x, y, z] of ZYX Euler angles (body FRD -> NED)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]


def frames(
    sources: list[str], seconds: float, rate_hz: float = 50.0, title: str = "synthetic"
) -> Iterator[dict[str, Any]]:
    """The frames of `seconds` of flight of every source, in time order (meta first)."""
    yield {"kind": "meta", "src": sources[0], "t_us": 0, "title": title, "sources": sources, "rate_hz": rate_hz}
    step_us = round(1e6 / rate_hz)
    modes: dict[str, str] = {}
    for i in range(int(seconds * rate_hz) + 1):
        t_us = i * step_us
        t = t_us / 1e6
        for k, src in enumerate(sources):
            pos, vel, euler, sp = _state(t, k)
            q = quat_of_euler(*euler)
            mode = "Hold" if t < TAKEOFF_AT_S else ("Takeoff" if t < TAKEOFF_AT_S + CLIMB_S else "Hold")
            if modes.get(src) != mode:
                modes[src] = mode
                yield {"kind": "event", "src": src, "t_us": t_us, "severity": 6, "text": f"Mode: {mode}"}
            if i % round(rate_hz) == 0:
                yield {
                    "kind": "plan",
                    "src": src,
                    "t_us": t_us,
                    "home_ned_m": [1.5 * k, 0.0, 0.0],
                    "mission_ned_m": [[1.5 * k, 0.0, -2.0], [1.5 * k + 4, 0.0, -2.0], [1.5 * k + 4, 4.0, -3.0]],
                    "mission_current": 1,
                    "fence_polygons_ne_m": [[[-10, -10], [10, -10], [10, 10], [-10, 10]]] if k == 0 else [],
                    "fence_circles_ne_m": [[0.0, 0.0, 12.0]] if k == 0 else [],
                    "fence_max_alt_m": 5.0 if k == 0 else None,
                    "rally_ned_m": [[-3.0, 2.0 + k, 0.0]],
                }
            if i % max(1, round(rate_hz / 5)) == 0:
                ahead = [_state(t + 0.25 * j, k)[3] for j in range(1, 13)]
                yield {"kind": "ahead", "src": src, "t_us": t_us, "points_ned_m": ahead}
            yield {
                "kind": "truth",
                "src": src,
                "t_us": t_us,
                "pos_ned_m": pos,
                "q_ned_frd": q,
                "vel_ned_mps": vel,
                "euler_rad": euler,
                "wind_ned_mps": [1.0 + 0.3 * math.sin(0.4 * t), 0.5, 0.0],
            }
            est = [p + 0.02 * math.sin(3 * t + j) for j, p in enumerate(pos)]
            hover = 1500.0 if t >= TAKEOFF_AT_S else 1000.0
            yield {
                "kind": "vehicle",
                "src": src,
                "t_us": t_us,
                "armed": t >= TAKEOFF_AT_S,
                "mode": mode,
                "pos_ned_m": est,
                "vel_ned_mps": vel,
                "q_ned_frd": q,
                "euler_rad": euler,
                "sp_pos_ned_m": sp,
                "sp_euler_rad": [0.0, 0.0, 0.0],
                "pwm_us": [hover + 20 * math.sin(5 * t + m) for m in range(4)],
                "battery_v": 16.8 - 0.01 * t,
                "battery_pct": 100.0 - 0.05 * t,
                "telemetry": {
                    **{f"aco.w_t_{a}": 0.1 * math.sin(0.2 * t + j) for j, a in enumerate("ned")},
                    **{f"aco.b_t_{a}_mps2": 0.01 * t * (j + 1) for j, a in enumerate("ned")},
                    **{f"aco.c_r_{a}": 0.05 * math.cos(0.3 * t + j) for j, a in enumerate("xyz")},
                    **{f"aco.d_r_{a}_radps2": 0.02 * j for j, a in enumerate("xyz")},
                    **{f"aco.mass_est_{a}_kg": 1.5 for a in "ned"},
                    "aco.other": 1.0,
                },
            }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (default 60)")
    p.add_argument("--sources", default="v0", help="comma-separated source names (default v0)")
    p.add_argument("--rate", type=float, default=50.0, help="truth and vehicle frames per second (default 50)")
    p.add_argument("--pace", action="store_true", help="write in real time (else as fast as possible)")
    args = p.parse_args(argv)
    start = time.monotonic()
    out = sys.stdout
    try:
        for frame in frames(args.sources.split(","), args.seconds, args.rate):
            if args.pace:
                ahead = frame["t_us"] / 1e6 - (time.monotonic() - start)
                if ahead > 0:
                    out.flush()
                    time.sleep(ahead)
            out.write(json.dumps(frame) + "\n")
        out.flush()
    except BrokenPipeError:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
