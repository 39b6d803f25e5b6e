"""MAVLink 2 signing through `sitl run`, set up and used as pymavlink does: SETUP_SIGNING over TCP (a link
the user made), then over UDP, where anyone on the network can send, an unsigned command is dropped, a
signed one is answered, a replayed one is dropped; the key outlives a restart; a signed SETUP_SIGNING with
the zero key turns signing off. Waits are bounded in wall time only to stop a hung run."""

import os
import time

from sitl_harness import start_sitl

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

from aco_gcs import link

mavlink = mavutil.mavlink
KEY = bytes(range(1, 33))
AUTOPILOT_VERSION = 148


def now_timestamp():
    """MAVLink's signing time: 10 µs units since 2015-01-01."""
    return int((time.time() - 1420070400) * 1e5)


def wait_for(conn, predicate, wall_s):
    end = time.monotonic() + wall_s
    while time.monotonic() < end:
        msg = conn.recv_match(blocking=True, timeout=0.2)
        if msg is not None and predicate(msg):
            return msg
    return None


def tcp(sitl):
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{5760 + sitl.instance}", source_system=255, source_component=190)
    assert conn.wait_heartbeat(timeout=30) is not None
    return conn


def udp(sitl, signed):
    conn = mavutil.mavlink_connection(
        f"udpin:127.0.0.1:{link.api_port(sitl.instance)}", source_system=254, source_component=190
    )
    assert conn.wait_heartbeat(timeout=30) is not None
    if signed:
        conn.mav.signing.secret_key = KEY
        conn.mav.signing.link_id = 2
        conn.mav.signing.sign_outgoing = True
        conn.mav.signing.timestamp = now_timestamp()
    return conn


def request_version(conn, sitl):
    """REQUEST_MESSAGE(AUTOPILOT_VERSION) as bytes (signed if the connection signs), sent to the autopilot."""
    frame = conn.mav.command_long_encode(
        sitl.instance + 1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0
    )
    return frame.pack(conn.mav)


def answered(conn, sitl, frame):
    conn.port.sendto(frame, ("127.0.0.1", 18570 + sitl.instance))
    return wait_for(conn, lambda m: m.get_type() == "AUTOPILOT_VERSION", 3.0) is not None


def test_signing_set_up_over_tcp_drops_unsigned_and_replayed_udp_commands_and_survives_a_restart(tmp_path):
    sitl = start_sitl(tmp_path, speed="1")
    try:
        unsigned = udp(sitl, signed=False)
        assert answered(unsigned, sitl, request_version(unsigned, sitl)), "signing off: anyone is answered"
        # A SETUP_SIGNING over UDP is refused: anyone on the network reaches that port.
        unsigned.mav.setup_signing_send(sitl.instance + 1, 1, KEY, now_timestamp())
        refusal = wait_for(unsigned, lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith("Signing:"), 5.0)
        assert refusal is not None and "refused on UDP" in refusal.text
        # Over TCP, as a pymavlink script does it: SETUP_SIGNING to the vehicle, then sign locally.
        gcs = tcp(sitl)
        gcs.mav.setup_signing_send(sitl.instance + 1, 1, KEY, now_timestamp())
        gcs.setup_signing(KEY, sign_outgoing=True, initial_timestamp=now_timestamp())
        assert wait_for(gcs, lambda m: m.get_type() == "STATUSTEXT" and m.text == "Signing enabled", 5.0) is not None
        # Over UDP: unsigned dropped, signed answered, the same signed frame again dropped.
        assert not answered(unsigned, sitl, request_version(unsigned, sitl)), "an unsigned command is dropped"
        signed = udp(sitl, signed=True)
        frame = request_version(signed, sitl)
        assert answered(signed, sitl, frame), "a signed command is answered"
        assert not answered(signed, sitl, frame), "a replayed frame is dropped"
        assert answered(signed, sitl, request_version(signed, sitl)), "the next signed one is answered"
        for conn in (unsigned, signed, gcs):
            conn.close()
        # The key is kept (owner-only) and in force after a restart on the same state directory.
        key_file = tmp_path / "state" / "signing.key"
        assert key_file.stat().st_mode & 0o777 == 0o600
        assert KEY.hex() not in sitl.log_path.read_text(), "the key is never logged"
        sitl.stop()
        sitl = start_sitl(tmp_path, speed="1", instance=sitl.instance)
        unsigned = udp(sitl, signed=False)
        assert not answered(unsigned, sitl, request_version(unsigned, sitl)), "still on after the restart"
        # Off again: a signed SETUP_SIGNING with the zero key, over TCP.
        gcs = tcp(sitl)
        gcs.setup_signing(KEY, sign_outgoing=True, initial_timestamp=now_timestamp())
        gcs.mav.setup_signing_send(sitl.instance + 1, 1, bytes(32), 0)
        # The answer comes unsigned (signing is off once it is sent): accept it.
        gcs.mav.signing.allow_unsigned_callback = lambda mav, msg_id: True
        assert wait_for(gcs, lambda m: m.get_type() == "STATUSTEXT" and m.text == "Signing disabled", 5.0) is not None
        assert answered(unsigned, sitl, request_version(unsigned, sitl)), "signing off: unsigned answered again"
        assert not key_file.exists()
    finally:
        sitl.stop()
        print(sitl.log_tail())


def test_a_udp_link_the_configuration_marks_secure_takes_setup_signing(tmp_path):
    # GIVEN an autopilot whose configuration marks its UDP link secure (a network the user trusts).
    config = tmp_path / "autopilot.toml"
    config.write_text("[gcs]\nudp_secure = true\n")
    sitl = start_sitl(tmp_path, "--autopilot-config", str(config), speed="4")
    try:
        conn = udp(sitl, signed=False)
        # WHEN a SETUP_SIGNING arrives over UDP THEN it is taken, and unsigned commands are dropped after it.
        conn.mav.setup_signing_send(sitl.instance + 1, 1, KEY, now_timestamp())
        said = wait_for(conn, lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith("Signing"), 5.0)
        assert said is not None and said.text == "Signing enabled", said
        assert not answered(conn, sitl, request_version(conn, sitl)), "an unsigned command is dropped"
        conn.close()
        signed = udp(sitl, signed=True)
        assert answered(signed, sitl, request_version(signed, sitl)), "a signed one is answered"
    finally:
        sitl.stop()
