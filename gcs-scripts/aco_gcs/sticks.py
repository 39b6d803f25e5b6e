"""Fly Position mode by hand (pymavlink): the sticks go to the vehicle as MANUAL_CONTROL, as a ground
station's joystick sends them (x pitch, y roll, r yaw in -1000..1000, z throttle 0..1000 with 500 the
hold point), streamed continuously at --rate per second of vehicle time (and of wall time, whichever comes
first): the vehicle falls back to its manual-control-loss failsafe (NAV_RCL_ACT) once they are older than
COM_RC_LOSS_T (0.5 s). The script waits for the estimator, starts the stream with the sticks centred,
switches to Position mode (DO_SET_MODE, PX4 custom main mode 3), arms (ARM_DISARM, or the stick gesture
with --arm gesture), flies, prints what the vehicle says (STATUSTEXT) and the track (LOCAL_POSITION_NED),
and exits 1 when the vehicle refuses a step or leaves Position mode.

Sources of the sticks, one of:

  --script FILE   a stick sequence (TOML), each step held for its duration of vehicle time:
                      [[step]]
                      for_s = 3.0         # seconds of vehicle time (required, > 0)
                      pitch = 1.0         # -1..1, + forward (default 0)
                      roll = 0.0          # -1..1, + right (default 0)
                      yaw = 0.0           # -1..1, + clockwise (default 0)
                      throttle = 0.75     # 0..1, 0.5 holds the altitude (default 0.5)
                  Unknown keys and values out of range are errors (nothing is flown). After the last step
                  the vehicle lands with the throttle low and disarms (--then land, the default), or is
                  switched to Hold (--then hold; the vehicle's manual-control-loss failsafe, NAV_RCL_ACT,
                  then acts once the stream stops unless COM_RCL_EXCEPT exempts Hold, bit 2). --check
                  only reads the file.
  --keyboard      the terminal as sticks (each key press moves a stick one notch; they stay put):
                      up/down or w/s   pitch forward/back      left/right or a/d   roll left/right
                      q/e              yaw left/right          r/f                  throttle up/down
                      space            centre every stick (throttle 0.5: hold)
                      t                arm (--arm: ARM_DISARM or the gesture)
                      l                land: throttle low, the rest centred
                      x                quit (armed: disarm on the ground, land with the throttle low
                                       first in the air; Ctrl-C quits at once and leaves the vehicle to
                                       its manual-control-loss failsafe)
  --gamepad [DEV] a Linux joystick device (default /dev/input/js0), read as raw js_event records with no
                  extra dependency: --axes says which axis is which (default 3,4,1,0: roll = right stick
                  X, pitch = right stick Y, throttle = left stick Y, yaw = left stick X, the Mode 2 layout
                  of an Xbox-style pad under Linux); button 0 arms, button 1 quits as x does. QGroundControl's own
                  joystick support (Vehicle Setup > Joystick) is the full-featured way to fly a gamepad.
"""

import argparse
import contextlib
import math
import os
import select
import struct
import sys
import time
import tomllib
from dataclasses import dataclass, replace

from . import flight
from .link import (
    AUTOPILOT_COMPONENT,
    CheckFailed,
    GcsError,
    Params,
    Vehicle,
    add_link_args,
    mavlink,
    positive_float,
    run_main,
)

PX4_MAIN_POSCTL = 3
PX4_MAIN_AUTO = 4
PX4_AUTO_LOITER = 3
RCL_EXCEPT_HOLD = 2  # COM_RCL_EXCEPT bit: no manual-control-loss failsafe in Hold
DEFAULT_RATE_HZ = 25.0  # MAVSDK asks for 10 Hz at least; QGroundControl's joystick sends at 25-50 Hz
MAX_STEP_S = 3600.0
STICK_RANGES = {"pitch": (-1.0, 1.0), "roll": (-1.0, 1.0), "yaw": (-1.0, 1.0), "throttle": (0.0, 1.0)}
STEP_KEYS = ("for_s", *STICK_RANGES)
# The arming gesture (MAN_ARM_GESTURE): throttle low and yaw right held for COM_RC_ARM_HYST (1 s default).
DEFAULT_ARM_HYST_S = 1.0


@dataclass(frozen=True)
class Sticks:
    """The four sticks as PX4's manual_control_setpoint: roll (+ right), pitch (+ forward, nose down) and
    yaw (+ clockwise) in [-1, 1]; throttle in [0, 1], 0.5 the centre where Altitude and Position hold."""

    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    throttle: float = 0.5

    def clamped(self):
        """Every stick within its range (a NaN is centred)."""

        def clamp(value, low, high, centre):
            return centre if math.isnan(value) else min(max(value, low), high)

        return Sticks(
            roll=clamp(self.roll, -1.0, 1.0, 0.0),
            pitch=clamp(self.pitch, -1.0, 1.0, 0.0),
            yaw=clamp(self.yaw, -1.0, 1.0, 0.0),
            throttle=clamp(self.throttle, 0.0, 1.0, 0.5),
        )

    def describe(self):
        return f"pitch {self.pitch:+.2f} roll {self.roll:+.2f} yaw {self.yaw:+.2f} throttle {self.throttle:.2f}"


CENTRED = Sticks()


def manual_control_axes(sticks):
    """(x, y, z, r) of MANUAL_CONTROL for `sticks`, as PX4 reads them: x pitch, y roll, r yaw scaled to
    -1000..1000, z throttle to 0..1000 (500 = centre); rounded, out-of-range sticks clamped."""
    s = sticks.clamped()

    def scale(value):
        # Half away from zero, as the vehicle's own Sticks::to_manual_control (Python's round() is to even).
        return int(math.copysign(math.floor(abs(value) * 1000.0 + 0.5), value))

    return scale(s.pitch), scale(s.roll), scale(s.throttle), scale(s.yaw)


def manual_control_message(mav, target_system, sticks, buttons=0):
    """MANUAL_CONTROL to `target_system` (the vehicle's system id: a vehicle takes only its own) carrying
    `sticks`, encoded on the pymavlink MAVLink object `mav`."""
    x, y, z, r = manual_control_axes(sticks)
    return mav.manual_control_encode(target_system, x, y, z, r, buttons)


# -- the script ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Step:
    """Hold `sticks` for `for_s` seconds of vehicle time."""

    for_s: float
    sticks: Sticks


class ScriptError(GcsError):
    """A stick script that cannot be flown (exit 1, nothing sent)."""


def _number(value, where):
    # TOML booleans are not numbers here, though Python's bool is an int.
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScriptError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ScriptError(f"{where} must be finite, got {value}")
    return value


def parse_script(text, name="script"):
    """The steps of a stick script (TOML text; see the module docs). Every error names the step and key."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ScriptError(f"{name}: not TOML: {e}") from None
    extra = sorted(set(doc) - {"step"})
    if extra:
        raise ScriptError(f"{name}: unknown key(s) {', '.join(extra)}: a script has only [[step]] tables")
    raw = doc.get("step")
    if not raw:
        raise ScriptError(f"{name}: no [[step]]: nothing to fly")
    if not isinstance(raw, list) or not all(isinstance(s, dict) for s in raw):
        raise ScriptError(f"{name}: `step` must be an array of tables ([[step]])")
    steps = []
    for i, table in enumerate(raw, 1):
        where = f"{name}: step {i}"
        unknown = sorted(set(table) - set(STEP_KEYS))
        if unknown:
            raise ScriptError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(STEP_KEYS)})")
        if "for_s" not in table:
            raise ScriptError(f"{where}: for_s (its duration, s of vehicle time) is missing")
        for_s = _number(table["for_s"], f"{where}: for_s")
        if not 0.0 < for_s <= MAX_STEP_S:
            raise ScriptError(f"{where}: for_s = {for_s:g} must be > 0 and at most {MAX_STEP_S:g} s")
        values = {}
        for key, (low, high) in STICK_RANGES.items():
            if key in table:
                value = _number(table[key], f"{where}: {key}")
                if not low <= value <= high:
                    raise ScriptError(f"{where}: {key} = {value:g} is outside {low:g}..{high:g}")
                values[key] = value
        steps.append(Step(for_s, replace(CENTRED, **values)))
    return steps


def load_script(path):
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise ScriptError(f"cannot read {path}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ScriptError(f"{path}: not UTF-8 text") from None
    return parse_script(text, str(path))


# -- the keyboard ----------------------------------------------------------------------------------------

STICK_NOTCH = 0.25  # pitch, roll, yaw per key press
THROTTLE_NOTCH = 0.1
_ESCAPES = {"A": "up", "B": "down", "C": "right", "D": "left"}


def parse_keys(data):
    """The keys in a chunk of terminal input: single characters, and the arrow keys' escape sequences
    (ESC [ A..D, or ESC O A..D in application mode) as "up", "down", "right", "left"."""
    keys = []
    i = 0
    while i < len(data):
        ch = data[i]
        if ch == "\x1b" and i + 2 < len(data) and data[i + 1] in "[O" and data[i + 2] in _ESCAPES:
            keys.append(_ESCAPES[data[i + 2]])
            i += 3
            continue
        keys.append(ch)
        i += 1
    return keys


def apply_key(sticks, key):
    """(sticks after `key`, action or None): a stick key moves its stick one notch (clamped); space centres
    them all; "l" puts the throttle low with the rest centred; "t" asks to arm, "x" to quit."""
    moves = {
        "up": ("pitch", STICK_NOTCH),
        "w": ("pitch", STICK_NOTCH),
        "down": ("pitch", -STICK_NOTCH),
        "s": ("pitch", -STICK_NOTCH),
        "right": ("roll", STICK_NOTCH),
        "d": ("roll", STICK_NOTCH),
        "left": ("roll", -STICK_NOTCH),
        "a": ("roll", -STICK_NOTCH),
        "e": ("yaw", STICK_NOTCH),
        "q": ("yaw", -STICK_NOTCH),
        "r": ("throttle", THROTTLE_NOTCH),
        "f": ("throttle", -THROTTLE_NOTCH),
    }
    key = key.lower() if len(key) == 1 else key
    if key in moves:
        axis, delta = moves[key]
        value = round(getattr(sticks, axis) + delta, 6)
        return replace(sticks, **{axis: value}).clamped(), None
    if key == " ":
        return CENTRED, None
    if key == "l":
        return replace(CENTRED, throttle=0.0), "land"
    if key == "t":
        return sticks, "arm"
    if key == "x":
        return sticks, "quit"
    return sticks, None


# -- the gamepad (Linux joystick API, struct js_event) ----------------------------------------------------

JS_EVENT = struct.Struct("<IhBB")  # time ms, value, type, number
JS_EVENT_BUTTON = 0x01
JS_EVENT_AXIS = 0x02
JS_EVENT_INIT = 0x80
JS_AXIS_MAX = 32767.0


def decode_js_events(data):
    """(kind, number, value) of each whole js_event in `data` ("button" or "axis"; the driver's initial
    state events count as events of their kind)."""
    events = []
    for offset in range(0, len(data) - len(data) % JS_EVENT.size, JS_EVENT.size):
        _, value, kind, number = JS_EVENT.unpack_from(data, offset)
        kind &= ~JS_EVENT_INIT
        if kind == JS_EVENT_AXIS:
            events.append(("axis", number, value))
        elif kind == JS_EVENT_BUTTON:
            events.append(("button", number, value))
    return events


def parse_axes(text):
    """--axes ROLL,PITCH,THROTTLE,YAW: four distinct axis numbers."""
    parts = text.split(",")
    if len(parts) != 4 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"--axes takes four axis numbers ROLL,PITCH,THROTTLE,YAW, got {text!r}")
    axes = tuple(int(p) for p in parts)
    if len(set(axes)) != 4:
        raise argparse.ArgumentTypeError(f"--axes must name four different axes, got {text!r}")
    return axes


def gamepad_sticks(axis_values, axes):
    """Sticks from the raw axis values (-32767..32767, up and left negative, as Linux reports them) under
    the `axes` assignment (roll, pitch, throttle, yaw): stick up is pitch forward and throttle high."""
    roll_axis, pitch_axis, throttle_axis, yaw_axis = axes

    def read(n):
        return axis_values.get(n, 0) / JS_AXIS_MAX

    return Sticks(
        roll=read(roll_axis),
        pitch=-read(pitch_axis),
        yaw=read(yaw_axis),
        throttle=(1.0 - read(throttle_axis)) / 2.0,
    ).clamped()


# -- the vehicle -----------------------------------------------------------------------------------------


class PilotVehicle(Vehicle):
    """A Vehicle that streams the current sticks (`sticks`; None: nothing is sent) as MANUAL_CONTROL before
    each receive, every `period_s` of vehicle time or of wall time, whichever comes first: every wait of the
    flight keeps them flowing."""

    def __init__(self, connect, target=None, wall_limit_s=600.0):
        super().__init__(connect, target, wall_limit_s)
        self.sticks: Sticks | None = None
        self.period_s = 1.0 / DEFAULT_RATE_HZ
        self.sent = 0
        self.last_sent_s: float | None = None  # the vehicle time of the last MANUAL_CONTROL sent
        self._next_sticks = (-1e9, -1e9)  # when the next is due: (vehicle s, wall s)

    def before_pump(self):
        super().before_pump()
        if self.sticks is None or self.system_id is None:
            return
        due_vehicle_s, due_wall = self._next_sticks
        now_vehicle_s, now_wall = self.now_s(), time.monotonic()
        vehicle_due, wall_due = now_vehicle_s >= due_vehicle_s - 1e-9, now_wall >= due_wall - 1e-9
        if vehicle_due or wall_due:
            # On the clock that called for it, due again one period after this one was due (the telemetry
            # clock moves in 20 ms ticks: one period after the send itself would average fewer than
            # `1 / period_s` a second), or a period from now if that has passed already; on the other
            # clock, a period from now.
            self._next_sticks = (
                self._next_due(due_vehicle_s, now_vehicle_s) if vehicle_due else now_vehicle_s + self.period_s,
                self._next_due(due_wall, now_wall) if wall_due else now_wall + self.period_s,
            )
            self.last_sent_s = now_vehicle_s
            self.send(manual_control_message(self.conn.mav, self.system_id, self.sticks))
            self.sent += 1

    def _next_due(self, due, now):
        after = due + self.period_s
        return after if after > now else now + self.period_s


class Track:
    """LOCAL_POSITION_NED samples, printed every `every_s` of vehicle time."""

    def __init__(self, vehicle, every_s):
        self.vehicle = vehicle
        self.every_s = every_s
        self.samples = []  # (t_s, (n, e, d), (vn, ve, vd))
        self._printed_s = -1e9

    def __call__(self, msg):
        if msg.get_type() != "LOCAL_POSITION_NED":
            return
        t = self.vehicle.now_s()
        pos, vel = (msg.x, msg.y, msg.z), (msg.vx, msg.vy, msg.vz)
        self.samples.append((t, pos, vel))
        if self.every_s > 0 and t - self._printed_s >= self.every_s:
            self._printed_s = t
            flight.say(
                f"  t {t:8.2f} s  N {pos[0]:+7.2f} E {pos[1]:+7.2f} D {pos[2]:+7.2f} m"
                f"  v {vel[0]:+5.2f} {vel[1]:+5.2f} {vel[2]:+5.2f} m/s"
            )


def position_mode(vehicle):
    """DO_SET_MODE Position (PX4 main 3): fails with the vehicle's reason when refused."""
    vehicle.set_px4_mode(PX4_MAIN_POSCTL, 0, "Position mode")
    flight.say(f"Position mode at t {vehicle.now_s():.2f} s")


def arm(vehicle, how):
    """Arm by ARM_DISARM ("command") or the stick gesture ("gesture": throttle low, yaw right, held longer
    than COM_RC_ARM_HYST); the sticks are centred afterwards. Fails with the vehicle's reason."""
    if how == "gesture":
        hyst_s = Params(vehicle, AUTOPILOT_COMPONENT).get("COM_RC_ARM_HYST") or DEFAULT_ARM_HYST_S
        since = vehicle.now_s()
        vehicle.sticks = Sticks(throttle=0.0, yaw=1.0)
        try:
            vehicle.wait_until(hyst_s + 2.0, "armed by the stick gesture", lambda: vehicle.armed)
        except CheckFailed as e:
            texts = "; ".join(vehicle.texts_since(since))
            raise CheckFailed(f"{e}" + (f" ({texts})" if texts else "")) from None
        finally:
            vehicle.sticks = CENTRED
    else:
        vehicle.require("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        vehicle.wait_until(2.0, "armed HEARTBEAT", lambda: vehicle.armed)
    flight.say(f"armed at t {vehicle.now_s():.2f} s")


def hold_mode(vehicle):
    """DO_SET_MODE Hold (AUTO LOITER), which needs no sticks; warns when the vehicle will still fail safe
    once the stream stops (COM_RCL_EXCEPT without bit 2, Hold)."""
    vehicle.set_px4_mode(PX4_MAIN_AUTO, PX4_AUTO_LOITER, "Hold mode")
    flight.say(f"Hold mode at t {vehicle.now_s():.2f} s")
    exempt = Params(vehicle, AUTOPILOT_COMPONENT).get("COM_RCL_EXCEPT")
    if exempt is not None and not int(exempt) & RCL_EXCEPT_HOLD:
        flight.warn(
            f"COM_RCL_EXCEPT = {int(exempt)} does not exempt Hold (bit 2): once the sticks stop, the vehicle "
            "takes its manual-control-loss action (NAV_RCL_ACT) after COM_RC_LOSS_T"
        )


def check_still_flying(vehicle, since_s):
    """Fail when the vehicle has left Position mode (a failsafe or another ground station)."""
    if vehicle.px4_mode()[0] != PX4_MAIN_POSCTL:
        texts = "; ".join(vehicle.texts_since(since_s))
        main, sub = vehicle.px4_mode()
        raise CheckFailed(
            f"the vehicle left Position mode (now PX4 mode {main}.{sub}) at t {vehicle.now_s():.2f} s"
            + (f": {texts}" if texts else "")
        )


def land_by_throttle(vehicle, seconds=120.0):
    """Throttle low, the rest centred, until the vehicle is on the ground and disarmed (COM_DISARM_LAND)."""
    vehicle.sticks = Sticks(throttle=0.0)
    took = vehicle.wait_until(
        seconds,
        "landed (throttle low) and disarmed",
        lambda: vehicle.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND and not vehicle.armed,
    )
    flight.say(f"landed and disarmed after {took:.1f} s of throttle low (t {vehicle.now_s():.2f} s)")


def fly_script(vehicle, steps, then):
    """Each step's sticks for its vehicle time; then land (throttle low) or Hold."""
    start_s = vehicle.now_s()
    for i, step in enumerate(steps, 1):
        begin_s = vehicle.now_s()
        flight.say(f"step {i}/{len(steps)} at t {begin_s:.2f} s for {step.for_s:g} s: {step.sticks.describe()}")
        vehicle.sticks = step.sticks
        begin = vehicle.pos
        while vehicle.now_s() - begin_s < step.for_s:
            vehicle.pump()
            if not vehicle.armed:
                if vehicle.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
                    flight.say(f"landed and disarmed during step {i} at t {vehicle.now_s():.2f} s")
                    return
                raise CheckFailed(f"disarmed during step {i} at t {vehicle.now_s():.2f} s")
            check_still_flying(vehicle, start_s)
        if begin is not None and vehicle.pos is not None:
            moved = [b - a for a, b in zip(begin, vehicle.pos, strict=True)]
            flight.say(f"  step {i} moved N {moved[0]:+.2f} E {moved[1]:+.2f} D {moved[2]:+.2f} m")
    if then == "hold":
        hold_mode(vehicle)
    elif vehicle.armed:
        land_by_throttle(vehicle)


KEYBOARD_HELP = """keys (each press moves a stick one notch; it stays there):
  up/down or w/s  pitch forward/back    left/right or a/d  roll left/right
  q/e             yaw left/right        r/f                throttle up/down (0.5 holds the altitude)
  space           centre every stick    t                  arm
  l               land (throttle low)   x                  quit (in the air: lands first)"""


def quit_flight(vehicle):
    """Before the stream stops, armed: on the ground, disarm (ARM_DISARM); in the air (or when the vehicle
    refuses the disarm: it may have left the ground since its last EXTENDED_SYS_STATE), land by throttle low
    and wait for the disarm."""
    if not vehicle.armed:
        return
    on_ground = vehicle.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND
    if on_ground and vehicle.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mavlink.MAV_RESULT_ACCEPTED:
        vehicle.wait_until(2.0, "disarmed HEARTBEAT", lambda: not vehicle.armed)
        flight.say(f"disarmed on the ground at t {vehicle.now_s():.2f} s")
        return
    flight.say("in the air: landing before quitting (Ctrl-C quits at once)")
    land_by_throttle(vehicle)


def _keyboard_loop(vehicle, args, read_input):
    flight.say(KEYBOARD_HELP)
    vehicle.sticks = CENTRED
    while True:
        for key in parse_keys(read_input()):
            sticks, action = apply_key(vehicle.sticks, key)
            if sticks != vehicle.sticks:
                vehicle.sticks = sticks
                flight.say(f"sticks: {sticks.describe()}")
            if action == "arm":
                try:
                    arm(vehicle, args.arm)
                except CheckFailed as e:
                    flight.warn(str(e))  # a refusal at the keyboard is reported, not fatal
            elif action == "land":
                flight.say("landing: throttle low")
            elif action == "quit":
                quit_flight(vehicle)
                return
        vehicle.pump()


def fly_keyboard(vehicle, args):
    """The terminal in cbreak mode (keys arrive as pressed, output as usual) until "x"."""
    import termios
    import tty

    fd = sys.stdin.fileno()

    def read_input():
        chunks = []
        while select.select([fd], [], [], 0)[0]:
            data = os.read(fd, 64)
            if not data:
                break
            chunks.append(data.decode("utf-8", "replace"))
        return "".join(chunks)

    saved = termios.tcgetattr(fd)
    try:
        # TCSADRAIN, not tty's default TCSAFLUSH: a key typed before the terminal switched is kept.
        tty.setcbreak(fd, termios.TCSADRAIN)
        _keyboard_loop(vehicle, args, read_input)
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def open_gamepad(device):
    """The joystick device, opened non-blocking (before anything is sent to the vehicle)."""
    try:
        return os.open(device, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as e:
        raise GcsError(
            f"cannot open {device}: {e.strerror} (--gamepad reads a Linux joystick device, /dev/input/jsN; "
            "or fly a gamepad with QGroundControl's joystick support, Vehicle Setup > Joystick)"
        ) from None


def fly_gamepad(vehicle, args, fd):
    """Axes and buttons from a Linux joystick device until button 1 (or Ctrl-C)."""
    axis_values: dict[int, int] = {}
    vehicle.sticks = CENTRED
    flight.say(f"gamepad {args.gamepad}: axes roll,pitch,throttle,yaw = {args.axes}; button 0 arms, button 1 quits")
    try:
        while True:
            with contextlib.suppress(BlockingIOError):
                for kind, number, value in decode_js_events(os.read(fd, JS_EVENT.size * 64)):
                    if kind == "axis":
                        axis_values[number] = value
                    elif value and number == 0:
                        try:
                            arm(vehicle, args.arm)
                        except CheckFailed as e:
                            flight.warn(str(e))
                    elif value and number == 1:
                        quit_flight(vehicle)
                        return
            vehicle.sticks = gamepad_sticks(axis_values, args.axes)
            vehicle.pump()
    finally:
        os.close(fd)


def parser():
    p = argparse.ArgumentParser(
        prog="aco-sticks", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_link_args(p)
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--script", metavar="FILE", help="fly a stick script (TOML, see above)")
    source.add_argument("--keyboard", action="store_true", help="fly from the terminal's keys")
    source.add_argument(
        "--gamepad", nargs="?", const="/dev/input/js0", metavar="DEVICE", help="fly a Linux joystick device"
    )
    p.add_argument(
        "--axes",
        type=parse_axes,
        default=(3, 4, 1, 0),
        metavar="R,P,T,Y",
        help="--gamepad: the axis numbers of roll, pitch, throttle and yaw (default 3,4,1,0)",
    )
    p.add_argument(
        "--arm",
        choices=("command", "gesture"),
        default="command",
        help="arm by ARM_DISARM (default) or by the stick gesture (throttle low, yaw right; MAN_ARM_GESTURE)",
    )
    p.add_argument(
        "--then",
        choices=("land", "hold"),
        default="land",
        help="--script: after the last step, land by throttle low and wait for the disarm (default), or Hold",
    )
    p.add_argument(
        "--rate",
        type=positive_float,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help=f"MANUAL_CONTROL per second of vehicle time (and of wall time) (default {DEFAULT_RATE_HZ:g})",
    )
    p.add_argument(
        "--track",
        type=float,
        default=0.5,
        metavar="S",
        help="print the position every S seconds of vehicle time (default 0.5; 0: not at all)",
    )
    p.add_argument("--check", action="store_true", help="--script: read and check the script, fly nothing")
    return p


def run(args):
    steps = load_script(args.script) if args.script is not None else None
    if args.check:
        if steps is None:
            raise GcsError("--check reads a --script")
        for i, step in enumerate(steps, 1):
            flight.say(f"step {i}/{len(steps)} for {step.for_s:g} s: {step.sticks.describe()}")
        flight.say(f"{len(steps)} steps, {sum(s.for_s for s in steps):g} s of vehicle time")
        return 0
    if args.keyboard and not os.isatty(sys.stdin.fileno()):
        raise GcsError("--keyboard needs a terminal on standard input")
    if not args.rate <= 1000.0:
        raise GcsError(f"--rate {args.rate:g} is more than 1000 per second")
    gamepad_fd = open_gamepad(args.gamepad) if args.gamepad is not None else None
    vehicle = PilotVehicle.from_args(args)
    vehicle.period_s = 1.0 / args.rate
    track = Track(vehicle, args.track)
    vehicle.listeners.append(track)
    flight.say(f"vehicle: system {vehicle.system_id} on {vehicle.connect}")
    _, converge_s = flight.wait_ready(vehicle)
    flight.say(f"estimator ready after {converge_s:.1f} s")
    # The sticks flow before the mode change: a manual mode needs manual control that is already there.
    vehicle.sticks = CENTRED
    vehicle.wait_until(1.0, "the first MANUAL_CONTROL out", lambda: vehicle.sent >= 3)
    position_mode(vehicle)
    if steps is not None:
        arm(vehicle, args.arm)
        fly_script(vehicle, steps, args.then)
    elif args.keyboard:
        fly_keyboard(vehicle, args)
    elif gamepad_fd is not None:
        fly_gamepad(vehicle, args, gamepad_fd)
    flight.say(f"{vehicle.sent} MANUAL_CONTROL sent")
    vehicle.sticks = None
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
