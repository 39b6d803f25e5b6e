"""Offboard square (MAVSDK-Python, classic API): connect, wait for health (global and home position ok,
armable), arm, take off to --alt, start offboard with PositionNedYaw setpoints and fly a square of --side
metres (north, then east, then back), stop offboard (the vehicle holds), land and wait for the disarm.
Exit 1 if a step fails, 2 if no vehicle connects.

Needs the SITL at real time: `sitl run` (its default; not `--speed 20` or `--speed max`). MAVSDK re-sends
the offboard setpoint at 20 Hz of wall time, while the vehicle's offboard timeout (0.5 s) runs on vehicle
time; sped up 20-30x the vehicle sees 0.5 s without a setpoint between two of MAVSDK's, and leaves
offboard. Every wait here is still measured on the vehicle's clock (ATTITUDE time_boot_ms, as MAVSDK's
attitude timestamp)."""

import argparse
import asyncio
import math
import sys
import time
import warnings

from .link import CheckFailed, NoVehicle, api_port, positive_float, run_main


def parser():
    p = argparse.ArgumentParser(
        prog="aco-offboard-square", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    from .link import add_link_args

    add_link_args(p, mavsdk=True)
    p.add_argument("--alt", type=positive_float, default=1.5, help="takeoff height above home, m (default 1.5)")
    p.add_argument("--side", type=positive_float, default=1.0, help="side of the square, m (default 1)")
    p.add_argument("--tolerance", type=positive_float, default=0.10, help="corner reached within, m (default 0.10)")
    p.add_argument(
        "--grpc-port",
        type=int,
        help="port of the mavsdk_server this script starts (default 50051+N, so several run at once)",
    )
    return p


class State:
    """The latest telemetry and the vehicle's clock (µs), kept by background subscriptions."""

    def __init__(self, wall_limit_s):
        self.now_us = 0
        self.health = None
        self.pos = None  # PositionVelocityNed
        self.yaw_deg = 0.0
        self.armed = False
        self.in_air = False
        self.mode = None
        self.deadline = time.monotonic() + wall_limit_s
        self.wall_limit_s = wall_limit_s

    def now_s(self):
        return self.now_us / 1e6

    async def wait_until(self, seconds, what, cond):
        """Until `cond()` holds, failing after `seconds` of vehicle time. Returns the seconds it took."""
        start = self.now_s()
        while not cond():
            if self.now_s() - start > seconds:
                raise CheckFailed(f"{what}: not within {seconds:g} s of vehicle time")
            if time.monotonic() > self.deadline:
                raise CheckFailed(f"{what}: wall-clock limit of {self.wall_limit_s:g} s reached")
            await asyncio.sleep(0.01)  # a polling interval, not a timed wait: the limits are vehicle time
        return self.now_s() - start


async def watch(stream, update):
    async for value in stream:
        update(value)


async def fly(args, drone, state):
    from mavsdk.action import ActionError
    from mavsdk.offboard import OffboardError, PositionNedYaw

    def say(text):
        print(text, flush=True)

    await state.wait_until(5.0, "the vehicle clock (ATTITUDE)", lambda: state.now_us > 0)
    t_wall, t_vehicle = time.monotonic(), state.now_s()
    flags = ("is_global_position_ok", "is_home_position_ok", "is_armable")
    try:
        await state.wait_until(
            30.0,
            "health: global position, home position, armable",
            lambda: state.health is not None and all(getattr(state.health, f) for f in flags) and state.pos is not None,
        )
    except CheckFailed as e:
        missing = [f for f in flags if state.health is None or not getattr(state.health, f)]
        raise CheckFailed(f"{e}; still false: {', '.join(missing) or 'none (no position yet)'}") from None
    wall = time.monotonic() - t_wall
    if wall > 0.5 and (state.now_s() - t_vehicle) / wall > 1.5:
        rate = (state.now_s() - t_vehicle) / wall
        print(
            f"warning: the vehicle runs at {rate:.0f}x real time; MAVSDK's offboard setpoints come on the wall "
            "clock and will time out: run `sitl run` at real time (without --speed, or --speed 1)",
            file=sys.stderr,
            flush=True,
        )
    ground_down = state.pos.position.down_m
    say(f"healthy at t={state.now_s():.1f} s; ground at D {ground_down:.3f} m")
    try:
        await drone.action.set_takeoff_altitude(args.alt)
        await drone.action.arm()
        await state.wait_until(2.0, "armed", lambda: state.armed)
        await drone.action.takeoff()
    except ActionError as e:
        raise CheckFailed(f"takeoff: {e}") from e
    target_down = ground_down - args.alt
    climb = await state.wait_until(
        20.0,
        f"climb to {args.alt:g} m",
        lambda: abs(state.pos.position.down_m - target_down) < 0.1 and abs(state.pos.velocity.down_m_s) < 0.1,
    )
    say(f"at {args.alt:g} m after {climb:.1f} s")

    p = state.pos.position
    n0, e0, yaw = p.north_m, p.east_m, state.yaw_deg
    corners = [(n0 + args.side, e0), (n0 + args.side, e0 + args.side), (n0, e0 + args.side), (n0, e0)]
    try:
        await drone.offboard.set_position_ned(PositionNedYaw(n0, e0, target_down, yaw))
        await drone.offboard.start()
        for k, (north, east) in enumerate(corners, 1):
            await drone.offboard.set_position_ned(PositionNedYaw(north, east, target_down, yaw))

            def near(n=north, e=east):
                q = state.pos.position
                return math.hypot(q.north_m - n, q.east_m - e) < args.tolerance and abs(q.down_m - target_down) < 0.15

            took = await state.wait_until(20.0, f"corner {k} of the square", near)
            if state.mode is not None and state.mode.name != "OFFBOARD":
                raise CheckFailed(f"the vehicle left offboard (now {state.mode.name}) on the way to corner {k}")
            say(f"corner {k} (N {north - n0:+.2f}, E {east - e0:+.2f}) m reached in {took:.1f} s")
        await drone.offboard.stop()
    except OffboardError as e:
        raise CheckFailed(f"offboard: {e}") from e
    try:
        await drone.action.land()
    except ActionError as e:
        raise CheckFailed(f"land: {e}") from e
    landed = await state.wait_until(30.0, "landed and disarmed", lambda: not state.in_air and not state.armed)
    say(f"landed and disarmed after {landed:.1f} s (vehicle time)")


async def run_async(args):
    with warnings.catch_warnings():
        # mavsdk 3.17.4 warns that the name moves to a new binding in 4.x; requirements.txt pins `mavsdk<4`,
        # the freeze that warning itself recommends.
        warnings.filterwarnings("ignore", message="The 'mavsdk' package has been renamed", category=FutureWarning)
        from mavsdk import System

    connect = args.connect or f"udpin://0.0.0.0:{api_port(args.instance)}"
    grpc_port = args.grpc_port or 50051 + args.instance
    drone = System(port=grpc_port)
    tasks = []
    try:

        async def connected():
            # mavsdk_server serves gRPC only once it has discovered a system: connect() itself waits for
            # the vehicle's first HEARTBEAT, so the time-out covers it too.
            await drone.connect(system_address=connect)
            async for c in drone.core.connection_state():
                if c.is_connected:
                    return

        try:
            await asyncio.wait_for(connected(), args.heartbeat_timeout)
        except TimeoutError:
            raise NoVehicle(
                f"no vehicle HEARTBEAT on {connect} within {args.heartbeat_timeout:g} s "
                f"(is `sitl run -i {args.instance}` running, at real time?)"
            ) from None
        print(f"vehicle connected on {connect}", flush=True)
        state = State(args.wall_limit)
        t = drone.telemetry

        def on_attitude(a):
            state.now_us = max(state.now_us, a.timestamp_us)
            state.yaw_deg = a.yaw_deg

        last_text: list = [None, 0]

        def on_text(s):
            # MAVSDK re-requests what the vehicle lacks, and the vehicle answers each time: print repeats once.
            if s.text == last_text[0]:
                last_text[1] += 1
                return
            if last_text[1]:
                print(f"  [vehicle] (the last message {last_text[1]} more times)", file=sys.stderr, flush=True)
            last_text[:] = [s.text, 0]
            print(f"  [vehicle] {s.text}", file=sys.stderr, flush=True)

        tasks = [
            asyncio.ensure_future(watch(t.attitude_euler(), on_attitude)),
            asyncio.ensure_future(watch(t.health(), lambda h: setattr(state, "health", h))),
            asyncio.ensure_future(watch(t.position_velocity_ned(), lambda p: setattr(state, "pos", p))),
            asyncio.ensure_future(watch(t.armed(), lambda a: setattr(state, "armed", a))),
            asyncio.ensure_future(watch(t.in_air(), lambda a: setattr(state, "in_air", a))),
            asyncio.ensure_future(watch(t.flight_mode(), lambda m: setattr(state, "mode", m))),
            asyncio.ensure_future(watch(t.status_text(), on_text)),
        ]
        await fly(args, drone, state)
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        drone._stop_mavsdk_server()  # the bundled server is a child process: never leave it behind
    return 0


def run(args):
    return asyncio.run(run_async(args))


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
