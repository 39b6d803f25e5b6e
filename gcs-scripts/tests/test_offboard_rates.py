"""Offboard body rates through `sitl run` at real time, as a companion script or a learned policy sends
them: SET_ATTITUDE_TARGET with ATTITUDE_IGNORE (type_mask bit 7), body rates and the hover thrust, streamed
at 50 Hz, by pymavlink and by MAVSDK's `Offboard.set_attitude_rate`. From a hover in Offboard: roll at
+0.5 rad/s for 0.6 s (the truth rolls by 0.30 +- 0.06 rad), at -0.5 rad/s for 0.6 s (it comes back within
0.06 rad of where it began, judged once that turn has ended: half a second into the zero rates, when the
rates are within 0.03 rad/s), then zero rates for 1 s (every rate within 0.03 rad/s over its second half).
At the instant the -0.5 rad/s ends the vehicle is still turning: the roll then is 0.045-0.062 rad, the
lag of a 1 rad/s reversal the paper's airframe can make at about 9 rad/s² of roll authority, plus the
link's latency; it is printed.

The autopilot runs with `--estimator truth`, so ATTITUDE is the plant's truth (asked for at 100 Hz with
SET_MESSAGE_INTERVAL); the phases are timed on the vehicle's clock (ATTITUDE time_boot_ms). At real time,
because the offboard timeout (0.5 s) runs on vehicle time and the setpoints on the wall clock."""

import asyncio
import math
import time
from typing import Any

from sitl_harness import connect, mavsdk_module, mavsdk_ready, start_sitl

from aco_gcs.flight import takeoff, wait_ready
from aco_gcs.link import Params, mavlink

PX4_MAIN_OFFBOARD = 6
ATTITUDE_IGNORE = 128
PERIOD_S = 0.02  # 50 Hz


class Rates:
    """The sequence's measurements: the truth roll (rad) at each phase's end, the largest body rate (rad/s)
    over the last half of the zero phase."""

    def __init__(self):
        self.roll0 = self.rolled = self.at_switch = self.back = self.worst = math.nan

    def check(self):
        print(
            f"offboard rates: rolled {self.rolled:.3f} rad, {self.at_switch:.3f} rad as -0.5 rad/s ends, "
            f"back to {self.back:.3f} rad, rates <= {self.worst:.4f}"
        )
        assert abs(self.rolled - 0.30) <= 0.06, f"rolled {self.rolled} rad"
        assert abs(self.back) <= 0.06, f"came back to {self.back} rad"
        assert self.worst <= 0.03, f"a rate of {self.worst} rad/s at zero rates"


def test_offboard_body_rates_by_pymavlink_at_real_time_roll_and_come_back_on_the_truth(tmp_path):
    sitl = start_sitl(tmp_path, "--estimator", "truth", speed="1")
    try:
        vehicle = connect(sitl)
        ground, _ = wait_ready(vehicle)
        vehicle.require("ATTITUDE at 100 Hz", mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 10_000)
        takeoff(vehicle, 5.0, ground)
        hover = Params(vehicle, 1).get("MPC_THR_HOVER")
        att: dict[str, Any] = {"roll": math.nan, "rates": (math.nan,) * 3}

        def on_attitude(msg):
            if msg.get_type() == "ATTITUDE":
                att["roll"] = msg.roll
                att["rates"] = (msg.rollspeed, msg.pitchspeed, msg.yawspeed)

        vehicle.listeners.append(on_attitude)
        next_send = [0.0]

        def stream(seconds, rates, each=None):
            """Send the rates every 20 ms of wall time for `seconds` of vehicle time."""
            end = vehicle.now_s() + seconds
            while vehicle.now_s() < end:
                if time.monotonic() >= next_send[0]:
                    next_send[0] = time.monotonic() + PERIOD_S
                    vehicle.conn.mav.set_attitude_target_send(
                        0, vehicle.system_id, 1, ATTITUDE_IGNORE, [1.0, 0.0, 0.0, 0.0], *rates, hover
                    )
                vehicle.pump()
                if each is not None:
                    each()

        r = Rates()
        stream(1.0, (0.0, 0.0, 0.0))
        vehicle.require("Offboard", mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0)
        stream(0.5, (0.0, 0.0, 0.0))
        assert vehicle.px4_mode() == (PX4_MAIN_OFFBOARD, 0)
        r.roll0 = att["roll"]
        stream(0.6, (0.5, 0.0, 0.0))
        r.rolled = att["roll"] - r.roll0
        stream(0.6, (-0.5, 0.0, 0.0))
        r.at_switch = att["roll"] - r.roll0
        stream(0.5, (0.0, 0.0, 0.0))
        r.back = att["roll"] - r.roll0
        worst = [0.0]
        stream(0.5, (0.0, 0.0, 0.0), lambda: worst.__setitem__(0, max(worst[0], *map(abs, att["rates"]))))
        r.worst = worst[0]
        assert vehicle.px4_mode() == (PX4_MAIN_OFFBOARD, 0), "still in Offboard"
        r.check()
        vehicle.close()
    finally:
        sitl.stop()
        print(sitl.log_tail())


async def mavsdk_rate_sequence(instance, truth):
    attitude_rate = mavsdk_module("mavsdk.offboard").AttitudeRate
    drone = await mavsdk_ready(instance)
    await drone.telemetry.set_rate_attitude_euler(100.0)
    state: dict[str, Any] = {"now_s": 0.0, "roll": math.nan, "rates": (math.nan,) * 3, "mode": None, "z": None}

    async def watch(stream, update):
        async for value in stream:
            update(value)

    def on_attitude(a):
        state["now_s"] = max(state["now_s"], a.timestamp_us / 1e6)
        state["roll"] = math.radians(a.roll_deg)

    def on_rates(w):
        state["rates"] = (w.roll_rad_s, w.pitch_rad_s, w.yaw_rad_s)

    t = drone.telemetry
    tasks = [
        asyncio.ensure_future(watch(t.attitude_euler(), on_attitude)),
        asyncio.ensure_future(watch(t.attitude_angular_velocity_body(), on_rates)),
        asyncio.ensure_future(watch(t.flight_mode(), lambda m: state.update(mode=m.name))),
        asyncio.ensure_future(watch(t.position_velocity_ned(), lambda p: state.update(z=p.position.down_m))),
    ]

    async def until(seconds, what, cond):
        start, wall_end = state["now_s"], time.monotonic() + 10 * seconds + 30
        while not cond():
            assert state["now_s"] - start <= seconds, f"{what}: not within {seconds:g} s of vehicle time"
            assert time.monotonic() < wall_end, f"{what}: wall-clock guard"
            await asyncio.sleep(0.005)

    async def stream(seconds, rates_radps, each=None):
        """set_attitude_rate every 20 ms for `seconds` of vehicle time (MAVSDK takes deg/s)."""
        end = state["now_s"] + seconds
        degps = [math.degrees(x) for x in rates_radps]
        while state["now_s"] < end:
            await drone.offboard.set_attitude_rate(attitude_rate(*degps, truth["hover"]))
            sent = time.monotonic()
            while time.monotonic() - sent < PERIOD_S and state["now_s"] < end:
                if each is not None:
                    each()
                await asyncio.sleep(0.002)

    try:
        await until(10.0, "telemetry", lambda: state["z"] is not None)
        ground_d = state["z"]
        await drone.action.set_takeoff_altitude(5.0)
        await drone.action.arm()
        await drone.action.takeoff()
        await until(30.0, "climb to 5 m", lambda: ground_d - state["z"] > 4.9)
        await stream(3.0, (0.0, 0.0, 0.0))  # settles the takeoff's hold before the switch
        await drone.offboard.start()
        await until(2.0, "Offboard", lambda: state["mode"] == "OFFBOARD")
        r = Rates()
        await stream(0.5, (0.0, 0.0, 0.0))
        r.roll0 = state["roll"]
        await stream(0.6, (0.5, 0.0, 0.0))
        r.rolled = state["roll"] - r.roll0
        await stream(0.6, (-0.5, 0.0, 0.0))
        r.at_switch = state["roll"] - r.roll0
        await stream(0.5, (0.0, 0.0, 0.0))
        r.back = state["roll"] - r.roll0
        worst = [0.0]
        await stream(0.5, (0.0, 0.0, 0.0), lambda: worst.__setitem__(0, max(worst[0], *map(abs, state["rates"]))))
        r.worst = worst[0]
        assert state["mode"] == "OFFBOARD", state["mode"]
        return r
    finally:
        for task in tasks:
            task.cancel()


def test_offboard_body_rates_by_mavsdk_set_attitude_rate_at_real_time(tmp_path):
    sitl = start_sitl(tmp_path, "--estimator", "truth", speed="1")
    try:
        vehicle = connect(sitl)
        hover = Params(vehicle, 1).get("MPC_THR_HOVER")
        vehicle.close()
        r = asyncio.run(asyncio.wait_for(mavsdk_rate_sequence(sitl.instance, {"hover": hover}), 300))
        r.check()
    finally:
        sitl.stop()
        print(sitl.log_tail())
