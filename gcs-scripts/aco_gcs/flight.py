"""Flight steps the pymavlink scripts share, each waiting on the vehicle's clock: wait for the estimator,
take off to a height above the ground point, hold while sampling the hover error, land and wait for the
auto-disarm."""

import math
import sys

from .link import LANDED_ON_GROUND, CheckFailed, mavlink


def say(text):
    print(text, flush=True)


def wait_ready(vehicle, seconds=30.0):
    """Wait for the estimator (SYS_STATUS PREARM_CHECK healthy) and a local position; returns the ground
    point (LOCAL_POSITION_NED x, y, z) and the seconds it took."""
    took = vehicle.wait_until(
        seconds,
        "estimator convergence (SYS_STATUS PREARM_CHECK)",
        lambda: vehicle.prearm_ok and vehicle.pos is not None,
    )
    return vehicle.pos, took


def takeoff(vehicle, alt_m, ground, climb_s=20.0):
    """NAV_TAKEOFF to `alt_m` above home (sent as AMSL, NaN yaw), arm, and wait until within 5 cm of the
    height and nearly still. Returns the hover point (NED) and the climb's vehicle seconds."""
    home_amsl = vehicle.home_amsl_m()
    if home_amsl is None:
        vehicle.wait_until(10.0, "GLOBAL_POSITION_INT (home altitude)", lambda: vehicle.home_amsl_m() is not None)
        home_amsl = vehicle.home_amsl_m()
    nan = float("nan")
    vehicle.require("takeoff", mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, home_amsl + alt_m)
    vehicle.require("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    vehicle.wait_until(2.0, "armed HEARTBEAT", lambda: vehicle.armed)
    hover = (ground[0], ground[1], ground[2] - alt_m)

    def at_height():
        return abs(vehicle.pos[2] - hover[2]) < 0.05 and abs(vehicle.vel[2]) < 0.1

    took = vehicle.wait_until(climb_s, f"climb to {alt_m:g} m", at_height)
    return hover, took


def hold(vehicle, seconds, on_sample=None):
    """Pump for `seconds` of vehicle time, calling `on_sample(t_s, pos, vel)` on each LOCAL_POSITION_NED;
    fails if the vehicle disarms meanwhile."""

    def sample(msg):
        if msg.get_type() == "LOCAL_POSITION_NED" and on_sample is not None:
            on_sample(vehicle.now_s(), (msg.x, msg.y, msg.z), (msg.vx, msg.vy, msg.vz))

    vehicle.listeners.append(sample)
    try:
        end = vehicle.now_s() + seconds
        while vehicle.now_s() < end:
            vehicle.pump()
            if not vehicle.armed:
                raise CheckFailed(f"disarmed during the hold at t = {vehicle.now_s():.1f} s")
    finally:
        vehicle.listeners.remove(sample)


def land(vehicle, seconds=30.0):
    """NAV_LAND and wait for EXTENDED_SYS_STATE on-ground and the auto-disarm; returns the vehicle seconds."""
    vehicle.require("land", mavlink.MAV_CMD_NAV_LAND)
    return vehicle.wait_until(
        seconds, "landed and disarmed", lambda: vehicle.landed_state == LANDED_ON_GROUND and not vehicle.armed
    )


def horizontal_error(pos, point):
    return math.hypot(pos[0] - point[0], pos[1] - point[1])


def warn(text):
    print(f"warning: {text}", file=sys.stderr, flush=True)
