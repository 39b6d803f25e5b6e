"""Failure injection through `sitl run` with MAVSDK's Failure plugin, as a pilot rehearses a fault: the
autopilot forwards MAV_CMD_INJECT_FAILURE to the plant, the plant fails what it simulates, and the vehicle
reacts from its data only (fused estimator). Judged on the plant's truth (`PlantTruth`, the SIM_ port's
SIM_STATE) against the point where the fault came, and on what the vehicle said. Real time (`--speed 1`):
the announcement bounds are wall seconds, with the vehicle's own bounds at half of them."""

import asyncio
import math
import random
import threading
import time

from sitl_harness import connect, first, start_sitl

from aco_gcs import link
from aco_gcs.flight import land, takeoff, wait_ready
from aco_gcs.link import Params, Plant, mavlink

OPTICAL_FLOW = 5  # FAILURE_UNIT_SENSOR_OPTICAL_FLOW: a sensor this vehicle does not have


class TruthPump:
    """Drains a `PlantTruth` every 10 ms on a thread, so its samples keep up while MAVSDK awaits."""

    def __init__(self, instance):
        self.truth = link.PlantTruth(f"udpout:127.0.0.1:{link.PLANT_PARAM_PORT + instance}", instance + 1)
        self.lock = threading.Lock()
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while self.running:
            with self.lock:
                self.truth.drain()
            time.sleep(0.01)

    def last_down_m(self):
        with self.lock:
            return self.truth.samples[-1][1][2] if self.truth.samples else None

    def downs_between(self, t0_s, t1_s):
        with self.lock:
            return [pos[2] for (t, pos) in self.truth.samples if t0_s <= t <= t1_s]

    def last_time_s(self):
        with self.lock:
            return self.truth.samples[-1][0] if self.truth.samples else None

    def stop(self):
        self.running = False
        self.thread.join()


async def rehearse(instance):
    from mavsdk import System
    from mavsdk.failure import FailureType, FailureUnit

    drone = System(port=random.randint(50100, 50900))
    await drone.connect(system_address=f"udpin://0.0.0.0:{link.api_port(instance)}")
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection")
    said = []

    async def listen():
        async for s in drone.telemetry.status_text():
            said.append((time.monotonic(), s.text))

    listener = asyncio.ensure_future(listen())

    def said_since(prefix, t0):
        return [t - t0 for (t, text) in said if t >= t0 and text.startswith(prefix)]

    async def wait_said(prefix, t0, seconds):
        while time.monotonic() - t0 < seconds:
            if said_since(prefix, t0):
                return said_since(prefix, t0)[0]
            await asyncio.sleep(0.02)
        raise AssertionError(f"{prefix!r} not said within {seconds} s: {said[-10:]}")

    await first(drone.telemetry.health(), lambda h: h.is_global_position_ok and h.is_armable, "health", timeout_s=120)
    pump = TruthPump(instance)
    try:
        await drone.action.set_takeoff_altitude(2.0)
        await drone.action.arm()
        await drone.action.takeoff()
        await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 1.9, "takeoff to 2 m")
        await asyncio.sleep(4.0)

        # Baro stuck: flagged, the height held on GPS within 0.5 m (truth) for 10 s.
        d0, t0_truth, t0 = pump.last_down_m(), pump.last_time_s(), time.monotonic()
        await drone.failure.inject(FailureUnit.SENSOR_BARO, FailureType.STUCK, 0)
        baro_said_s = await wait_said("Baro stuck", t0, 3.0)
        await asyncio.sleep(10.0)
        baro_worst_m = max(abs(d - d0) for d in pump.downs_between(t0_truth, t0_truth + 10.0))
        await drone.failure.inject(FailureUnit.SENSOR_BARO, FailureType.OK, 0)
        await asyncio.sleep(3.0)

        # GPS off in Hold: the loss said within 1 s, the height held within 0.3 m (truth) until the
        # position failsafe lands, then down and disarmed.
        d0, t0_truth, t0 = pump.last_down_m(), pump.last_time_s(), time.monotonic()
        await drone.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
        gps_said_s = await wait_said("GPS lost", t0, 2.0)
        land_s = await wait_said("Failsafe: position lost", t0, 5.0)
        gps_worst_m = max(abs(d - d0) for d in pump.downs_between(t0_truth, t0_truth + land_s))
        await first(drone.telemetry.armed(), lambda a: not a, "disarmed after the landing", timeout_s=60)
    finally:
        pump.stop()
        listener.cancel()
    print(
        f"injection via MAVSDK: baro stuck said {baro_said_s:.2f} s after, worst truth height error over 10 s "
        f"{baro_worst_m:.3f} m; GPS lost said {gps_said_s:.2f} s after, landing at {land_s:.2f} s, worst truth "
        f"height error before it {gps_worst_m:.3f} m"
    )
    assert baro_said_s <= 1.5 + 0.5 and baro_worst_m <= 0.5
    assert gps_said_s <= 1.0 and gps_worst_m <= 0.3


def test_failure_injection_denied_then_unsupported_then_mavsdk_baro_stuck_and_gps_off_judged_on_truth(tmp_path):
    sitl = start_sitl(tmp_path, speed="1")
    try:
        # pymavlink first: MAVSDK's Failure plugin reads SYS_FAILURE_EN once when it connects and refuses
        # locally (DISABLED) while it is 0, so the vehicle's own DENIED is seen with a raw COMMAND_LONG.
        vehicle = connect(sitl)
        inject = mavlink.MAV_CMD_INJECT_FAILURE
        assert vehicle.command(inject, mavlink.FAILURE_UNIT_SENSOR_GPS, 1, 0) == mavlink.MAV_RESULT_DENIED
        Params(vehicle, 1).require_set("SYS_FAILURE_EN", 1)
        # A unit the plant does not simulate: UNSUPPORTED, never accepted and ignored.
        assert vehicle.command(inject, OPTICAL_FLOW, 1, 0) == mavlink.MAV_RESULT_UNSUPPORTED
        vehicle.close()
        asyncio.run(asyncio.wait_for(rehearse(sitl.instance), 300))
    finally:
        sitl.stop()
        print(sitl.log_tail())


def test_motor_1_wrong_at_90_percent_in_hold_holds_within_0_3_m_on_truth_and_the_ulog_shows_rotor_1_pushed_harder(
    tmp_path,
):
    # 90 %: the 70 % is beyond this airframe for any controller (docs/faults.md); paced at 4x.
    sitl = start_sitl(tmp_path, speed="4")
    try:
        vehicle = connect(sitl)
        truth = link.PlantTruth(f"udpout:127.0.0.1:{link.PLANT_PARAM_PORT + sitl.instance}", sitl.instance + 1)
        vehicle.listeners.append(lambda _m: truth.drain())
        Params(vehicle, 1).require_set("SYS_FAILURE_EN", 1)
        plant = Plant(sitl.instance, 60.0)
        plant.hello()
        Params(plant, plant.component).require_set("SIM_MOT_WRNG_EFF", 0.9)
        ground, _ = wait_ready(vehicle)
        takeoff(vehicle, 2.0, ground)
        settled = vehicle.now_s() + 5.0
        vehicle.wait_until(6.0, "a 5 s hold", lambda: vehicle.now_s() >= settled)
        fault_s = vehicle.now_s()
        hold = truth.wait_at(vehicle, fault_s)
        motor, wrong = mavlink.FAILURE_UNIT_SYSTEM_MOTOR, mavlink.FAILURE_TYPE_WRONG
        assert vehicle.command(mavlink.MAV_CMD_INJECT_FAILURE, motor, wrong, 1) == mavlink.MAV_RESULT_ACCEPTED
        end_s = fault_s + 20.0
        vehicle.wait_until(21.0, "20 s on a weak rotor", lambda: vehicle.now_s() >= end_s)
        truth.wait_at(vehicle, end_s)
        worst_m = max(math.dist(p, hold) for p in truth.window(fault_s, end_s))
        assert vehicle.armed, "still flying"
        land(vehicle)
    finally:
        sitl.stop()
    from pyulog import ULog

    (path,) = sorted((tmp_path / "state" / "log").glob("*/*.ulg"))
    out = ULog(str(path), message_name_filter_list=["actuator_outputs"]).data_list[0].data
    t_s = out["timestamp"] * 1e-6

    def rotor_1_over_the_others_us(t0_s, t1_s):
        rows = [k for k in range(len(t_s)) if t0_s <= t_s[k] <= t1_s]
        others = [sum(out[f"output[{i}]"][k] for i in (1, 2, 3)) / 3.0 for k in rows]
        return sum(out["output[0]"][k] - o for k, o in zip(rows, others, strict=True)) / len(rows)

    before_us = rotor_1_over_the_others_us(fault_s - 4.0, fault_s)
    after_us = rotor_1_over_the_others_us(fault_s + 5.0, end_s)
    print(
        f"motor 1 at 90 % through sitl run: worst truth distance from the hold point {worst_m:.3f} m over 20 s; "
        f"ULog rotor 1 minus the others' mean {before_us:.1f} us before, {after_us:.1f} us after"
    )
    assert worst_m <= 0.3
    # Rotor 1 makes up its lost tenth: commanded well above the others (the lift curve gives about 3.2 N per
    # 1000 us; a tenth of the 12.75 N hover lift is about 400 us).
    assert after_us - before_us >= 100.0
