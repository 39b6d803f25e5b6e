"""The scripts' pure parts, without a vehicle: parameter files, REAL32 formatting and PX4's bytewise INT32
encoding, the figure-8 mission's geometry, the gust metrics, the instance's ports and the plant's truth
client."""

import argparse
import math
import socket
import struct
import time
from pathlib import Path

import pytest

from aco_gcs import figure8_mission, gust_hover, link, params


def test_a_script_of_instance_n_listens_on_its_api_port_and_talks_to_its_autopilot():
    p = argparse.ArgumentParser()
    link.add_link_args(p)
    assert link.resolve_link(p.parse_args([])) == ("udpin:127.0.0.1:14540", "127.0.0.1:18570")
    assert link.resolve_link(p.parse_args(["-i", "3"])) == ("udpin:127.0.0.1:14543", "127.0.0.1:18573")
    # The API ports skip QGroundControl's 14550, which every instance sends to.
    assert [link.api_port(n) for n in (9, 10, 254)] == [14549, 14551, 14795]
    with pytest.raises(link.GcsError):
        link.api_port(255)
    # An explicit connection keeps pymavlink's own addressing unless a target is given too.
    assert link.resolve_link(p.parse_args(["--connect", "tcp:127.0.0.1:5760"])) == ("tcp:127.0.0.1:5760", None)


def test_parameter_values_round_trip_as_real32_text():
    for value in (0.6667, 2.16, 12.3, 0.0, -5.0, 1e-7, 123456.78, 3.25):
        text = params.format_value(value)
        assert link.same_float32(float(text), value), (value, text)
    assert params.format_value(4.0) == "4"
    assert params.format_value(6.7) == "6.7"


def test_integer_parameters_travel_bytewise_as_px4_encodes_them():
    mav = link.mavlink

    def bits(field):
        return struct.unpack("<I", struct.pack("<f", field))[0]

    # The int32's bytes as they are in the float field: 2 is the denormal 2.8e-45, -3 is 0xFFFFFFFD.
    for value, expected_bits in [(2, 0x2), (500, 0x1F4), (0, 0x0), (-3, 0xFFFF_FFFD)]:
        field = link.encode_param(value, mav.MAV_PARAM_TYPE_INT32)
        assert bits(field) == expected_bits, (value, hex(bits(field)))
        assert link.decode_param(field, mav.MAV_PARAM_TYPE_INT32) == value
    assert 0 < link.encode_param(2, mav.MAV_PARAM_TYPE_INT32) < 1e-44
    for param_type, value, expected_bits in [
        (mav.MAV_PARAM_TYPE_UINT8, 255, 0xFF),
        (mav.MAV_PARAM_TYPE_INT8, -128, 0x80),
        (mav.MAV_PARAM_TYPE_UINT16, 65535, 0xFFFF),
        (mav.MAV_PARAM_TYPE_INT16, -2, 0xFFFE),
        (mav.MAV_PARAM_TYPE_UINT32, 7, 0x7),
    ]:
        field = link.encode_param(value, param_type)
        assert bits(field) == expected_bits and link.decode_param(field, param_type) == value, param_type
    # A REAL32 is the float itself, both ways.
    assert link.encode_param(2, mav.MAV_PARAM_TYPE_REAL32) == 2.0
    assert link.decode_param(2.5, mav.MAV_PARAM_TYPE_REAL32) == 2.5
    assert link.int_fits(5, mav.MAV_PARAM_TYPE_INT32) and link.int_fits(5.0, mav.MAV_PARAM_TYPE_UINT8)
    assert not link.int_fits(2.5, mav.MAV_PARAM_TYPE_INT32)
    assert not link.int_fits(float("nan"), mav.MAV_PARAM_TYPE_INT32)
    assert not link.int_fits(1e20, mav.MAV_PARAM_TYPE_INT32) and not link.int_fits(256, mav.MAV_PARAM_TYPE_UINT8)


def test_parameter_files_in_mavproxy_and_qgroundcontrol_style_parse():
    text = "# comment\nMIS_TAKEOFF_ALT  2.5\nNAV_ACC_RAD,0.2  # trailing\n\n1\t1\tACO_POS_P\t0.6667\t9\n"
    assert params.parse_file(text) == [("MIS_TAKEOFF_ALT", 2.5), ("NAV_ACC_RAD", 0.2), ("ACO_POS_P", 0.6667)]
    with pytest.raises(link.GcsError, match="line 1"):
        params.parse_file("JUST_A_NAME\n")
    with pytest.raises(link.GcsError, match="not a number"):
        params.parse_file("NAME abc\n")


def test_figure8_mission_items_sit_on_the_grid_around_home():
    lat0, lon0 = 47.397742, 8.545594
    items = figure8_mission.build_mission(lat0, lon0, 1.5, 0.3)
    mav = link.mavlink
    assert [it.command for it in items[:2]] == [mav.MAV_CMD_NAV_TAKEOFF, mav.MAV_CMD_DO_CHANGE_SPEED]
    assert items[-1].command == mav.MAV_CMD_NAV_LAND and len(items) == 12
    assert items[1].params[1] == 0.3
    wps = [it for it in items if it.command == mav.MAV_CMD_NAV_SPLINE_WAYPOINT]
    assert all(it.frame == mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT and it.z == 1.5 for it in wps)
    for it, (n, e) in zip(wps, figure8_mission.FIGURE8_NE_M, strict=True):
        dn = math.radians(it.x / 1e7 - lat0) * figure8_mission.EARTH_RADIUS_M
        de = math.radians(it.y / 1e7 - lon0) * figure8_mission.EARTH_RADIUS_M * math.cos(math.radians(lat0))
        assert abs(dn - n) < 0.01 and abs(de - e) < 0.01, (it, n, e)
    assert items[2].matches(items[2]) and not items[2].matches(items[3])


def test_cross_track_is_the_distance_to_the_nearest_segment():
    square = [(0, 0), (1, 0), (1, 1)]
    assert figure8_mission.cross_track_m((0.5, 0.2), square) == pytest.approx(0.2)
    assert figure8_mission.cross_track_m((1.3, 0.5), square) == pytest.approx(0.3)


def test_recovery_is_the_time_until_the_error_stays_below_the_threshold():
    samples = [(t / 10, e) for t, e in enumerate([0.0, 0.05, 0.2, 0.15, 0.08, 0.12, 0.05, 0.04, 0.03])]
    assert gust_hover.recovery_s(samples, 0.1, 0.8, 0.10) == pytest.approx(0.5)  # below from t = 0.6 on
    assert gust_hover.recovery_s(samples, 0.6, 0.8, 0.10) == 0.0
    assert gust_hover.recovery_s([(0.0, 0.2), (1.0, 0.3)], 0.0, 1.0, 0.10) is None
    assert gust_hover.plant_time(["gust 6.7 m/s to 90 deg, rise 1.0 s, t=18.80"], 3.0) == 18.8
    assert gust_hover.plant_time(["no time here"], 3.0) == 3.0


def test_scripts_write_files_only_when_asked():
    # No --png / --csv: no plot or samples file appears in the working directory.
    for module in (figure8_mission, gust_hover):
        args = module.parser().parse_args([])
        assert (args.png, args.csv) == (None, None), module.__name__


def test_the_tests_import_the_installed_package():
    # scripts/test installs gcs-scripts (editable); the tests import that, not a sys.path edit.
    import importlib.metadata

    assert importlib.metadata.distribution("aco-gcs-scripts").metadata["Name"] == "aco-gcs-scripts"
    assert Path(link.__file__).resolve().parent == Path(__file__).resolve().parents[1] / "aco_gcs"


def test_plant_truth_pairs_each_sim_state_with_its_plant_time_and_maps_it_about_the_first_sample():
    # GIVEN a stand-in for the plant's SIM_ port (system 3, component 51) and a truth client of it.
    plant = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    plant.bind(("127.0.0.1", 0))
    plant.settimeout(5.0)
    truth = link.PlantTruth(f"udpout:127.0.0.1:{plant.getsockname()[1]}", 3)
    try:
        truth.drain()  # says HEARTBEAT: the plant learns where to send
        _, client = plant.recvfrom(2048)
        mav = link.mavlink.MAVLink(None, srcSystem=3, srcComponent=link.PLANT_COMPONENT)
        lat0, lon0, alt0 = 47.3977420, 8.5455940, 488.0

        def sample(t_ms, north_m, east_m, up_m, v1=False):
            lat = lat0 + math.degrees(north_m / link.EARTH_RADIUS_M)
            lon = lon0 + math.degrees(east_m / (link.EARTH_RADIUS_M * math.cos(math.radians(lat0))))
            state = mav.sim_state_encode(
                1, 0, 0, 0, 0, 0, 0, 0, 0, -9.81, 0, 0, 0, lat, lon, alt0 + up_m, 0, 0, 0, 0, 0,
                0 if v1 else round(lat * 1e7), 0 if v1 else round(lon * 1e7),
            )  # fmt: skip
            return mav.system_time_encode(0, t_ms).pack(mav) + state.pack(mav)

        # WHEN it sends samples at 20, 40 and 60 ms (the last without the degE7 fields, as on MAVLink 1),
        # and another component's SIM_STATE in between.
        plant.sendto(sample(20, 0.0, 0.0, 0.0), client)
        other = link.mavlink.MAVLink(None, srcSystem=3, srcComponent=1)
        plant.sendto(other.sim_state_encode(*[0.0] * 21, 0, 0).pack(other), client)
        plant.sendto(sample(40, 0.03, -0.04, 1.5), client)
        plant.sendto(sample(60, 1.0, 2.0, 1.5, v1=True), client)
        deadline = time.monotonic() + 5.0
        while len(truth.samples) < 3 and time.monotonic() < deadline:
            truth.drain()
        # THEN three samples at their plant times, NED about the first: degE7 to a centimetre, and the
        # f32-degree fallback to its half-metre resolution.
        assert [t for (t, _) in truth.samples] == [0.02, 0.04, 0.06]
        assert truth.samples[0][1] == (0.0, 0.0, 0.0)
        assert math.dist(truth.samples[1][1], (0.03, -0.04, -1.5)) < 0.012
        assert math.dist(truth.samples[2][1], (1.0, 2.0, -1.5)) < 0.6
        # AND `at` gives the last sample at or before a time once a later one has come.
        assert truth.at(0.05) == truth.samples[1][1]
        assert truth.at(0.06) is None, "none later yet: a sample at 0.06 may still be coming"
        with pytest.raises(link.CheckFailed):
            truth.at(0.01)
        assert truth.window(0.03, 0.06) == [truth.samples[1][1], truth.samples[2][1]]
    finally:
        truth.close()
        plant.close()
