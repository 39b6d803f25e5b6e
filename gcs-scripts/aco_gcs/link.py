"""The plumbing every pymavlink script shares: the SITL instance's ports, a link to the vehicle that keeps
its clock (the largest `time_boot_ms` seen) and its state from telemetry, waits measured on that clock,
COMMAND_LONG with its ACK, the parameter protocol, the plant's SIM_ parameter link and its truth stream
(`PlantTruth`), and the exit codes.

Time: every wait in a flight is measured on the vehicle's clock, so a script behaves the same whether
the SITL runs at real time (`sitl run`'s default) or at `--speed 30`. Protocol timeouts (an ACK, a
PARAM_VALUE) are a few seconds of vehicle time rather than PX4 clients' fraction of a second: sped up, a
Python client reads the telemetry a little behind the vehicle, and its clock is the telemetry it has
read. Wall time is only a hang guard (`--wall-limit`), the first HEARTBEAT's timeout
(`--heartbeat-timeout`: there is no vehicle clock before it) and the plant's SIM_ parameter link (the
plant sends no clock on that port).

Addressing (as `sitl run` sets it up for instance N, PX4's multi-vehicle convention): every autopilot
sends to UDP 127.0.0.1:14550 (QGroundControl's, shared; system id N+1 tells them apart) and to its own
API port (`api_port(N)`: 14540+N, 14541+N from N = 10 so as to skip 14550), and listens on 18570+N. A
script listens on the API port (`udpin:`), takes only system N+1's messages (`--sysid` for another) and
sends to 18570+N explicitly. The plant answers its SIM_ parameters on 127.0.0.1:19550+N as system N+1,
component 51, and streams its true state there (SIM_STATE at 50 Hz of plant time) to every client that
spoke in the last 10 s.

Exit codes: 0 success, 1 a failed flight check (or the hang guard), 2 no vehicle (no HEARTBEAT in time).
"""

import argparse
import contextlib
import math
import os
import struct
import sys
import time

os.environ.setdefault("MAVLINK20", "1")  # pymavlink speaks MAVLink 1 unless told otherwise
from pymavlink import mavutil

mavlink = mavutil.mavlink

QGC_PORT = 14550
API_PORT = 14540
MAX_INSTANCE = 254  # system id N+1 is a byte
AUTOPILOT_PORT = 18570
PLANT_PARAM_PORT = 19550
PLANT_COMPONENT = 51
EARTH_RADIUS_M = 6_378_137.0  # flat-Earth maps about a point a few metres across
AUTOPILOT_COMPONENT = 1
GCS_SYSTEM = 255
GCS_COMPONENT = 190  # MAV_COMP_ID_MISSIONPLANNER, as QGroundControl and MAVProxy

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_NO_VEHICLE = 2

PREARM_CHECK = 0x10000000  # MAV_SYS_STATUS_PREARM_CHECK: the vehicle is armable (estimator converged)
LANDED_ON_GROUND = 1  # MAV_LANDED_STATE_ON_GROUND
# PX4 custom modes: main mode in bits 16-23, sub mode in bits 24-31.
PX4_MAIN_AUTO = 4
PX4_MAIN_OFFBOARD = 6
PX4_AUTO_LOITER = 3
PX4_AUTO_MISSION = 4
# Wall seconds without a single message from the vehicle before a script gives up on it.
SILENCE_LIMIT_S = 15.0


class GcsError(Exception):
    """A script failure with its exit code."""

    exit_code = EXIT_CHECK_FAILED


class CheckFailed(GcsError):
    """A flight check failed (or the vehicle refused something): exit 1."""

    exit_code = EXIT_CHECK_FAILED


class NoVehicle(GcsError):
    """No HEARTBEAT arrived in time: exit 2."""

    exit_code = EXIT_NO_VEHICLE


def float32(value):
    """`value` as the f32 it becomes on the wire."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


def same_float32(a, b):
    """Whether two values are the same REAL32 (NaN equals NaN)."""
    a, b = float32(a), float32(b)
    return a == b or (math.isnan(a) and math.isnan(b))


# The integer parameter types, each as the `struct` format of its bytes at the start of the field.
_PARAM_INT_FORMATS = {
    mavlink.MAV_PARAM_TYPE_UINT8: "<B",
    mavlink.MAV_PARAM_TYPE_INT8: "<b",
    mavlink.MAV_PARAM_TYPE_UINT16: "<H",
    mavlink.MAV_PARAM_TYPE_INT16: "<h",
    mavlink.MAV_PARAM_TYPE_UINT32: "<I",
    mavlink.MAV_PARAM_TYPE_INT32: "<i",
}


def decode_param(field, param_type):
    """The value in the float field `param_value` of a PARAM_VALUE of `param_type`, decoded as PX4 encodes
    it (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE): REAL32 is the float itself; an integer type's bytes
    stand in the field as they are (the INT32 2 arrives as the float 2.8e-45) and come back as an int.
    Exact for every value of the vehicle's and the plant's tables (Python's float conversion would only
    change the bit patterns of signalling NaNs, integers beyond +-2^22)."""
    fmt = _PARAM_INT_FORMATS.get(param_type)
    if fmt is None:
        return field
    return struct.unpack_from(fmt, struct.pack("<f", field))[0]


def encode_param(value, param_type):
    """The float field `param_value` of a PARAM_SET of `value` as `param_type`, the inverse of
    `decode_param`: an integer's bytes placed as they are (the rest 0), a REAL32 the float itself."""
    fmt = _PARAM_INT_FORMATS.get(param_type)
    if fmt is None:
        return float(value)
    return struct.unpack("<f", struct.pack(fmt, int(value)).ljust(4, b"\0"))[0]


def int_fits(value, param_type):
    """Whether `value` is a whole number that integer type `param_type` holds."""
    value = float(value)
    if not value.is_integer():
        return False
    try:
        struct.pack(_PARAM_INT_FORMATS[param_type], int(value))
    except struct.error:
        return False
    return True


def result_name(result):
    """MAV_RESULT as its name."""
    entry = mavlink.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else str(result)


def api_port(instance):
    """Instance N's API / offboard port: 14540+N, skipping QGroundControl's 14550 (14541+N from N = 10)."""
    if not 0 <= instance <= MAX_INSTANCE:
        raise GcsError(f"instance {instance} is out of range: instances are 0..={MAX_INSTANCE}")
    return API_PORT + instance + (1 if API_PORT + instance >= QGC_PORT else 0)


def add_link_args(parser, mavsdk=False):
    """The connection options every script has."""
    parser.add_argument(
        "-i",
        "--instance",
        type=int,
        default=0,
        metavar="N",
        help="SITL instance N (`sitl run -i N`): its API port 14540+N and autopilot port 18570+N, vehicle "
        "system id N+1 (default 0)",
    )
    parser.add_argument(
        "--sysid",
        type=int,
        metavar="S",
        help="the vehicle's system id, for a link several vehicles send on such as udpin:0.0.0.0:14550 (default N+1)",
    )
    if mavsdk:
        parser.add_argument(
            "--connect",
            metavar="URL",
            help="MAVSDK connection (default udpin://0.0.0.0:14540+N, the instance's API port)",
        )
    else:
        parser.add_argument(
            "--connect",
            metavar="DEVICE",
            help="pymavlink connection (default udpin:127.0.0.1:14540+N, the instance's API port)",
        )
        parser.add_argument(
            "--target",
            metavar="HOST:PORT",
            help="where messages to the vehicle go (default 127.0.0.1:18570+N, the autopilot's UDP port, "
            "when --connect is the default; otherwise pymavlink's own addressing)",
        )
    parser.add_argument(
        "--heartbeat-timeout",
        type=float,
        default=20.0,
        metavar="S",
        help="wall seconds to wait for the vehicle's first HEARTBEAT before exiting with code 2 (default 20)",
    )
    parser.add_argument(
        "--wall-limit",
        type=float,
        default=600.0,
        metavar="S",
        help="hang guard: give up after this many wall seconds (default 600); every wait in the flight "
        "itself is measured on the vehicle's clock",
    )


def resolve_link(args):
    """(connect, target) from the parsed options: the defaults of instance N unless given."""
    n = args.instance
    if args.connect is None:
        connect = f"udpin:127.0.0.1:{api_port(n)}"
        target = args.target or f"127.0.0.1:{AUTOPILOT_PORT + n}"
    else:
        connect, target = args.connect, args.target
    return connect, target


def run_main(run, args, prog="aco-gcs"):
    """Call `run(args)` and turn its outcome into an exit code, with the error on stderr as `prog: error: ...`."""
    try:
        code = run(args)
        return EXIT_OK if code is None else code
    except GcsError as e:
        print(f"{prog}: error: {e}", file=sys.stderr, flush=True)
        return e.exit_code
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


def _address(text):
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise GcsError(f"--target must be HOST:PORT, got {text!r}")
    return host, int(port)


class Link:
    """A pymavlink connection to one MAVLink component: state from what it sends, and waits. Subclasses say
    which clock the waits use (`now_s`)."""

    component = AUTOPILOT_COMPONENT
    # Wall seconds of silence after which the component is taken as gone (None: never).
    silence_limit_s: float | None = SILENCE_LIMIT_S

    def __init__(self, connect, target=None, wall_limit_s=600.0):
        self.connect = connect
        try:
            self.conn = mavutil.mavlink_connection(connect, source_system=GCS_SYSTEM, source_component=GCS_COMPONENT)
        except OSError as e:
            raise GcsError(f"cannot open {connect}: {e}") from e
        if target is not None:
            # pymavlink's udpin answers whoever sent last; address the component explicitly instead.
            address = _address(target)
            port = self.conn.port
            self.conn.write = lambda buf: _sendto(port, buf, address)
        self.target = target
        self.deadline = time.monotonic() + wall_limit_s
        self.wall_limit_s = wall_limit_s
        self.system_id = None
        self.last_heard = time.monotonic()
        self.statustexts = []  # (time, severity, text)
        self.listeners = []

    def lost(self):
        """Messages lost so far (gaps in the senders' MAVLink sequence numbers, as pymavlink counts them)."""
        return getattr(self.conn, "mav_loss", 0)

    # -- the clock ------------------------------------------------------------------------------------
    def now_s(self):
        raise NotImplementedError

    # -- receiving ------------------------------------------------------------------------------------
    def ours(self, msg):
        return self.system_id is not None and msg.get_srcSystem() == self.system_id

    def pump(self):
        """Receive at most one message (waiting up to 0.5 s of wall time) and update the state from it;
        returns it, or None."""
        now = time.monotonic()
        if now > self.deadline:
            raise CheckFailed(f"wall-clock limit of {self.wall_limit_s:.0f} s reached: the SITL hung or is too slow")
        limit = self.silence_limit_s
        if self.system_id is not None and limit is not None and now - self.last_heard > limit:
            raise CheckFailed(f"nothing from the {self.name()} for {limit:.0f} s of wall time")
        self.before_pump()
        msg = self.conn.recv_match(blocking=True, timeout=0.5)
        if msg is None or msg.get_type() == "BAD_DATA" or not self.ours(msg):
            return None
        self.last_heard = time.monotonic()
        self.handle(msg)
        for listener in self.listeners:
            listener(msg)
        return msg

    def before_pump(self):
        """Hook: called before each receive (to send heartbeats)."""

    def handle(self, msg):
        if msg.get_type() == "STATUSTEXT":
            self.statustexts.append((self.now_s(), msg.severity, msg.text))
            print(f"  [{self.name()}] {msg.text}", file=sys.stderr, flush=True)

    def name(self):
        return f"system {self.system_id}"

    def wait_until(self, seconds, what, cond):
        """Pump until `cond()` holds; fail if that takes more than `seconds` on this link's clock. Returns
        the seconds it took."""
        start = self.now_s()
        while not cond():
            if self.now_s() - start > seconds:
                raise CheckFailed(f"{what}: not within {seconds:g} s of {self.clock_name()}")
            self.pump()
        return self.now_s() - start

    def next_message(self, seconds, match):
        """The first message (of ours) for which `match(msg)` holds within `seconds`, or None."""
        start = self.now_s()
        while self.now_s() - start <= seconds:
            msg = self.pump()
            if msg is not None and match(msg):
                return msg
        return None

    def clock_name(self):
        return "vehicle time"

    def send(self, msg):
        self.conn.mav.send(msg)

    def texts_since(self, t):
        return [text for (at, _, text) in self.statustexts if at >= t]

    def close(self):
        self.conn.close()


def _sendto(sock, buf, address):
    # Nobody listening yet is not an error: the waits time out and say so.
    with contextlib.suppress(OSError):
        sock.sendto(buf, address)


class VehicleState:
    """What a ground station knows of one autopilot from its telemetry; its clock is the largest
    `time_boot_ms` seen. `update` takes each of the autopilot's messages."""

    def __init__(self):
        self.now_ms = 0
        self.heartbeat = None
        self.armed = False
        self.custom_mode = 0
        self.prearm_ok = False
        self.pos = None  # LOCAL_POSITION_NED (x, y, z) m
        self.vel = None
        self.global_pos = None  # GLOBAL_POSITION_INT message
        self.home = None  # HOME_POSITION message
        self.landed_state = None
        self.acks = {}

    def now_s(self):
        return self.now_ms / 1000.0

    def landed(self):
        """On the ground (EXTENDED_SYS_STATE) and disarmed."""
        return self.landed_state == LANDED_ON_GROUND and not self.armed

    def update(self, msg):
        kind = msg.get_type()
        t = getattr(msg, "time_boot_ms", None)
        if t is not None:
            self.now_ms = max(self.now_ms, t)
        if kind == "HEARTBEAT":
            self.heartbeat = msg
            self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            self.custom_mode = msg.custom_mode
        elif kind == "SYS_STATUS":
            self.prearm_ok = bool(msg.onboard_control_sensors_health & PREARM_CHECK)
        elif kind == "LOCAL_POSITION_NED":
            self.pos = (msg.x, msg.y, msg.z)
            self.vel = (msg.vx, msg.vy, msg.vz)
        elif kind == "GLOBAL_POSITION_INT":
            self.global_pos = msg
        elif kind == "HOME_POSITION":
            self.home = msg
        elif kind == "EXTENDED_SYS_STATE":
            self.landed_state = msg.landed_state
        elif kind == "COMMAND_ACK":
            self.acks[msg.command] = msg.result


class Vehicle(VehicleState, Link):
    """The autopilot (component 1) over a link of its own: its state ([`VehicleState`]) and clock from
    its telemetry, and commands to it."""

    def __init__(self, connect, target=None, wall_limit_s=600.0):
        Link.__init__(self, connect, target, wall_limit_s)
        VehicleState.__init__(self)
        self._last_gcs_heartbeat = (-1e9, 0.0)

    @classmethod
    def from_args(cls, args):
        connect, target = resolve_link(args)
        vehicle = cls(connect, target, args.wall_limit)
        sysid = args.sysid if getattr(args, "sysid", None) is not None else args.instance + 1
        vehicle.wait_heartbeat(args.heartbeat_timeout, args.instance, sysid)
        return vehicle

    def name(self):
        return "vehicle"

    def wait_heartbeat(self, timeout_s, instance=None, sysid=None):
        """Wait (wall time: there is no vehicle clock yet) for an autopilot's HEARTBEAT (from system `sysid`
        when given: several vehicles may send on one port); lock onto its system id."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            self.before_pump()
            msg = self.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if msg is None or msg.get_srcComponent() != AUTOPILOT_COMPONENT:
                continue
            if msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID or msg.type == mavlink.MAV_TYPE_GCS:
                continue
            if sysid is not None and msg.get_srcSystem() != sysid:
                continue
            self.system_id = msg.get_srcSystem()
            self.conn.target_system, self.conn.target_component = self.system_id, AUTOPILOT_COMPONENT
            self.last_heard = time.monotonic()
            self.handle(msg)
            # The waits run on the vehicle's clock, which HEARTBEAT does not carry: read it from the
            # telemetry first, or a vehicle that has been up for a while would look as if every wait
            # had timed out at once.
            while self.now_ms == 0 and time.monotonic() < end:
                self.pump()
            if self.now_ms == 0:
                raise NoVehicle(f"vehicle HEARTBEAT on {self.connect} but no timed telemetry within {timeout_s:g} s")
            return msg
        hint = f" (is `sitl run -i {instance}` running?)" if instance is not None else ""
        raise NoVehicle(f"no vehicle HEARTBEAT on {self.connect} within {timeout_s:g} s{hint}")

    def before_pump(self):
        # A GCS heartbeat once per second of vehicle time (and of wall time), as ground stations send.
        last_vehicle_s, last_wall = self._last_gcs_heartbeat
        now_wall = time.monotonic()
        if self.now_s() - last_vehicle_s >= 1.0 or now_wall - last_wall >= 1.0:
            self._last_gcs_heartbeat = (self.now_s(), now_wall)
            self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def ours(self, msg):
        return super().ours(msg) and msg.get_srcComponent() == AUTOPILOT_COMPONENT

    def handle(self, msg):
        Link.handle(self, msg)
        self.update(msg)

    def px4_mode(self):
        """(main, sub) of the PX4 custom mode in the last HEARTBEAT."""
        return (self.custom_mode >> 16) & 0xFF, (self.custom_mode >> 24) & 0xFF

    # -- commands -------------------------------------------------------------------------------------
    def command(self, command, *params, ack_s=5.0, attempts=3):
        """Send COMMAND_LONG (resending with a higher confirmation when no ACK comes within `ack_s` of
        vehicle time) and return the ACK's result."""
        values = [*params, *[0.0] * (7 - len(params))]
        for confirmation in range(attempts):
            self.acks.pop(command, None)
            self.conn.mav.command_long_send(self.system_id, AUTOPILOT_COMPONENT, command, confirmation, *values)
            start = self.now_s()
            while command not in self.acks and self.now_s() - start <= ack_s:
                self.pump()
            if command in self.acks:
                return self.acks[command]
        name = mavlink.enums["MAV_CMD"][command].name if command in mavlink.enums["MAV_CMD"] else command
        raise CheckFailed(f"no COMMAND_ACK for {name} after {attempts} tries of {ack_s:g} s of vehicle time")

    def require(self, what, command, *params, **kwargs):
        """`command`, failing unless the vehicle ACCEPTED it (with its STATUSTEXT in the message)."""
        since = self.now_s()
        result = self.command(command, *params, **kwargs)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            if not self.texts_since(since):
                # The reason's STATUSTEXT may follow the ACK: a second of vehicle time for it.
                self.next_message(1.0, lambda m: m.get_type() == "STATUSTEXT")
            texts = "; ".join(self.texts_since(since))
            raise CheckFailed(f"{what}: the vehicle answered {result_name(result)}" + (f" ({texts})" if texts else ""))

    def set_px4_mode(self, main, sub=0, what=None):
        """DO_SET_MODE to a PX4 custom mode, and wait for the HEARTBEAT to show it."""
        what = what or f"mode {main}.{sub}"
        self.require(what, mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub)
        self.wait_until(3.0, f"{what} in the HEARTBEAT", lambda: self.px4_mode() == (main, sub))

    def home_amsl_m(self):
        """Home altitude (m AMSL): HOME_POSITION's; before there is one, a vehicle still on the ground
        (disarmed) is at its home-to-be, so GLOBAL_POSITION_INT's altitude; otherwise alt - relative_alt."""
        if self.home is not None:
            return self.home.altitude / 1000.0
        if self.global_pos is not None:
            if not self.armed:
                return self.global_pos.alt / 1000.0
            return (self.global_pos.alt - self.global_pos.relative_alt) / 1000.0
        return None


class Params:
    """The MAVLink parameter protocol against one component of a link (vehicle or plant); waits on the
    link's clock. Values are decoded by their `param_type` as PX4 encodes them (`decode_param`: a real is
    REAL32, an integer INT32 with its bytes as they are) and set in the type the component declared."""

    def __init__(self, link, component):
        self.link = link
        self.component = component
        self.values = {}  # name -> value (an int for an integer type)
        self.types = {}  # name -> MAV_PARAM_TYPE of its PARAM_VALUEs
        self.by_index = {}  # index -> name
        self.count = None
        link.listeners.append(self._on_message)

    def _on_message(self, msg):
        if msg.get_type() == "PARAM_VALUE" and msg.get_srcComponent() == self.component:
            self.values[msg.param_id] = decode_param(msg.param_value, msg.param_type)
            self.types[msg.param_id] = msg.param_type
            if msg.param_index != 65535:
                self.by_index[msg.param_index] = msg.param_id
            self.count = msg.param_count

    def fetch_all(self, seconds=60.0, quiet_s=3.0):
        """Every parameter: PARAM_REQUEST_LIST, then PARAM_REQUEST_READ by index for any missing after
        `quiet_s` without news. Returns {name: value} in index order."""
        link = self.link
        link.conn.mav.param_request_list_send(link.system_id, self.component)
        start = last_news = link.now_s()
        seen = -1
        while self.count is None or len(self.by_index) < self.count:
            if link.now_s() - start > seconds:
                have = len(self.by_index)
                raise CheckFailed(
                    f"parameter list: {have} of {self.count or '?'} in {seconds:g} s of {link.clock_name()}"
                )
            link.pump()
            if len(self.by_index) != seen:
                seen, last_news = len(self.by_index), link.now_s()
            elif link.now_s() - last_news > quiet_s:
                last_news = link.now_s()
                if self.count is None:
                    link.conn.mav.param_request_list_send(link.system_id, self.component)
                else:
                    for index in sorted(set(range(self.count)) - set(self.by_index)):
                        link.conn.mav.param_request_read_send(link.system_id, self.component, b"", index)
        return {self.by_index[i]: self.values[self.by_index[i]] for i in sorted(self.by_index)}

    def get(self, name, seconds=5.0, attempts=3):
        """One parameter by name, or None if it is not answered (`read` also says why)."""
        return self.read(name, seconds, attempts)[0]

    def read(self, name, seconds=5.0, attempts=3):
        """(value, reason): the value of `name`, or None and the reason the component gave (the vehicle
        answers a name it does not have with `unknown parameter NAME`), or None and None on silence."""
        link = self.link
        reason = f"unknown parameter {name}"
        for _ in range(attempts):
            self.values.pop(name, None)
            since = link.now_s()
            link.conn.mav.param_request_read_send(link.system_id, self.component, name.encode(), -1)
            got = link.next_message(
                seconds,
                lambda m: (
                    (m.get_type() == "PARAM_VALUE" and m.param_id == name)
                    or (m.get_type() == "STATUSTEXT" and m.text == reason)
                ),
            )
            if got is not None and got.get_type() == "PARAM_VALUE":
                return decode_param(got.param_value, got.param_type), None
            if got is not None or reason in link.texts_since(since):
                return None, reason
        return None, None

    def set(self, name, value, seconds=5.0, attempts=3):
        """PARAM_SET and wait for the echo. Returns (echoed value or None, texts the component sent
        meanwhile): the set was taken when the echo equals `value` as a REAL32. The set is in the type the
        component declared for `name` (read first if no PARAM_VALUE of it was seen): an integer as INT32
        bytewise when `value` is whole; otherwise REAL32, so that the component says why it refuses a
        fraction for an integer, and a name it does not know is refused by name."""
        link = self.link
        if name not in self.types:
            self.get(name, attempts=1)
        param_type = self.types.get(name, mavlink.MAV_PARAM_TYPE_REAL32)
        if param_type in _PARAM_INT_FORMATS and not int_fits(value, param_type):
            param_type = mavlink.MAV_PARAM_TYPE_REAL32
        field = encode_param(value, param_type)
        since = link.now_s()
        for _ in range(attempts):
            link.conn.mav.param_set_send(link.system_id, self.component, name.encode(), field, param_type)
            got = link.next_message(seconds, lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name)
            # A PARAM_VALUE with another value and no word of refusal may be a late answer to the read
            # above (a backlog on a fast vehicle): the echo is still to come.
            while (
                got is not None
                and not link.texts_since(since)
                and not same_float32(decode_param(got.param_value, got.param_type), value)
            ):
                late = link.next_message(seconds, lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name)
                if late is None:
                    break
                got = late
            if got is not None:
                return decode_param(got.param_value, got.param_type), link.texts_since(since)
            if link.texts_since(since):
                break  # refused without an echo (an unknown name): no point in resending
        return None, link.texts_since(since)

    def require_set(self, name, value, **kwargs):
        echoed, texts = self.set(name, value, **kwargs)
        if echoed is None or not same_float32(echoed, value):
            why = "; ".join(texts) or ("no PARAM_VALUE echo" if echoed is None else f"echoed {echoed:g}")
            raise CheckFailed(f"{name} = {value:g} refused: {why}")
        return echoed


class Plant(Link):
    """The plant's SIM_ parameter service (UDP 127.0.0.1:19550+N, component 51). It sends no clock, so its
    waits are on the wall clock."""

    component = PLANT_COMPONENT
    silence_limit_s = None  # it only speaks when spoken to (and heartbeats while it is)

    def __init__(self, instance, wall_limit_s=600.0, host="127.0.0.1"):
        self.port = PLANT_PARAM_PORT + instance
        super().__init__(f"udpout:{host}:{self.port}", None, wall_limit_s)
        self.instance = instance

    def now_s(self):
        return time.monotonic()

    def clock_name(self):
        return "wall time"

    def name(self):
        return "plant"

    def ours(self, msg):
        return super().ours(msg) and msg.get_srcComponent() == PLANT_COMPONENT

    def hello(self, timeout_s=5.0):
        """Say HEARTBEAT (the plant only heartbeats to clients that spoke) and wait for its HEARTBEAT."""
        end = time.monotonic() + timeout_s
        next_hello = 0.0
        while time.monotonic() < end:
            if time.monotonic() >= next_hello:
                next_hello = time.monotonic() + 0.5
                self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            msg = self.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
            if msg is not None and msg.get_srcComponent() == PLANT_COMPONENT:
                self.system_id = msg.get_srcSystem()
                self.last_heard = time.monotonic()
                return msg
        raise NoVehicle(
            f"no plant HEARTBEAT on udp 127.0.0.1:{self.port} within {timeout_s:g} s "
            f"(is `sitl run -i {self.instance}` running, with SIM_ parameters?)"
        )


def ned_from_geodetic(origin, lat_deg, lon_deg, alt_amsl_m):
    """(north, east, down) m of a point about `origin` = (lat_deg, lon_deg, alt_amsl_m): flat Earth on a
    sphere, whose scale differs from WGS-84's by under 0.7 %, a millimetre over the 0.1 m a hover strays."""
    lat0, lon0, alt0 = origin
    north = math.radians(lat_deg - lat0) * EARTH_RADIUS_M
    east = math.radians(lon_deg - lon0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
    return north, east, alt0 - alt_amsl_m


class PlantTruth:
    """The plant's true state from its SIM_ port (`sitl run -i N`: UDP 127.0.0.1:19550+N, system N+1,
    component 51), to judge a flight by what happened rather than by what the vehicle estimates. The plant
    streams to every client that spoke in the last 10 s: one datagram per sample at 50 Hz of plant time,
    SYSTEM_TIME (`time_boot_ms`: the plant time, which is the vehicle's clock) then SIM_STATE (the truth;
    `lat_int`/`lon_int` degE7, `alt` m AMSL). This client says HEARTBEAT (every 20 ms of wall time until the
    truth flows, then every second) and keeps each sample as (t_s, (north, east, down) m about the first
    sample's point). It only reads when `drain` is called: call it often (as a listener of the vehicle's
    link), or the kernel drops what does not fit its buffer."""

    def __init__(self, connect, system_id):
        self.connect = connect
        self.system_id = system_id
        try:
            self.conn = mavutil.mavlink_connection(connect, source_system=GCS_SYSTEM, source_component=GCS_COMPONENT)
        except OSError as e:
            raise GcsError(f"cannot open {connect}: {e}") from e
        self.origin = None
        self.samples = []  # (t_s, (n, e, d))
        self._time_ms = None
        self._last_hello = -1e9

    def drain(self):
        """Say HEARTBEAT if due, then read every message waiting."""
        now = time.monotonic()
        if now - self._last_hello >= (1.0 if self.samples else 0.02):
            self._last_hello = now
            with contextlib.suppress(OSError):
                self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        while True:
            try:
                msg = self.conn.recv_match(blocking=False)
            except OSError:
                return  # the port is not there (yet): the waits time out and say so
            if msg is None:
                return
            if msg.get_srcSystem() != self.system_id or msg.get_srcComponent() != PLANT_COMPONENT:
                continue
            kind = msg.get_type()
            if kind == "SYSTEM_TIME":
                self._time_ms = msg.time_boot_ms
            elif kind == "SIM_STATE" and self._time_ms is not None:
                lat = msg.lat_int * 1e-7 if msg.lat_int else msg.lat
                lon = msg.lon_int * 1e-7 if msg.lon_int else msg.lon
                if self.origin is None:
                    self.origin = (lat, lon, msg.alt)
                self.samples.append((self._time_ms / 1000.0, ned_from_geodetic(self.origin, lat, lon, msg.alt)))
                self._time_ms = None

    def at(self, t_s):
        """The last sample's position at or before vehicle time `t_s`, once a later sample has come (the truth
        trails the telemetry by up to a poll of the plant); None until then."""
        if not self.samples or self.samples[-1][0] <= t_s:
            return None
        before = [pos for (t, pos) in self.samples if t <= t_s]
        if not before:
            first_s = self.samples[0][0]
            raise CheckFailed(f"no truth sample at or before t = {t_s:.2f} s (the first is at {first_s:.2f} s)")
        return before[-1]

    def wait_at(self, vehicle, t_s, seconds=10.0):
        """`at(t_s)`, pumping `vehicle` (its listeners drain this) for up to `seconds` of vehicle time."""
        vehicle.wait_until(
            seconds,
            f"the plant's truth past t = {t_s:.2f} s on {self.connect}",
            lambda: self.samples and self.samples[-1][0] > t_s,
        )
        return self.at(t_s)

    def wait_flowing(self, vehicle, seconds=10.0):
        """Pump `vehicle` (its listeners drain this) until the first sample, for up to `seconds` of vehicle
        time; returns the vehicle time of the first sample."""
        vehicle.wait_until(seconds, f"the plant's truth (SIM_STATE) on {self.connect}", lambda: bool(self.samples))
        return self.samples[0][0]

    def window(self, t0_s, t1_s):
        """The positions sampled in [t0_s, t1_s] of vehicle time."""
        return [pos for (t, pos) in self.samples if t0_s <= t <= t1_s]

    def close(self):
        self.conn.close()


def positive_float(text):
    value = float(text)
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value
