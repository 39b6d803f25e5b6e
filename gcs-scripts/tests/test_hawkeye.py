"""PX4's Hawkeye convention: `sitl run --hawkeye` sends the plant's truth as HIL_STATE_QUATERNION to UDP
127.0.0.1:19410+N at 50 Hz of simulated time. Listened to as Hawkeye does (pymavlink `udpin:` on the port)
on an instance N > 0 (the port is 19410+N, not 19410), through a takeoff at 4x real time: the rate from
`time_usec` is 50 Hz of vehicle time over more than 10 s, and at equal times the samples are the SIM_
port's SIM_STATE (timed by the SYSTEM_TIME before it): the same attitude quaternion, lat/lon and altitude."""

import contextlib
import itertools
import socket
import time

import pytest
from sitl_harness import connect, free_instance, start_sitl

from aco_gcs.flight import takeoff, wait_ready
from aco_gcs.link import GCS_COMPONENT, GCS_SYSTEM, PLANT_COMPONENT, PLANT_PARAM_PORT, mavlink, mavutil

HAWKEYE_PORT = 19410
SPEED = "4"
TAKEOFF_M = 3.0
WINDOW_S = 10.0  # vehicle seconds of Hawkeye samples at least


def port_free(port):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.bind(("127.0.0.1", port))
        return True
    except OSError:
        return False
    finally:
        s.close()


class Streams:
    """What Hawkeye gets (HIL_STATE_QUATERNION on 19410+N) and the SIM_ port's truth (SYSTEM_TIME then
    SIM_STATE on 19550+N, for a client that says HEARTBEAT), each kept by its time in µs."""

    def __init__(self, instance):
        self.system_id = instance + 1
        self.hawkeye = mavutil.mavlink_connection(f"udpin:127.0.0.1:{HAWKEYE_PORT + instance}")
        self.hawkeye.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.sim = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{PLANT_PARAM_PORT + instance}", source_system=GCS_SYSTEM, source_component=GCS_COMPONENT
        )
        self.hil = {}  # time_usec -> HIL_STATE_QUATERNION
        self.sim_states = {}  # time_boot_ms * 1000 -> SIM_STATE
        self.senders = set()  # (system, component) of the Hawkeye frames
        self._time_ms = None
        self._last_hello = -1e9

    def drain(self, _msg=None):
        now = time.monotonic()
        if now - self._last_hello >= 0.5:
            self._last_hello = now
            with contextlib.suppress(OSError):
                self.sim.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        while (msg := self.hawkeye.recv_match(blocking=False)) is not None:
            if msg.get_type() == "HIL_STATE_QUATERNION":
                self.hil[msg.time_usec] = msg
                self.senders.add((msg.get_srcSystem(), msg.get_srcComponent()))
        while True:
            try:
                msg = self.sim.recv_match(blocking=False)
            except OSError:
                return  # the plant is not up yet
            if msg is None:
                return
            if msg.get_srcSystem() != self.system_id or msg.get_srcComponent() != PLANT_COMPONENT:
                continue
            if msg.get_type() == "SYSTEM_TIME":
                self._time_ms = msg.time_boot_ms
            elif msg.get_type() == "SIM_STATE" and self._time_ms is not None:
                self.sim_states[self._time_ms * 1000] = msg
                self._time_ms = None

    def hawkeye_span_s(self):
        return (max(self.hil) - min(self.hil)) / 1e6 if len(self.hil) > 1 else 0.0

    def close(self):
        self.hawkeye.close()
        self.sim.close()


def test_hawkeye_gets_the_truth_at_50_hz_of_vehicle_time_on_19410_plus_n_equal_to_sim_state(tmp_path):
    n = next((k for k in (free_instance() for _ in range(20)) if port_free(HAWKEYE_PORT + k)), None)
    if n is None:
        pytest.fail("no free instance with a free Hawkeye port")
    streams = Streams(n)
    sitl = start_sitl(tmp_path, "--hawkeye", speed=SPEED, instance=n)
    started = time.monotonic()
    try:
        vehicle = connect(sitl)
        vehicle.listeners.append(streams.drain)
        ground, _ = wait_ready(vehicle)
        takeoff(vehicle, TAKEOFF_M, ground)
        vehicle.wait_until(
            WINDOW_S + 5.0, f"{WINDOW_S:g} s of Hawkeye samples", lambda: streams.hawkeye_span_s() > WINDOW_S
        )
        streams.drain()
    finally:
        sitl.stop()
        streams.close()
        print(sitl.log_tail(1500))
    wall_s = time.monotonic() - started

    times = sorted(streams.hil)
    span_s = streams.hawkeye_span_s()
    rate_hz = (len(times) - 1) / span_s
    deltas = [b - a for a, b in itertools.pairwise(times)]
    print(f"hawkeye: {len(times)} samples over {span_s:.2f} s of vehicle time = {rate_hz:.2f} Hz; {wall_s:.1f} s wall")
    assert span_s >= WINDOW_S, span_s
    assert abs(rate_hz - 50.0) <= 2.0, rate_hz
    assert all(d % 20_000 == 0 for d in deltas), "every sample on a 20 ms tick of plant time"
    assert sum(d == 20_000 for d in deltas) >= 0.98 * len(deltas), "next to none lost"
    assert streams.senders == {(n + 1, PLANT_COMPONENT)}, streams.senders

    # At equal times the Hawkeye sample is the SIM_ port's: the same f32 quaternion, degE7, altitude.
    common = sorted(set(streams.hil) & set(streams.sim_states))
    assert len(common) >= 0.9 * len(times), f"{len(common)} of {len(times)} times in both streams"
    for t in common:
        h, s = streams.hil[t], streams.sim_states[t]
        q_sim = (s.q1, s.q2, s.q3, s.q4)
        assert all(abs(a - b) <= 1e-6 for a, b in zip(h.attitude_quaternion, q_sim, strict=True)), (t, h, s)
        assert abs(h.lat * 1e-7 - s.lat_int * 1e-7) <= 1e-7 and abs(h.lon * 1e-7 - s.lon_int * 1e-7) <= 1e-7, (t, h, s)
        assert abs(h.alt - s.alt * 1000.0) <= 1.0, (t, h.alt, s.alt)
    # On a moving vehicle: the climb is in the compared samples.
    alts_m = [streams.hil[t].alt / 1000.0 for t in common]
    climbing = [t for t in common if streams.hil[t].vz <= -30]
    assert max(alts_m) - min(alts_m) >= TAKEOFF_M - 0.3, (min(alts_m), max(alts_m))
    assert len(climbing) >= 10, "samples of the climb (vz <= -0.3 m/s) compared"
    assert wall_s < 60.0, wall_s
