"""Take off, hover, land (pymavlink): wait for the estimator, NAV_TAKEOFF to --alt, arm, hold --hold
seconds of vehicle time while measuring the largest distance from the hover point, land and wait for the
auto-disarm. Exit 1 if the hover error exceeds --max-error or any step fails, 2 if no vehicle answers.

The hover error: without --truth, of the vehicle's own estimate (LOCAL_POSITION_NED) from its ground
point + --alt, both from the same estimate, so the estimator's error does not show. With --truth, of the
plant's true position (SIM_STATE on the SITL plant's SIM_ port, 127.0.0.1:19550+N) from the commanded
point: the true position on the ground before the takeoff + --alt straight up; the estimate's figure is
printed too."""

import argparse
import math
import sys

from . import flight
from .link import PLANT_PARAM_PORT, PlantTruth, Vehicle, add_link_args, positive_float, run_main


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
    p.add_argument(
        "--truth",
        nargs="?",
        const="",
        metavar="DEVICE",
        help="grade the hover on the plant's truth (SIM_STATE) read from DEVICE (default, with --truth alone: "
        f"the instance's SIM_ port, udpout:127.0.0.1:{PLANT_PARAM_PORT}+N)",
    )
    return p


def truth_device(args):
    """The pymavlink device of --truth: as given, else the instance's SIM_ port."""
    return args.truth or f"udpout:127.0.0.1:{PLANT_PARAM_PORT + args.instance}"


def run(args):
    vehicle = Vehicle.from_args(args)
    flight.say(f"vehicle: system {vehicle.system_id} on {vehicle.connect}")
    truth = None
    if args.truth is not None:
        truth = PlantTruth(truth_device(args), vehicle.system_id)
        vehicle.listeners.append(lambda _msg: truth.drain())
    ground, converge_s = flight.wait_ready(vehicle)
    flight.say(
        f"estimator ready after {converge_s:.1f} s; ground at N {ground[0]:.3f} E {ground[1]:.3f} D {ground[2]:.3f} m"
    )
    hover_truth = None
    if truth is not None:
        # The commanded point in the truth: where the plant has the vehicle standing before it arms, + alt up.
        first_s = truth.wait_flowing(vehicle)
        ground_truth = truth.wait_at(vehicle, max(first_s, vehicle.now_s()))
        hover_truth = (ground_truth[0], ground_truth[1], ground_truth[2] - args.alt)
        flight.say(f"truth from {truth.connect} since t = {first_s:.2f} s")
    hover, climb_s = flight.takeoff(vehicle, args.alt, ground)
    flight.say(f"at {args.alt:g} m after {climb_s:.1f} s")
    worst = [0.0]

    def sample(_t, pos, _vel):
        worst[0] = max(worst[0], math.dist(pos, hover))

    hold_from_s = vehicle.now_s()
    flight.hold(vehicle, args.hold, sample)
    hold_to_s = vehicle.now_s()
    flight.say(f"hover error over {args.hold:g} s: max {worst[0]:.3f} m (the estimate, from its own ground point)")
    graded = worst[0]
    if truth is not None and hover_truth is not None:
        truth.wait_at(vehicle, hold_to_s)
        window = truth.window(hold_from_s, hold_to_s)
        expected = round((hold_to_s - hold_from_s) * 50)
        if len(window) < 0.9 * expected:
            flight.warn(f"{len(window)} truth samples in the hold, of {expected} sent: the rest were dropped")
        if not window:
            print("no truth sample in the hold", file=sys.stderr)
            return 1
        graded = max(math.dist(pos, hover_truth) for pos in window)
        flight.say(f"truth hover error over {args.hold:g} s: max {graded:.3f} m ({len(window)} samples)")
    land_s = flight.land(vehicle)
    flight.say(f"landed and disarmed after {land_s:.1f} s (vehicle time)")
    if graded > args.max_error:
        print(f"hover error {graded:.3f} m > {args.max_error:g} m", file=sys.stderr)
        return 1
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
