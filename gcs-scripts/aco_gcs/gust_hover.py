"""Hover under a Beaufort-4 gust blown at run time (pymavlink): take off to --alt, hover --settle s, then
set the plant's SIM_ parameters (its own MAVLink component on UDP 19550+N) to blow a gust of --gust-speed
m/s toward --gust-dir deg (default 6.7 m/s toward east, 1 s 1-cos rise) for --gust-s s of vehicle time,
release it, hover --after s more and land. Plots the horizontal error from LOCAL_POSITION_NED against
vehicle time with the gust shaded, and reports the peak error and the recovery times (from onset and
from release until the error stays below --threshold). Exit 1 if the vehicle has not recovered from the
release by the end of the hover (or a step fails), 2 if no vehicle or no plant answers."""

import argparse
import re
import sys

from . import flight
from .link import Params, Plant, Vehicle, add_link_args, positive_float, run_main


def parser():
    p = argparse.ArgumentParser(
        prog="aco-gust-hover", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_link_args(p)
    p.add_argument("--alt", type=positive_float, default=1.5, help="hover height above home, m (default 1.5)")
    p.add_argument("--settle", type=positive_float, default=5.0, help="hover before the gust, s (default 5)")
    p.add_argument("--gust-s", type=positive_float, default=12.0, help="gust duration, s of vehicle time (default 12)")
    p.add_argument("--after", type=positive_float, default=15.0, help="hover after the release, s (default 15)")
    p.add_argument("--gust-speed", type=float, default=6.7, help="gust peak speed, m/s (default 6.7: Beaufort 4)")
    p.add_argument(
        "--gust-dir", type=float, default=90.0, help="direction the gust blows toward, deg (default 90: east)"
    )
    p.add_argument("--gust-rise", type=positive_float, default=1.0, help="1-cos rise and fall time, s (default 1)")
    p.add_argument("--threshold", type=positive_float, default=0.10, help="recovery threshold, m (default 0.10)")
    p.add_argument("--png", help="write the error plot to this PNG (default: no plot)")
    p.add_argument("--csv", help="write the error samples to this CSV (default: none)")
    return p


def recovery_s(samples, t0, t1, threshold):
    """Seconds from `t0` until the error stays below `threshold` up to `t1` (None if it never does)."""
    window = [(t, e) for (t, e) in samples if t0 <= t <= t1]
    if not window:
        return None
    last_bad = None
    for t, e in window:
        if e >= threshold:
            last_bad = t
    if last_bad is None:
        return 0.0
    if last_bad >= window[-1][0]:
        return None
    later = [t for (t, _) in window if t > last_bad]
    return later[0] - t0


def plant_time(texts, fallback):
    """The plant time in the plant's STATUSTEXT ("... t=12.34"), else `fallback`."""
    for text in reversed(texts):
        m = re.search(r"t=([0-9.]+)", text)
        if m:
            return float(m.group(1))
    return fallback


def run(args):
    vehicle = Vehicle.from_args(args)
    flight.say(f"vehicle: system {vehicle.system_id} on {vehicle.connect}")
    plant = Plant(args.instance, args.wall_limit)
    plant.hello()
    sim = Params(plant, plant.component)
    flight.say(f"plant: SIM_ parameters on udp 127.0.0.1:{plant.port} (system {plant.system_id})")
    ground, _ = flight.wait_ready(vehicle)
    hover, climb_s = flight.takeoff(vehicle, args.alt, ground)
    flight.say(f"at {args.alt:g} m after {climb_s:.1f} s; hovering {args.settle:g} s")

    samples = []  # (t_s, horizontal error m, n, e, d)

    def sample(t, pos, _vel):
        samples.append((t, flight.horizontal_error(pos, hover), pos[0], pos[1], pos[2]))

    gust_on = False
    try:
        flight.hold(vehicle, args.settle, sample)
        sim.require_set("SIM_GUST_SPD", args.gust_speed)
        sim.require_set("SIM_GUST_DIR", args.gust_dir % 360.0)
        sim.require_set("SIM_GUST_RISE", args.gust_rise)
        before = plant.now_s()
        sim.require_set("SIM_GUST_ON", 1)
        gust_on = True
        onset = plant_time(plant.texts_since(before), vehicle.now_s())
        flight.say(f"gust on at t={onset:.2f} s: {args.gust_speed:g} m/s toward {args.gust_dir:g} deg")
        flight.hold(vehicle, max(0.0, onset + args.gust_s - vehicle.now_s()), sample)
        before = plant.now_s()
        sim.require_set("SIM_GUST_ON", 0)
        gust_on = False
        release = plant_time(plant.texts_since(before), vehicle.now_s())
        flight.say(f"gust released at t={release:.2f} s; hovering {args.after:g} s")
        flight.hold(vehicle, max(0.0, release + args.after - vehicle.now_s()), sample)
    finally:
        if gust_on:
            sim.set("SIM_GUST_ON", 0)
    land_s = flight.land(vehicle)
    flight.say(f"landed and disarmed after {land_s:.1f} s")

    end = samples[-1][0]
    in_gust = [e for (t, e, *_rest) in samples if t >= onset]
    peak = max(in_gust) if in_gust else float("nan")
    steady = [e for (t, e, *_rest) in samples if release - 3.0 <= t < release]
    rec_onset = recovery_s([(t, e) for (t, e, *_r) in samples], onset, release, args.threshold)
    rec_release = recovery_s([(t, e) for (t, e, *_r) in samples], release, end, args.threshold)

    from .plot import figure, save, write_csv

    if args.csv:
        write_csv(
            args.csv,
            ["t_s", "err_xy_m", "north_m", "east_m", "down_m", "gust"],
            [(t, e, n, ea, d, int(onset <= t < release + args.gust_rise)) for (t, e, n, ea, d) in samples],
        )
    if args.png:
        fig, ax = figure(size=(9, 4.5))
        ax.plot([s[0] for s in samples], [s[1] for s in samples], lw=1.0, label="horizontal error")
        ax.axvspan(onset, release + args.gust_rise, color="tab:orange", alpha=0.2, label="gust (onset to end of fall)")
        ax.axhline(args.threshold, color="gray", ls="--", lw=0.8, label=f"{args.threshold:g} m")
        ax.set_xlabel("vehicle time (s)")
        ax.set_ylabel("horizontal error (m)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
        ax.set_title(f"Hover under a {args.gust_speed:g} m/s gust toward {args.gust_dir:g} deg (SIM_ parameters)")
        save(fig, args.png)

    def fmt(v):
        return "never" if v is None else f"{v:.2f} s"

    flight.say(f"peak horizontal error {peak:.3f} m")
    if steady:
        flight.say(f"steady error before release {sum(steady) / len(steady):.3f} m")
    flight.say(f"recovery below {args.threshold:g} m: from onset {fmt(rec_onset)}, from release {fmt(rec_release)}")
    for what, path in (("plot", args.png), ("error samples", args.csv)):
        if path:
            flight.say(f"wrote the {what} to {path}")
    if rec_release is None:
        print(f"no recovery below {args.threshold:g} m within {args.after:g} s of the release", file=sys.stderr)
        return 1
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
