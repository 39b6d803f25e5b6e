"""The failsafes flown through `sitl run` with pymavlink as a ground station flies them: the ground station
that goes silent in a mission, the pack drained by SIM_BAT_DRAIN, the geofence (a goto beyond it, an
offboard velocity pushing through it, a polygon uploaded, downloaded and kept across a restart). The
autopilot runs with `--estimator truth`, so LOCAL_POSITION_NED is the plant's truth: every flight is judged
on where the vehicle really is. Paced at 4x real time: wall latencies of a few milliseconds stay well
under 0.1 s of vehicle time. Every wait is on the vehicle's clock; a wall-clock limit only stops a hung run."""

import math

import pytest
from sitl_harness import connect, start_sitl

from aco_gcs.figure8_mission import Item, offset_deg, upload
from aco_gcs.flight import takeoff, wait_ready
from aco_gcs.link import (
    PX4_AUTO_LOITER,
    PX4_MAIN_AUTO,
    Params,
    Plant,
    mavlink,
)

SPEED = "4"
PX4_AUTO_RTL = 5
FENCE = mavlink.MAV_MISSION_TYPE_FENCE


@pytest.fixture
def run_sitl(tmp_path):
    """Starts `sitl run` (restartable on the same state directory); stops whatever is running at the end."""
    running: list = []

    def start(speed=SPEED):
        s = start_sitl(tmp_path, "--estimator", "truth", speed=speed, instance=running[0].instance if running else None)
        running.append(s)
        return s

    yield start
    for s in running:
        s.stop()
    if running:
        print(running[-1].log_tail())


def said(vehicle, text):
    """The vehicle times (s) at which STATUSTEXT `text` arrived."""
    return [t for (t, _, got) in vehicle.statustexts if got == text]


def horizontal_m(a, b):
    return math.hypot(a[0] - b[0], a[1] - b[1])


def test_gcs_silent_in_a_mission_with_nav_dll_act_2_returns_after_com_dl_loss_t_and_lands_home(run_sitl):
    vehicle = connect(run_sitl())
    params = Params(vehicle, 1)
    params.require_set("NAV_DLL_ACT", 2)
    params.require_set("COM_DL_LOSS_T", 5)
    ground, _ = wait_ready(vehicle)
    home = vehicle.global_pos
    lat0, lon0 = home.lat / 1e7, home.lon / 1e7
    rel = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    nan = float("nan")

    def at(n: float, e: float) -> tuple[int, int]:
        lat, lon = offset_deg(lat0, lon0, n, e)
        return round(lat * 1e7), round(lon * 1e7)

    items = [Item(mavlink.MAV_CMD_NAV_TAKEOFF, rel, (0, 0, 0, nan), *at(0, 0), 5.0)]
    items += [
        Item(mavlink.MAV_CMD_NAV_WAYPOINT, rel, (0, 0, 0, nan), *at(n, e), 5.0) for n, e in [(20, 0), (20, 20), (0, 20)]
    ]
    upload(vehicle, items)
    vehicle.require("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    vehicle.set_px4_mode(PX4_MAIN_AUTO, 4, "AUTO MISSION")
    vehicle.wait_until(30.0, "15 m out", lambda: vehicle.pos is not None and horizontal_m(vehicle.pos, ground) > 15.0)
    # The ground station goes silent: no more HEARTBEATs (it keeps listening).
    last_heartbeat_s = vehicle._last_gcs_heartbeat[0]
    vehicle.before_pump = lambda: None
    text = "Failsafe: GCS link lost, returning"
    vehicle.wait_until(
        10.0, "RTL, announced", lambda: vehicle.px4_mode() == (PX4_MAIN_AUTO, PX4_AUTO_RTL) and said(vehicle, text)
    )
    vehicle.wait_until(90.0, "landed and disarmed", lambda: not vehicle.armed)
    announced = said(vehicle, text)
    after_s = announced[0] - last_heartbeat_s
    landed_m = horizontal_m(vehicle.pos, ground)
    print(
        f"datalink loss through sitl run: RTL announced {after_s:.3f} s after the last HEARTBEAT, "
        f"landed {landed_m:.3f} m from home"
    )
    assert len(announced) == 1
    assert abs(after_s - 5.0) <= 0.1 + 0.05, (
        f"{after_s} s (the last telemetry time before the HEARTBEAT went out is 50 ms coarse)"
    )
    assert landed_m < 0.2


def test_pack_drained_by_sim_bat_drain_warns_returns_and_lands_before_empty(run_sitl):
    # At 10x: this flight is 300 s of vehicle time, and nothing in it is timed to a tenth of a second.
    sitl = run_sitl("10")
    vehicle = connect(sitl)
    ground, _ = wait_ready(vehicle)
    battery = []
    vehicle.listeners.append(
        lambda m: battery.append(m.battery_remaining) if m.get_type() == "BATTERY_STATUS" else None
    )
    vehicle.wait_until(3.0, "BATTERY_STATUS", lambda: battery)
    assert battery[-1] >= 99, "a full pack (the avionics draw from the start)"
    # Drained linearly in 300 s of motor time (1 % every 3 s): low (15 %) after 255 s, critical (7 %)
    # after 279 s, then the return (from 3 m over home: RTL_RETURN_ALT 3 m, so straight down at 0.7 m/s)
    # has 12 s before BAT_EMERGEN_THR 3 %.
    Params(vehicle, 1).require_set("BAT_EMERGEN_THR", 0.03)
    Params(vehicle, 1).require_set("RTL_RETURN_ALT", 3)
    plant = Plant(sitl.instance, 60.0)
    plant.hello()
    Params(plant, plant.component).require_set("SIM_BAT_DRAIN", 300)
    takeoff(vehicle, 3.0, ground)
    vehicle.wait_until(300.0, "RTL", lambda: vehicle.px4_mode() == (PX4_MAIN_AUTO, PX4_AUTO_RTL))
    vehicle.wait_until(60.0, "landed and disarmed", lambda: not vehicle.armed)
    texts = [t for (_, _, t) in vehicle.statustexts]
    low = [t for t in texts if t.startswith("Battery low:")]
    critical = [t for t in texts if t.startswith("Failsafe: battery critical")]
    print(
        f"battery through sitl run: {low} then {critical}; landed with {battery[-1]} % "
        f"at {horizontal_m(vehicle.pos, ground):.3f} m from home"
    )
    assert low == ["Battery low: 14% remaining"]
    assert len(critical) == 1 and critical[0].endswith("returning")
    assert texts.index(low[0]) < texts.index(critical[0])
    assert battery[-1] > 0, "landed before the pack was empty"
    assert horizontal_m(vehicle.pos, ground) < 0.2


def fence_items(lat0, lon0):
    """A 60 m x 60 m inclusion square around home, as QGroundControl sends it (5001, param1 = 4)."""
    items = []
    for n, e in [(-30, -30), (30, -30), (30, 30), (-30, 30)]:
        lat, lon = offset_deg(lat0, lon0, n, e)
        items.append((round(lat * 1e7), round(lon * 1e7)))
    return items


def upload_fence(vehicle, vertices):
    vehicle.conn.mav.mission_count_send(vehicle.system_id, 1, len(vertices), FENCE)
    while True:
        msg = vehicle.next_message(
            5.0, lambda m: m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        )
        assert msg is not None, "fence upload: no answer"
        assert msg.mission_type == FENCE
        if msg.get_type() == "MISSION_ACK":
            return msg.type
        x, y = vertices[msg.seq]
        vehicle.conn.mav.mission_item_int_send(
            vehicle.system_id,
            1,
            msg.seq,
            mavlink.MAV_FRAME_GLOBAL,
            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            0,
            1,
            len(vertices),
            0,
            0,
            0,
            x,
            y,
            0.0,
            FENCE,
        )


def download_fence(vehicle):
    vehicle.conn.mav.mission_request_list_send(vehicle.system_id, 1, FENCE)
    count = vehicle.next_message(5.0, lambda m: m.get_type() == "MISSION_COUNT" and m.mission_type == FENCE)
    assert count is not None, "no fence MISSION_COUNT"
    got = []
    for seq in range(count.count):
        vehicle.conn.mav.mission_request_int_send(vehicle.system_id, 1, seq, FENCE)
        item = vehicle.next_message(5.0, lambda m, s=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == s)
        assert item is not None and item.mission_type == FENCE
        assert item.command == mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION and item.param1 == count.count
        got.append((item.x, item.y))
    vehicle.conn.mav.mission_ack_send(vehicle.system_id, 1, mavlink.MAV_MISSION_ACCEPTED, FENCE)
    return got


def test_geofence_refuses_a_goto_beyond_it_holds_an_offboard_push_and_keeps_a_polygon_across_a_restart(run_sitl):
    first = run_sitl()
    vehicle = connect(first)
    params = Params(vehicle, 1)
    params.require_set("GF_MAX_HOR_DIST", 10)
    ground, _ = wait_ready(vehicle)
    home = vehicle.global_pos
    lat0, lon0 = home.lat / 1e7, home.lon / 1e7
    # A polygon fence: uploaded, downloaded back identical.
    square = fence_items(lat0, lon0)
    assert upload_fence(vehicle, square) == mavlink.MAV_MISSION_ACCEPTED
    assert download_fence(vehicle) == square
    takeoff(vehicle, 3.0, ground)
    # A goto 20 m away: refused with the reason, not flown.
    lat, lon = offset_deg(lat0, lon0, 20, 0)
    since = vehicle.now_s()
    vehicle.conn.mav.command_int_send(
        vehicle.system_id,
        1,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink.MAV_CMD_DO_REPOSITION,
        0,
        0,
        -1,
        0,
        0,
        float("nan"),
        round(lat * 1e7),
        round(lon * 1e7),
        3.0,
    )
    vehicle.wait_until(5.0, "the reposition's ACK", lambda: mavlink.MAV_CMD_DO_REPOSITION in vehicle.acks)
    assert vehicle.acks[mavlink.MAV_CMD_DO_REPOSITION] == mavlink.MAV_RESULT_DENIED
    vehicle.wait_until(
        2.0, "the refusal's reason", lambda: "Reposition: beyond GF_MAX_HOR_DIST" in vehicle.texts_since(since)
    )
    # An offboard velocity north at 1.5 m/s: the vehicle holds before the fence, on the truth.
    farthest = [0.0]

    def stream():
        vehicle.conn.mav.set_position_target_local_ned_send(
            0,
            vehicle.system_id,
            1,
            mavlink.MAV_FRAME_LOCAL_NED,
            7 | 448 | 1024 | 2048,
            0,
            0,
            0,
            1.5,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
        )
        if vehicle.pos is not None:
            farthest[0] = max(farthest[0], horizontal_m(vehicle.pos, ground))

    for _ in range(5):
        stream()
        vehicle.pump()
    vehicle.set_px4_mode(6, 0, "OFFBOARD")
    start = vehicle.now_s()
    last = 0.0
    while vehicle.now_s() - start < 20.0:
        if vehicle.now_s() - last >= 0.05:
            last = vehicle.now_s()
            stream()
        vehicle.pump()
    print(f"geofence through sitl run: farthest {farthest[0]:.2f} m from home with GF_MAX_HOR_DIST 10 m")
    assert said(vehicle, "Failsafe: fence, beyond GF_MAX_HOR_DIST, holding"), vehicle.statustexts
    assert vehicle.px4_mode() == (PX4_MAIN_AUTO, PX4_AUTO_LOITER)
    assert farthest[0] < 10.5
    # The fence outlives a restart of the SITL on the same state directory.
    vehicle.close()
    first.stop()
    vehicle = connect(run_sitl())
    assert download_fence(vehicle) == square
    vehicle.close()
