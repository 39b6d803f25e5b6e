"""Take off, hover, land (pymavlink): wait for the estimator, NAV_TAKEOFF to --alt, arm, hold --hold
seconds of vehicle time while measuring the largest distance from the hover point (the vehicle's own
estimate, LOCAL_POSITION_NED), land and wait for the auto-disarm. Exit 1 if the hover error exceeds
--max-error or any step fails, 2 if no vehicle answers."""

import argparse
import math
import sys

from . import flight
from .link import Vehicle, add_link_args, positive_float, run_main


def parser():
    p = argparse.ArgumentParser(
        prog="aco-takeoff-hover-land",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_link_args(p)
    p.add_argument("--alt", type=positive_float, default=1.5, help="takeoff height above home, m (default 1.5)")
    p.add_argument("--hold", type=positive_float, default=10.0, help="hover time, s of vehicle time (default 10)")
    p.add_argument(
        "--max-error", type=positive_float, default=0.10, help="largest hover error that passes, m (default 0.10)"
    )
    return p


def run(args):
    vehicle = Vehicle.from_args(args)
    flight.say(f"vehicle: system {vehicle.system_id} on {vehicle.connect}")
    ground, converge_s = flight.wait_ready(vehicle)
    flight.say(
        f"estimator ready after {converge_s:.1f} s; ground at N {ground[0]:.3f} E {ground[1]:.3f} D {ground[2]:.3f} m"
    )
    hover, climb_s = flight.takeoff(vehicle, args.alt, ground)
    flight.say(f"at {args.alt:g} m after {climb_s:.1f} s")
    worst = [0.0]

    def sample(_t, pos, _vel):
        worst[0] = max(worst[0], math.dist(pos, hover))

    flight.hold(vehicle, args.hold, sample)
    flight.say(f"hover error over {args.hold:g} s: max {worst[0]:.3f} m")
    land_s = flight.land(vehicle)
    flight.say(f"landed and disarmed after {land_s:.1f} s (vehicle time)")
    if worst[0] > args.max_error:
        print(f"hover error {worst[0]:.3f} m > {args.max_error:g} m", file=sys.stderr)
        return 1
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
