"""The ground stations the field flies PX4 with, against the real SITL (`sitl run --speed max`: lockstep, as
fast as possible, so the suite stays short): MAVSDK-Python (classic API) through a whole session (telemetry
and health, arm, takeoff, the paper's figure-8 uploaded and flown to its end, goto, return and land) and its
param plugin on integer and float parameters; pymavlink's PX4 mode handling and PX4's bytewise INT32
parameters; MAVProxy (lean install) downloading every parameter and the mission; pymavlink over the TCP
server; and the connection sequence of QGroundControl. Waits are on the vehicle's telemetry; wall-clock
limits only stop a hung run."""

import asyncio
import math
import os
import random
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from sitl_harness import ROOT, first, start_sitl

os.environ["MAVLINK20"] = "1"
from pymavlink import mavparm, mavutil

from aco_gcs import link
from aco_gcs.figure8_mission import FIGURE8_NE_M

mavlink = mavutil.mavlink
EARTH_RADIUS_M = 6_378_137.0


def param_rows():
    """{name: (MAVLink type, default as text)} of every parameter of the vehicle: the rows of
    docs/params.md, which is generated from the table."""
    rows = {}
    for line in (ROOT / "docs" / "params.md").read_text().splitlines():
        if line.startswith("| `"):
            name, param_type, default = (cell.strip() for cell in line.strip("|").split("|")[:3])
            rows[name.strip("`")] = (param_type, default)
    return rows


PARAM_ROWS = param_rows()
PARAM_COUNT = len(PARAM_ROWS)
INT32_PARAMS = {name for name, (param_type, _) in PARAM_ROWS.items() if param_type == "INT32"}


def bytewise_int32(field):
    """The int32 whose four bytes a PARAM_VALUE of type INT32 carries in its float field (PX4's encoding),
    written out here rather than taken from the scripts' `link.decode_param`."""
    return struct.unpack("<i", struct.pack("<f", field))[0]


@pytest.fixture
def sitl(tmp_path):
    s = start_sitl(tmp_path, speed="max")
    try:
        yield s
    finally:
        s.stop()
        print(s.log_tail())


def offset(lat_deg, lon_deg, north_m, east_m):
    """The point `north_m`, `east_m` from (lat, lon) on a flat earth (enough for metres)."""
    lat = lat_deg + math.degrees(north_m / EARTH_RADIUS_M)
    lon = lon_deg + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat_deg))))
    return lat, lon


def vehicle(s):
    """A pymavlink link to the vehicle of `s`, as a script listens (its API port, sending to 18570+N)."""
    v = link.Vehicle(
        f"udpin:127.0.0.1:{link.api_port(s.instance)}", target=f"127.0.0.1:{18570 + s.instance}", wall_limit_s=300
    )
    v.wait_heartbeat(30, s.instance)
    return v


# -- MAVSDK -------------------------------------------------------------------------------------------


async def mavsdk_session(instance):
    from mavsdk import System
    from mavsdk.mission import MissionItem, MissionPlan

    drone = System(port=random.randint(50100, 50900))
    await drone.connect(system_address=f"udpin://0.0.0.0:{link.api_port(instance)}")
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection")
    health = await first(
        drone.telemetry.health(),
        lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
        "health (global position, home, armable)",
    )
    assert health.is_gyrometer_calibration_ok and health.is_accelerometer_calibration_ok
    home = await first(drone.telemetry.home(), what="home")
    position = await first(drone.telemetry.position(), what="position")
    assert abs(position.latitude_deg - home.latitude_deg) < 1e-5
    await first(drone.telemetry.attitude_euler(), what="attitude")
    assert await first(drone.telemetry.landed_state(), what="landed state") is not None

    await drone.action.set_takeoff_altitude(1.5)
    await drone.action.arm()
    await drone.action.takeoff()
    await first(drone.telemetry.in_air(), lambda a: a, "in air")
    await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 1.35, "takeoff to 1.5 m")

    # The paper's figure-8 around home at 1.5 m and 0.3 m/s, flown through (no stops).
    items = []
    for north_m, east_m in FIGURE8_NE_M:
        lat, lon = offset(home.latitude_deg, home.longitude_deg, north_m, east_m)
        items.append(
            MissionItem(
                lat,
                lon,
                1.5,
                0.3,
                True,
                float("nan"),
                float("nan"),
                MissionItem.CameraAction.NONE,
                float("nan"),
                float("nan"),
                float("nan"),
                float("nan"),
                float("nan"),
                MissionItem.VehicleAction.NONE,
            )
        )
    await drone.mission.set_return_to_launch_after_mission(False)
    await drone.mission.upload_mission(MissionPlan(items))
    downloaded = await drone.mission.download_mission()
    assert len(downloaded.mission_items) == len(items)
    await drone.mission.start_mission()
    seen = []

    def progressed(p):
        seen.append(p.current)
        return p.total == len(items) and p.current == p.total

    await first(drone.mission.mission_progress(), progressed, "mission progress to its end", timeout_s=240)
    assert await drone.mission.is_mission_finished()
    assert seen == sorted(seen), f"progress only goes forward: {seen}"

    # Goto 3 m north of home, 2 m above it (AMSL), then return and land.
    lat, lon = offset(home.latitude_deg, home.longitude_deg, 3.0, 0.0)
    await drone.action.goto_location(lat, lon, home.absolute_altitude_m + 2.0, 0.0)

    def arrived(p):
        north = math.radians(p.latitude_deg - home.latitude_deg) * EARTH_RADIUS_M
        return abs(north - 3.0) < 0.25 and abs(p.relative_altitude_m - 2.0) < 0.25

    await first(drone.telemetry.position(), arrived, "goto 3 m north")
    await drone.action.return_to_launch()
    await first(drone.telemetry.flight_mode(), lambda m: m.name == "RETURN_TO_LAUNCH", "RTL mode")
    await first(drone.telemetry.in_air(), lambda a: not a, "landed", timeout_s=240)
    await first(drone.telemetry.armed(), lambda a: not a, "auto-disarm")
    landed_at = await first(drone.telemetry.position(), what="position")
    north = math.radians(landed_at.latitude_deg - home.latitude_deg) * EARTH_RADIUS_M
    assert abs(north) < 0.5, f"landed {north:.2f} m from home"
    return seen


def test_mavsdk_flies_takeoff_the_figure8_mission_goto_and_return(sitl):
    seen = asyncio.run(asyncio.wait_for(mavsdk_session(sitl.instance), 600))
    print(f"MAVSDK mission progress: {seen}")


async def mavsdk_params(instance):
    """What a MAVSDK script written for PX4 does with parameters: integers through `*_param_int` (INT32,
    bytewise), reals through `*_param_float` (REAL32)."""
    from mavsdk import System
    from mavsdk.param import ParamError

    drone = System(port=random.randint(50100, 50900))
    await drone.connect(system_address=f"udpin://0.0.0.0:{link.api_port(instance)}")
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection")
    param = drone.param
    assert await param.get_param_int("NAV_DLL_ACT") == 0
    assert await param.get_param_int("LOOP_INNER_HZ") == 500
    assert await param.get_param_int("ACO_ADAPT_EN") == 1
    await param.set_param_int("NAV_DLL_ACT", 2)
    assert await param.get_param_int("NAV_DLL_ACT") == 2
    assert await param.get_param_float("COM_DL_LOSS_T") == 10.0
    await param.set_param_float("COM_DL_LOSS_T", 7.5)
    assert await param.get_param_float("COM_DL_LOSS_T") == 7.5
    # The failsafe actions as a PX4 script sets them (PX4's numbers), and their refusals.
    assert (await param.get_param_int("GF_ACTION"), await param.get_param_int("COM_LOW_BAT_ACT")) == (2, 3)
    await param.set_param_int("GF_ACTION", 3)
    await param.set_param_int("COM_LOW_BAT_ACT", 2)
    assert (await param.get_param_int("GF_ACTION"), await param.get_param_int("COM_LOW_BAT_ACT")) == (3, 2)
    with pytest.raises(ParamError):
        await param.set_param_int("COM_LOW_BAT_ACT", 1)  # not one of PX4's values (0, 2, 3)
    assert await param.get_param_int("COM_LOW_BAT_ACT") == 2
    # The vehicle's types are PX4's: an integer is not a float, nor a float an integer.
    with pytest.raises(ParamError) as wrong:
        await param.get_param_float("NAV_DLL_ACT")
    assert "WRONG_TYPE" in str(wrong.value), wrong.value
    with pytest.raises(ParamError) as wrong:
        await param.get_param_int("COM_DL_LOSS_T")
    assert "WRONG_TYPE" in str(wrong.value), wrong.value
    # Out of range (0..5): refused, the value stays.
    with pytest.raises(ParamError):
        await param.set_param_int("NAV_DLL_ACT", 9)
    assert await param.get_param_int("NAV_DLL_ACT") == 2
    everything = await param.get_all_params()
    ints = {p.name: p.value for p in everything.int_params}
    floats = {p.name: p.value for p in everything.float_params}
    assert set(ints) == INT32_PARAMS and len(ints) + len(floats) == PARAM_COUNT, (sorted(ints), len(floats))
    assert (ints["NAV_DLL_ACT"], ints["LOOP_POS_HZ"], floats["COM_DL_LOSS_T"]) == (2, 100, 7.5)


def test_mavsdk_param_plugin_gets_and_sets_integers_as_int32_and_reals_as_float(sitl):
    asyncio.run(asyncio.wait_for(mavsdk_params(sitl.instance), 300))


# -- pymavlink ----------------------------------------------------------------------------------------


def test_pymavlink_knows_the_px4_modes_and_set_mode_loiter_switches(sitl):
    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{link.api_port(sitl.instance)}", source_system=255)
    hb = conn.wait_heartbeat(timeout=30)
    assert hb is not None and hb.autopilot == mavlink.MAV_AUTOPILOT_PX4
    mapping = conn.mode_mapping()
    assert {"LOITER", "MISSION", "RTL", "OFFBOARD", "POSCTL"} <= set(mapping), mapping
    deadline = time.monotonic() + 30
    while conn.flightmode != "POSCTL":
        assert time.monotonic() < deadline, f"still {conn.flightmode}"
        # POSCTL flies the sticks: a joystick's MANUAL_CONTROL (centred, throttle at hold) goes with it.
        conn.mav.manual_control_send(conn.target_system, 0, 0, 500, 0, 0)
        conn.set_mode("POSCTL")
        conn.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
    conn.set_mode("LOITER")
    while conn.flightmode != "LOITER":
        assert time.monotonic() < deadline, f"still {conn.flightmode}"
        conn.recv_match(type="HEARTBEAT", blocking=True, timeout=1)


def test_pymavlink_reads_int32_parameters_bytewise_and_sets_them_as_int32_or_real32(sitl):
    """A pymavlink script written for PX4: every parameter read, an INT32 one decoded from its bytes (as
    MAVProxy does for a PX4), set by an older script's REAL32 and by pymavlink's own bytewise encoder."""
    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{link.api_port(sitl.instance)}", source_system=255)
    assert conn.wait_heartbeat(timeout=30) is not None
    int32, real32 = mavlink.MAV_PARAM_TYPE_INT32, mavlink.MAV_PARAM_TYPE_REAL32

    def answer(send, match, what, timeout_s=30):
        """`send()`, then the first message `match` accepts; `send()` again after each wall second without
        one, as clients resend (at lockstep speed a burst of telemetry can overflow the socket)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            send()
            resend = time.monotonic() + 1.0
            while time.monotonic() < resend:
                msg = conn.recv_match(type=["PARAM_VALUE", "STATUSTEXT"], blocking=True, timeout=0.2)
                if msg is not None and match(msg):
                    return msg
        pytest.fail(f"no {what}")

    def param_value(name):
        return lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name

    def read(name):
        return answer(lambda: conn.param_fetch_one(name), param_value(name), f"PARAM_VALUE of {name}")

    # Every parameter, missing indices re-requested (a burst may overflow the socket at lockstep speed).
    conn.param_fetch_all()
    got: dict = {}
    quiet_since = time.monotonic()
    while len(got) < PARAM_COUNT:
        assert time.monotonic() - quiet_since < 20, f"{len(got)} of {PARAM_COUNT} parameters"
        msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=1)
        if msg is not None:
            got[msg.param_id], quiet_since = msg, time.monotonic()
        elif got:
            for index in sorted(set(range(PARAM_COUNT)) - {m.param_index for m in got.values()}):
                conn.mav.param_request_read_send(conn.target_system, 1, b"", index)
    for name, (param_type, default) in PARAM_ROWS.items():
        msg = got[name]
        if param_type == "INT32":
            assert (msg.param_type, bytewise_int32(msg.param_value)) == (int32, int(default)), name
        else:
            assert msg.param_type == real32 and link.same_float32(msg.param_value, float(default)), name
    # 500's four bytes, not the float 500.0: read as a float it is a denormal.
    assert 0 < got["LOOP_INNER_HZ"].param_value < 1e-40

    # An older script's set: the value as a float, REAL32 (pymavlink's default type). Echoed as INT32.
    echo = answer(lambda: conn.param_set_send("NAV_DLL_ACT", 2.0), param_value("NAV_DLL_ACT"), "echo")
    assert (echo.param_type, bytewise_int32(echo.param_value)) == (int32, 2)
    # pymavlink's bytewise encoder (mavparm, as MAVProxy sets a PX4 integer): INT32.
    assert mavparm.MAVParmDict().mavset(conn, "NAV_DLL_ACT", 3, retries=10, parm_type=int32)
    assert bytewise_int32(read("NAV_DLL_ACT").param_value) == 3
    # A fraction is refused in words and the value stays.
    refusal = "NAV_DLL_ACT: 2.5 is not a whole number"
    answer(
        lambda: conn.param_set_send("NAV_DLL_ACT", 2.5),
        lambda m: m.get_type() == "STATUSTEXT" and m.text == refusal,
        "refusal",
    )
    assert bytewise_int32(read("NAV_DLL_ACT").param_value) == 3
    conn.close()


def test_pymavlink_over_tcp_reads_a_parameter_and_the_adaptive_weights(sitl):
    """The TCP server on 5760+N, as MAVProxy's and QGC's TCP links use it."""
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{5760 + sitl.instance}", source_system=255, retries=30)
    hb = conn.wait_heartbeat(timeout=30)
    assert hb is not None and conn.target_system == sitl.instance + 1
    conn.mav.param_request_read_send(conn.target_system, 1, b"ACO_WEIGHTS_HZ", -1)
    value = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=30)
    assert value is not None and value.param_id == "ACO_WEIGHTS_HZ" and value.param_value == 2.0
    names: set[str] = set()
    deadline = time.monotonic() + 30
    while len(names) < 5:
        assert time.monotonic() < deadline, f"only {sorted(names)}"
        vect = conn.recv_match(type="DEBUG_VECT", blocking=True, timeout=1)
        if vect is not None:
            names.add(vect.name)
            if vect.name == "aco.m_est":
                # The mass estimate (kg) per NED axis, starting at the nominal 5.2 kg on the ground.
                assert all(4.0 < m < 6.5 for m in (vect.x, vect.y, vect.z)), vect
    assert names == {"aco.w_t", "aco.b_t", "aco.c_r", "aco.d_r", "aco.m_est"}
    conn.close()


# -- MAVProxy -----------------------------------------------------------------------------------------


def upload(v, items):
    """Upload MISSION_ITEM_INTs with the mission protocol."""
    v.send(v.conn.mav.mission_count_encode(v.system_id, 1, len(items), 0))
    while True:
        msg = v.next_message(10, lambda m: m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"))
        assert msg is not None, "no mission request"
        if msg.get_type() == "MISSION_ACK":
            assert msg.type == mavlink.MAV_MISSION_ACCEPTED, msg
            return
        v.send(items[msg.seq])


def waypoints(v, count):
    lat0, lon0 = v.global_pos.lat * 1e-7, v.global_pos.lon * 1e-7
    out = []
    for seq in range(count):
        lat, lon = offset(lat0, lon0, 1.0 + seq, 0.0)
        out.append(
            v.conn.mav.mission_item_int_encode(
                v.system_id,
                1,
                seq,
                mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                mavlink.MAV_CMD_NAV_WAYPOINT,
                0,
                1,
                0,
                0,
                0,
                float("nan"),
                int(lat * 1e7),
                int(lon * 1e7),
                2.0,
                0,
            )
        )
    return out


def test_mavproxy_lean_install_downloads_every_parameter_and_the_mission(sitl, tmp_path):
    v = vehicle(sitl)
    v.wait_until(30, "global position", lambda: v.global_pos is not None)
    upload(v, waypoints(v, 4))
    v.close()
    mavproxy = Path(sys.executable).with_name("mavproxy.py")
    assert mavproxy.exists(), "MAVProxy is installed (scripts/test: requirements-mavproxy.txt, --no-deps)"
    # MAVProxy reads commands from standard input once it runs; give it the connection first.
    script = "wp list\nparam show RTL_RETURN_ALT\nparam show LOOP_INNER_HZ\n"
    proc = subprocess.Popen(
        [
            sys.executable,
            str(mavproxy),
            f"--master=udpin:127.0.0.1:{link.api_port(sitl.instance)}",
            "--source-system=250",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=tmp_path,
    )
    assert proc.stdin is not None and proc.stdout is not None
    stdin, stdout = proc.stdin, proc.stdout
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(stdout.readline, "")), daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 60
        sent = False
        while time.monotonic() < deadline:
            output = "".join(lines)
            if not sent and f"Received {PARAM_COUNT} parameters" in output:
                stdin.write(script)
                stdin.flush()
                sent = True
            after = output.split(f"Received {PARAM_COUNT} parameters")[-1]
            if sent and "RTL_RETURN_ALT" in after and "LOOP_INNER_HZ" in after and "Requesting 4 waypoints" in after:
                break
            time.sleep(0.1)
        time.sleep(1.0)
    finally:
        proc.kill()
        proc.wait()
    output = "".join(lines)
    print(output[-3000:])
    assert "online system" in output
    assert f"Received {PARAM_COUNT} parameters" in output, "every parameter downloaded"
    assert "Requesting 4 waypoints" in output, "the mission downloaded"
    assert "RTL_RETURN_ALT" in output.split(f"Received {PARAM_COUNT} parameters")[-1]
    saved = (tmp_path / f"mav_{sitl.instance + 1}_1.parm").read_text().splitlines()
    assert len([line for line in saved if line.strip()]) == PARAM_COUNT
    # MAVProxy decodes a PX4's INT32 parameters bytewise: the whole 500, not the float of its bytes.
    assert ["LOOP_INNER_HZ", "500"] in [line.split() for line in saved], [ln for ln in saved if "LOOP" in ln]


# -- QGroundControl -----------------------------------------------------------------------------------


def test_the_qgroundcontrol_connection_sequence_completes(sitl):
    """As QGroundControl's PX4 plugin connects: heartbeats, AUTOPILOT_VERSION, the full parameter list
    (re-asking missing indices), the plan (mission, fence, rally), a mode change with the SET_MODE
    message, then a takeoff sent before arming."""
    v = vehicle(sitl)
    sysid = v.system_id
    # AUTOPILOT_VERSION by REQUEST_MESSAGE.
    v.send(v.conn.mav.command_long_encode(sysid, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0))
    version = v.next_message(10, lambda m: m.get_type() == "AUTOPILOT_VERSION")
    assert version is not None, "AUTOPILOT_VERSION"
    for bit in ("MISSION_INT", "COMMAND_INT", "MAVLINK2", "PARAM_ENCODE_BYTEWISE", "MISSION_FENCE", "MISSION_RALLY"):
        assert version.capabilities & getattr(mavlink, f"MAV_PROTOCOL_CAPABILITY_{bit}"), bit
    assert not version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
    assert version.flight_sw_version >> 8 >= 0x010F00, hex(version.flight_sw_version)
    # The full parameter list; missing indices re-requested one by one.
    v.send(v.conn.mav.param_request_list_encode(sysid, 1))
    values, count = {}, None
    quiet_since = time.monotonic()
    while count is None or len(values) < count:
        msg = v.next_message(2, lambda m: m.get_type() == "PARAM_VALUE")
        if msg is not None:
            count = msg.param_count
            values[msg.param_index] = msg
            quiet_since = time.monotonic()
        elif count is not None and time.monotonic() - quiet_since > 1.0:
            for index in sorted(set(range(count)) - set(values)):
                v.send(v.conn.mav.param_request_read_encode(sysid, 1, b"", index))
        assert time.monotonic() - quiet_since < 20, f"{len(values)} of {count} parameters"
    assert count == PARAM_COUNT
    # Each parameter in its own type: integers and switches INT32 (bytewise), reals REAL32.
    types = {m.param_id: m.param_type for m in values.values()}
    assert types == {name: getattr(mavlink, f"MAV_PARAM_TYPE_{t}") for name, (t, _) in PARAM_ROWS.items()}
    assert (types["NAV_DLL_ACT"], types["ACO_ADAPT_EN"]) == (mavlink.MAV_PARAM_TYPE_INT32,) * 2
    assert (types["ACO_WEIGHTS_HZ"], types["COM_DL_LOSS_T"]) == (mavlink.MAV_PARAM_TYPE_REAL32,) * 2
    assert {"MIS_TAKEOFF_ALT", "RTL_RETURN_ALT"} <= {m.param_id for m in values.values()}
    # The plan: mission (type 0), geofence (1), rally points (2).
    for mission_type in (
        mavlink.MAV_MISSION_TYPE_MISSION,
        mavlink.MAV_MISSION_TYPE_FENCE,
        mavlink.MAV_MISSION_TYPE_RALLY,
    ):
        v.send(v.conn.mav.mission_request_list_encode(sysid, 1, mission_type))
        msg = v.next_message(10, lambda m, t=mission_type: m.get_type() == "MISSION_COUNT" and m.mission_type == t)
        assert msg is not None, f"MISSION_COUNT of type {mission_type}"
        assert msg.count == 0, f"type {mission_type}: nothing uploaded yet"
        v.send(v.conn.mav.mission_ack_encode(sysid, 1, mavlink.MAV_MISSION_ACCEPTED, mission_type))
    # The plan view's upload of a geofence (an inclusion polygon and an exclusion circle) and a rally point,
    # each with its mission_type on every message, then read back identical.
    lat0, lon0 = 473977420, 85455940  # around the SITL's home (degE7)
    fence = [
        (mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4, lat0 + dn, lon0 + de)
        for dn, de in [(-3000, -4000), (3000, -4000), (3000, 4000), (-3000, 4000)]
    ] + [(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 5, lat0 + 1500, lon0 + 1500)]
    rally = [(mavlink.MAV_CMD_NAV_RALLY_POINT, 0, lat0 + 1000, lon0)]
    for mission_type, items in ((mavlink.MAV_MISSION_TYPE_FENCE, fence), (mavlink.MAV_MISSION_TYPE_RALLY, rally)):
        v.send(v.conn.mav.mission_count_encode(sysid, 1, len(items), mission_type))
        while True:
            kinds = ("MISSION_REQUEST_INT", "MISSION_ACK")
            msg = v.next_message(10, lambda m, k=kinds, t=mission_type: m.get_type() in k and m.mission_type == t)
            assert msg is not None, f"type {mission_type}: upload stalled"
            if msg.get_type() == "MISSION_ACK":
                assert msg.type == mavlink.MAV_MISSION_ACCEPTED, msg
                break
            command, p1, x, y = items[msg.seq]
            frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
            v.send(
                v.conn.mav.mission_item_int_encode(
                    sysid, 1, msg.seq, frame, command, 0, 1, p1, 0, 0, 0, x, y, 10.0, mission_type
                )
            )
        v.send(v.conn.mav.mission_request_list_encode(sysid, 1, mission_type))
        msg = v.next_message(10, lambda m, t=mission_type: m.get_type() == "MISSION_COUNT" and m.mission_type == t)
        assert msg is not None and msg.count == len(items)
        for seq, (command, p1, x, y) in enumerate(items):
            v.send(v.conn.mav.mission_request_int_encode(sysid, 1, seq, mission_type))
            got = v.next_message(10, lambda m, s=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == s)
            assert got is not None and (got.command, got.param1, got.x, got.y, got.mission_type) == (
                command,
                p1,
                x,
                y,
                mission_type,
            )
        v.send(v.conn.mav.mission_ack_encode(sysid, 1, mavlink.MAV_MISSION_ACCEPTED, mission_type))
    # A mode change with the SET_MODE message (PX4 POSCTL), then back to Hold.
    for custom_mode in (3 << 16, (4 << 16) | (3 << 24)):
        # POSCTL flies the sticks: a joystick's MANUAL_CONTROL (centred, throttle at hold) first.
        v.send(v.conn.mav.manual_control_encode(sysid, 0, 0, 500, 0, 0))
        v.send(v.conn.mav.set_mode_encode(sysid, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom_mode))
        v.wait_until(10, f"custom mode {custom_mode:#x}", lambda c=custom_mode: v.custom_mode == c)
    # Takeoff before arming (AMSL altitude, NaN position), then arm: it climbs.
    v.wait_until(30, "estimator", lambda: v.prearm_ok and v.global_pos is not None)
    home_amsl_m = v.global_pos.alt * 1e-3 - v.global_pos.relative_alt * 1e-3
    nan = float("nan")
    v.require("takeoff", mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, nan, nan, nan, home_amsl_m + 2.0)
    v.require("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    v.wait_until(30, "climb to 2 m", lambda: v.pos is not None and -v.pos[2] > 1.8)
    v.close()
