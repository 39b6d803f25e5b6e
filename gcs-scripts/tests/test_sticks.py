"""aco-sticks without a vehicle: MANUAL_CONTROL as PX4 reads it (x pitch, y roll, z throttle 0..1000, r yaw),
the stick script's parser and its errors, the keyboard's keys, the Linux joystick records, the stream's
pacing on the vehicle's clock, and the command line's refusals before anything is sent."""

import math
import socket
import struct

import pytest
from sitl_harness import free_instance

from aco_gcs import link, sticks
from aco_gcs.sticks import CENTRED, ScriptError, Sticks

mavlink = link.mavlink


def decode(buf):
    """The messages in `buf`, parsed by a fresh pymavlink parser (what a vehicle's MAVLink layer sees)."""
    parser = mavlink.MAVLink(None)
    return parser.parse_buffer(buf) or []


# -- MANUAL_CONTROL ----------------------------------------------------------------------------------------


def test_manual_control_carries_pitch_in_x_roll_in_y_throttle_0_to_1000_in_z_and_yaw_in_r():
    s = Sticks(roll=-0.25, pitch=0.5, yaw=1.0, throttle=0.75)
    assert sticks.manual_control_axes(s) == (500, -250, 750, 1000)
    assert sticks.manual_control_axes(CENTRED) == (0, 0, 500, 0), "centred: throttle 500 is the hold point"
    # Out of range clamps (throttle never below 0: PX4 reads z as 0..1000), NaN centres.
    wild = Sticks(roll=3.0, pitch=-7.0, yaw=float("nan"), throttle=-0.2)
    assert sticks.manual_control_axes(wild) == (-1000, 1000, 0, 0)
    assert sticks.manual_control_axes(Sticks(throttle=float("nan"))) == (0, 0, 500, 0)
    # Halves round away from zero, as the vehicle's own Sticks::to_manual_control (not Python's to-even).
    assert sticks.manual_control_axes(Sticks(roll=0.0005, pitch=-0.0025, yaw=0.0015, throttle=0.0025)) == (
        -3,
        1,
        3,
        2,
    )


def test_manual_control_message_goes_to_the_vehicles_system_and_decodes_to_the_sticks():
    sender = mavlink.MAVLink(None, srcSystem=link.GCS_SYSTEM, srcComponent=link.GCS_COMPONENT)
    sender.robust_parsing = True
    msg = sticks.manual_control_message(sender, 7, Sticks(roll=0.1, pitch=-1.0, yaw=-0.3, throttle=0.0))
    (got,) = decode(msg.pack(sender))
    assert got.get_type() == "MANUAL_CONTROL" and got.get_msgId() == 69
    assert (got.target, got.x, got.y, got.z, got.r, got.buttons) == (7, -1000, 100, 0, -300, 0)
    assert (got.get_srcSystem(), got.get_srcComponent()) == (link.GCS_SYSTEM, link.GCS_COMPONENT)


# -- the script --------------------------------------------------------------------------------------------


def test_a_stick_script_gives_each_step_its_duration_and_sticks_with_the_rest_centred():
    steps = sticks.parse_script(
        """
        [[step]]
        for_s = 3
        throttle = 0.8

        [[step]]
        for_s = 2.5
        pitch = 1.0
        roll = -0.5
        yaw = 0.25

        [[step]]
        for_s = 1e-3
        throttle = 0
        """
    )
    assert steps == [
        sticks.Step(3.0, Sticks(throttle=0.8)),
        sticks.Step(2.5, Sticks(pitch=1.0, roll=-0.5, yaw=0.25)),
        sticks.Step(0.001, Sticks(throttle=0.0)),
    ]
    assert all(isinstance(s.for_s, float) for s in steps)


@pytest.mark.parametrize(
    "text, error",
    [
        ("[[step]]\nfor_s = 1\nthrotle = 0.6\n", "step 1: unknown key(s) throtle"),
        ("[[step]]\nfor_s = 1\n[[step]]\nfor_s = 1\npitch = 1.5\n", "step 2: pitch = 1.5 is outside -1..1"),
        ("[[step]]\nfor_s = 1\nroll = -1.01\n", "step 1: roll = -1.01 is outside -1..1"),
        ("[[step]]\nfor_s = 1\nyaw = 2\n", "step 1: yaw = 2 is outside -1..1"),
        ("[[step]]\nfor_s = 1\nthrottle = -0.1\n", "step 1: throttle = -0.1 is outside 0..1"),
        ("[[step]]\nfor_s = 1\nthrottle = 1.2\n", "step 1: throttle = 1.2 is outside 0..1"),
        ("[[step]]\npitch = 1\n", "step 1: for_s (its duration, s of vehicle time) is missing"),
        ("[[step]]\nfor_s = 0\n", "step 1: for_s = 0 must be > 0"),
        ("[[step]]\nfor_s = -2\n", "step 1: for_s = -2 must be > 0"),
        ("[[step]]\nfor_s = 3601\n", "at most 3600 s"),
        ("[[step]]\nfor_s = nan\n", "step 1: for_s must be finite"),
        ("[[step]]\nfor_s = inf\n", "step 1: for_s must be finite"),
        ("[[step]]\nfor_s = 1\npitch = '1'\n", "step 1: pitch must be a number, got '1'"),
        ("[[step]]\nfor_s = true\n", "step 1: for_s must be a number, got True"),
        ("[[step]]\nfor_s = 1\nthrottle = nan\n", "step 1: throttle must be finite"),
        ("", "no [[step]]: nothing to fly"),
        ("step = []\n", "no [[step]]: nothing to fly"),
        ("step = 3\n", "`step` must be an array of tables"),
        ("step = [1, 2]\n", "`step` must be an array of tables"),
        ("rate = 50\n[[step]]\nfor_s = 1\n", "unknown key(s) rate"),
        ("[[step]\nfor_s = 1\n", "not TOML"),
    ],
)
def test_a_stick_script_with_a_bad_step_is_refused_naming_the_step_and_key(text, error):
    with pytest.raises(ScriptError) as refused:
        sticks.parse_script(text, "s.toml")
    assert str(refused.value).startswith("s.toml: ") and error in str(refused.value), refused.value


def test_a_missing_or_binary_script_file_is_refused_in_words(tmp_path):
    with pytest.raises(ScriptError, match=r"cannot read .*missing\.toml"):
        sticks.load_script(tmp_path / "missing.toml")
    binary = tmp_path / "b.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ScriptError, match="not UTF-8"):
        sticks.load_script(binary)


def test_check_prints_the_steps_and_flies_nothing(tmp_path, capsys):
    script = tmp_path / "fwd.toml"
    script.write_text("[[step]]\nfor_s = 2\nthrottle = 0.75\n[[step]]\nfor_s = 3\npitch = 0.5\n")
    assert sticks.main(["--script", str(script), "--check"]) == 0
    out = capsys.readouterr().out
    assert "step 1/2 for 2 s: pitch +0.00 roll +0.00 yaw +0.00 throttle 0.75" in out
    assert "step 2/2 for 3 s: pitch +0.50" in out and "2 steps, 5 s of vehicle time" in out


def test_a_bad_script_exits_1_before_looking_for_a_vehicle(tmp_path, capsys):
    script = tmp_path / "bad.toml"
    script.write_text("[[step]]\nfor_s = 2\npitch = 4\n")
    n = free_instance(200, 254)
    # No vehicle on instance n: a script that got as far as connecting would exit 2 (no HEARTBEAT).
    assert sticks.main(["--instance", str(n), "--heartbeat-timeout", "5", "--script", str(script)]) == 1
    err = capsys.readouterr().err
    assert "aco-sticks: error:" in err and "step 1: pitch = 4 is outside -1..1" in err, err


def test_sticks_exits_2_without_a_vehicle_naming_the_port(tmp_path, capsys):
    script = tmp_path / "ok.toml"
    script.write_text("[[step]]\nfor_s = 1\n")
    n = free_instance(200, 254)
    assert sticks.main(["--instance", str(n), "--heartbeat-timeout", "1", "--script", str(script)]) == 2
    err = capsys.readouterr().err
    assert f"no vehicle HEARTBEAT on udpin:127.0.0.1:{link.api_port(n)}" in err, err


def test_a_missing_gamepad_device_is_refused_before_connecting(tmp_path, capsys):
    n = free_instance(200, 254)
    device = tmp_path / "js9"
    assert sticks.main(["--instance", str(n), "--heartbeat-timeout", "5", "--gamepad", str(device)]) == 1
    err = capsys.readouterr().err
    assert f"cannot open {device}" in err and "QGroundControl's joystick support" in err, err


# -- the keyboard ------------------------------------------------------------------------------------------


def test_keys_arrive_as_characters_and_arrow_escape_sequences():
    assert sticks.parse_keys("w\x1b[A\x1b[B\x1b[C\x1b[Dx") == ["w", "up", "down", "right", "left", "x"]
    assert sticks.parse_keys("\x1bOA ") == ["up", " "], "application-mode arrows"
    assert sticks.parse_keys("\x1b") == ["\x1b"], "a lone escape is a key of its own (ignored)"


def test_each_key_moves_its_stick_one_notch_within_range_and_space_centres():
    s = CENTRED
    for key in ("up", "w", "w", "w", "w"):  # five notches of 0.25: clamped at full forward
        s, action = sticks.apply_key(s, key)
        assert action is None
    assert s.pitch == 1.0
    s, _ = sticks.apply_key(s, "a")
    s, _ = sticks.apply_key(s, "left")
    assert s.roll == -0.5
    s, _ = sticks.apply_key(s, "E")  # case does not matter
    assert s.yaw == 0.25
    for _ in range(7):
        s, _ = sticks.apply_key(s, "r")
    assert s.throttle == 1.0
    for _ in range(3):
        s, _ = sticks.apply_key(s, "f")
    assert s.throttle == pytest.approx(0.7)
    assert sticks.apply_key(s, " ") == (CENTRED, None)
    assert sticks.apply_key(s, "l") == (Sticks(throttle=0.0), "land")
    assert sticks.apply_key(s, "t") == (s, "arm")
    assert sticks.apply_key(s, "x") == (s, "quit")
    assert sticks.apply_key(s, "z") == (s, None)


# -- the gamepad (struct js_event) -------------------------------------------------------------------------


def js_event(value, kind, number, t_ms=0):
    return struct.pack("<IhBB", t_ms, value, kind, number)


def test_joystick_records_decode_as_axes_and_buttons_with_the_init_flag_dropped():
    data = (
        js_event(-32767, 0x02, 1)
        + js_event(1, 0x01 | 0x80, 0)  # the driver's initial state of button 0
        + js_event(12000, 0x02 | 0x80, 3)
        + js_event(5, 0x40, 9)  # an unknown kind: skipped
        + js_event(1, 0x01, 1)[:5]  # half a record: left for the next read
    )
    assert sticks.decode_js_events(data) == [("axis", 1, -32767), ("button", 0, 1), ("axis", 3, 12000)]


def test_gamepad_axes_map_stick_up_to_pitch_forward_and_throttle_high():
    axes = (3, 4, 1, 0)  # roll, pitch, throttle, yaw
    assert sticks.gamepad_sticks({}, axes) == Sticks(throttle=0.5), "no event yet: centred"
    s = sticks.gamepad_sticks({3: 32767, 4: -32767, 1: -32767, 0: -16384}, axes)
    assert (s.roll, s.pitch, s.throttle) == (1.0, 1.0, 1.0)
    assert s.yaw == pytest.approx(-0.5, abs=1e-4)
    assert sticks.gamepad_sticks({1: 32767, 4: 32767}, axes) == Sticks(pitch=-1.0, throttle=0.0)
    # -32768 (some drivers' end) clamps.
    assert sticks.gamepad_sticks({3: -32768}, axes).roll == -1.0


@pytest.mark.parametrize("text", ["1,2,3", "1,2,3,x", "1,1,2,3", "", "-1,2,3,4"])
def test_gamepad_axes_option_takes_four_different_axis_numbers(text):
    with pytest.raises(Exception, match="--axes"):
        sticks.parse_axes(text)


# -- the stream ----------------------------------------------------------------------------------------------


def test_the_stream_sends_the_current_sticks_every_period_of_vehicle_time(monkeypatch):
    """With the wall clock standing still, the stream is paced by the vehicle's clock alone: at 25 Hz, one
    MANUAL_CONTROL every 40 ms of telemetry time, carrying whatever `sticks` holds then."""
    wall = [1000.0]
    monkeypatch.setattr(sticks.time, "monotonic", lambda: wall[0])
    vehicle_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle_sock.bind(("127.0.0.1", 0))
    vehicle_sock.settimeout(2.0)
    pilot = sticks.PilotVehicle("udpin:127.0.0.1:0", f"127.0.0.1:{vehicle_sock.getsockname()[1]}")
    try:
        pilot.system_id = 4
        pilot.before_pump()
        assert pilot.sent == 0, "no sticks yet: nothing sent"
        pilot.sticks = Sticks(pitch=0.5)
        for step in range(10):  # 0..180 ms of vehicle time, 20 ms apart
            pilot.now_ms = 5000 + 20 * step
            if step == 5:
                pilot.sticks = Sticks(roll=-1.0, throttle=0.6)
            pilot.before_pump()
        assert pilot.sent == 5
        got: list = []
        while len(got) < 5:
            got += [m for m in decode(vehicle_sock.recv(4096)) if m.get_type() == "MANUAL_CONTROL"]
        assert [(m.target, m.x, m.y, m.z, m.r) for m in got] == [(4, 500, 0, 500, 0)] * 3 + [(4, 0, -1000, 600, 0)] * 2
        # The wall clock alone paces it too (a vehicle whose telemetry stalls still hears the sticks).
        wall[0] += 0.05
        pilot.before_pump()
        assert pilot.sent == 6
        # On telemetry ticks of 20 ms, 25 a second of vehicle time on average (one per 40 ms), not one per
        # 60 ms as "a period since the last send" would give with the vehicle time 20 ms coarse.
        pilot.period_s = 1 / 25
        for tick in range(1, 51):
            pilot.now_ms = 6000 + 20 * tick
            pilot.before_pump()
        assert pilot.sent == 6 + 25
        assert pilot.last_sent_s == pytest.approx(6.98), "6.02, 6.06, ... 6.98"
    finally:
        pilot.close()
        vehicle_sock.close()


def test_track_keeps_every_local_position_and_prints_at_its_interval(capsys):
    class Clock:
        now = 0.0

        def now_s(self):
            return self.now

    clock = Clock()
    track = sticks.Track(clock, 0.5)
    mav = mavlink.MAVLink(None)
    for k in range(11):  # 0..1 s every 0.1 s
        clock.now = k / 10
        track(mav.local_position_ned_encode(k * 100, 0.1 * k, 0.0, -1.0, 1.0, 0.0, 0.0))
    assert len(track.samples) == 11
    lines = [line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("t ")]
    assert len(lines) == 3 and "N   +1.00 E   +0.00 D   -1.00 m" in lines[-1], lines
    assert math.isclose(track.samples[-1][1][0], 1.0)
