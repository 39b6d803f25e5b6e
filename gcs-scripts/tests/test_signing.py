"""MAVLink 2 signing through `sitl run`, set up and used as docs/running.md says. With pymavlink: SETUP_SIGNING
over TCP (a link the user made), then over UDP, where anyone on the network can send, an unsigned command
is dropped, a signed one is answered, a replayed one is dropped; the key outlives a restart; a signed
SETUP_SIGNING with the zero key turns signing off. With MAVProxy: `signing setup PASSPHRASE` over TCP, a
signed `arm throttle`, and ARM_DISARMs that are unsigned, signed with another key or replayed, which leave
the vehicle disarmed and are counted in SYS_STATUS. Waits are bounded in wall time only to stop a hung
run."""

import hashlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

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


PASSPHRASE = "correct-horse-battery"


class MavProxy:
    """MAVProxy (lean install) on a connection, fed commands on standard input, its output collected."""

    def __init__(self, master, cwd):
        mavproxy = Path(sys.executable).with_name("mavproxy.py")
        assert mavproxy.exists(), "MAVProxy is installed (scripts/test: requirements-mavproxy.txt, --no-deps)"
        self.proc = subprocess.Popen(
            [sys.executable, str(mavproxy), f"--master={master}", "--source-system=250"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=cwd,
        )
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.lines: list[str] = []
        stdout = self.proc.stdout
        threading.Thread(target=lambda: self.lines.extend(iter(stdout.readline, "")), daemon=True).start()

    def output(self):
        return "".join(self.lines)

    def wait_for(self, text, wall_s, after=0):
        """Waits until `text` appears in the output past character `after`; where it ends, or None."""
        end = time.monotonic() + wall_s
        while time.monotonic() < end:
            at = self.output().find(text, after)
            if at >= 0:
                return at + len(text)
            time.sleep(0.1)
        return None

    def send(self, command):
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def stop(self):
        self.proc.kill()
        self.proc.wait()


def arm_frame(conn, sitl, arm):
    frame = conn.mav.command_long_encode(
        sitl.instance + 1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1 if arm else 0, 0, 0, 0, 0, 0, 0
    )
    return frame.pack(conn.mav)


def arm_ack(conn, sitl, frame, wall_s=3.0):
    """Sends an ARM_DISARM frame as bytes to the autopilot; the COMMAND_ACK's result, or None."""
    conn.port.sendto(frame, ("127.0.0.1", 18570 + sitl.instance))
    ack = wait_for(
        conn,
        lambda m: m.get_type() == "COMMAND_ACK" and m.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
        wall_s,
    )
    return None if ack is None else ack.result


def armed(conn):
    hb = wait_for(conn, lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1, 3.0)
    assert hb is not None, "the vehicle's HEARTBEAT verifies with the key"
    return bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def sender(sitl, key=None, link_id=0):
    """A UDP client that sends to the autopilot's port from a port of its own (the API port has one
    listener: the test's signed connection), signing with `key` if given, and reads what it is sent."""
    conn = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{18570 + sitl.instance}", source_system=253, source_component=190
    )
    conn.mav.signing.allow_unsigned_callback = lambda mav, msg_id: True
    if key is not None:
        conn.setup_signing(key, sign_outgoing=True, link_id=link_id, initial_timestamp=now_timestamp())
    return conn


def test_mavproxy_signing_setup_then_only_signed_fresh_arm_commands_arm_and_the_rest_are_counted(tmp_path):
    sitl = start_sitl(tmp_path, speed="1")
    proxy = MavProxy(f"tcp:127.0.0.1:{5760 + sitl.instance}", tmp_path)
    try:
        # GIVEN MAVProxy on the vehicle's TCP port sets the key from a passphrase, as docs/running.md says.
        assert proxy.wait_for("online system", 60) is not None, proxy.output()[-2000:]
        proxy.send(f"signing setup {PASSPHRASE}")
        assert proxy.wait_for("Signing enabled", 10) is not None, proxy.output()[-2000:]
        key = hashlib.sha256(PASSPHRASE.encode()).digest()
        # The vehicle's frames verify with that key: pymavlink with it drops anything unsigned or forged.
        signed = udp(sitl, signed=False)
        signed.setup_signing(key, sign_outgoing=True, link_id=3, initial_timestamp=now_timestamp())
        msg = wait_for(signed, lambda m: m.get_type() == "SYS_STATUS", 5.0)
        assert msg is not None and msg._signed, "the vehicle signs what it sends"
        assert msg.errors_count1 == 0
        # WHEN ARM_DISARMs arrive over UDP unsigned, signed with another key, and (below) replayed.
        unsigned = sender(sitl)
        forger = sender(sitl, hashlib.sha256(b"not the passphrase").digest(), link_id=4)
        assert arm_ack(unsigned, sitl, arm_frame(unsigned, sitl, True)) is None, "an unsigned ARM is dropped"
        assert arm_ack(forger, sitl, arm_frame(forger, sitl, True)) is None, "an ARM with another key is dropped"
        assert not armed(signed)
        # THEN a signed ARM arms: MAVProxy's own `arm throttle` (retried until the estimate is ready).
        deadline = time.monotonic() + 60
        while not armed(signed):
            assert time.monotonic() < deadline, proxy.output()[-2000:]
            proxy.send("arm throttle")
            time.sleep(1.0)
        proxy.send("disarm")
        deadline = time.monotonic() + 10
        while armed(signed):
            assert time.monotonic() < deadline, proxy.output()[-2000:]
        # A signed pymavlink ARM is accepted once; the same frame again is a replay and dropped.
        frame = arm_frame(signed, sitl, True)
        assert arm_ack(signed, sitl, frame) == mavlink.MAV_RESULT_ACCEPTED
        assert arm_ack(signed, sitl, arm_frame(signed, sitl, False)) == mavlink.MAV_RESULT_ACCEPTED
        assert not armed(signed)
        assert arm_ack(signed, sitl, frame) is None, "a replayed ARM is dropped"
        assert not armed(signed)
        # The three dropped frames are counted in SYS_STATUS errors_count1.
        status = wait_for(signed, lambda m: m.get_type() == "SYS_STATUS", 3.0)
        assert status is not None and status.errors_count1 == 3, status
        for conn in (signed, unsigned, forger):
            conn.close()
    finally:
        proxy.stop()
        sitl.stop()
        print(proxy.output()[-2000:])
        print(sitl.log_tail())
