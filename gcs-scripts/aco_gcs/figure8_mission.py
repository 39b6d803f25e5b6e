"""The paper's figure-8 as a mission (pymavlink): NAV_TAKEOFF 1.5 m, DO_CHANGE_SPEED 0.3 m/s, nine
NAV_SPLINE_WAYPOINTs (one curve through them, as ArduPilot flies spline waypoints) through (N, E) =
(0,0) (0.6,0.6) (1.2,0) (0.6,-0.6) (0,0) (-0.6,0.6) (-1.2,0) (-0.6,-0.6) (0,0) m from home at 1.5 m
(MAV_FRAME_GLOBAL_RELATIVE_ALT_INT), NAV_LAND. Uploads it with the mission protocol, downloads it back
and compares, arms, switches to AUTO MISSION, follows MISSION_CURRENT / MISSION_ITEM_REACHED to the
landing, records LOCAL_POSITION_NED, and writes the flown track against the waypoints (--png, --csv).
Exit 1 if the mission does not go through (or a waypoint is not reached), 2 if no vehicle answers."""

import argparse
import itertools
import math
import sys

from . import flight
from .link import (
    PX4_AUTO_MISSION,
    PX4_MAIN_AUTO,
    CheckFailed,
    Vehicle,
    add_link_args,
    mavlink,
    positive_float,
    run_main,
    same_float32,
)

FIGURE8_NE_M = [(0, 0), (0.6, 0.6), (1.2, 0), (0.6, -0.6), (0, 0), (-0.6, 0.6), (-1.2, 0), (-0.6, -0.6), (0, 0)]
EARTH_RADIUS_M = 6_378_137.0
ITEM_TIMEOUT_S = 2.0  # vehicle seconds to wait for the next request / item before resending
RETRIES = 5


class Item:
    """One mission item as MISSION_ITEM_INT carries it."""

    def __init__(self, command, frame, params=(0, 0, 0, 0), x=0, y=0, z=0.0):
        self.command, self.frame = command, frame
        self.params = tuple(float(p) for p in params) + (0.0,) * (4 - len(params))
        self.x, self.y, self.z = int(x), int(y), float(z)

    def key(self):
        return (self.command, self.frame, self.x, self.y)

    def matches(self, other):
        return (
            self.key() == other.key()
            and abs(self.z - other.z) < 1e-3
            and all(same_float32(a, b) for a, b in zip(self.params, other.params, strict=True))
        )

    def __repr__(self):
        name = mavlink.enums["MAV_CMD"][self.command].name if self.command in mavlink.enums["MAV_CMD"] else self.command
        return f"{name}(frame {self.frame}, params {self.params}, x {self.x}, y {self.y}, z {self.z:g})"


def offset_deg(lat_deg, lon_deg, north_m, east_m):
    """Lat/lon (deg) of a point `north_m`, `east_m` from (lat, lon): flat Earth, exact to well below a
    millimetre over a few metres."""
    dlat = math.degrees(north_m / EARTH_RADIUS_M)
    dlon = math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat_deg))))
    return lat_deg + dlat, lon_deg + dlon


def build_mission(home_lat, home_lon, alt_m, speed_mps, points=FIGURE8_NE_M):
    rel = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    nan = float("nan")

    def at(n, e):
        lat, lon = offset_deg(home_lat, home_lon, n, e)
        return round(lat * 1e7), round(lon * 1e7)

    x0, y0 = at(0, 0)
    items = [
        Item(mavlink.MAV_CMD_NAV_TAKEOFF, rel, (0, 0, 0, nan), x0, y0, alt_m),
        Item(mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, (1, speed_mps, -1, 0)),
    ]
    for n, e in points:
        x, y = at(n, e)
        items.append(Item(mavlink.MAV_CMD_NAV_SPLINE_WAYPOINT, rel, (0, 0, 0, nan), x, y, alt_m))
    items.append(Item(mavlink.MAV_CMD_NAV_LAND, rel, (0, 0, 0, nan), x0, y0, 0.0))
    return items


def send_item(vehicle, seq, item, legacy):
    sysid = vehicle.system_id
    if legacy:
        vehicle.conn.mav.mission_item_send(
            sysid, 1, seq, item.frame, item.command, 0, 1, *item.params, item.x / 1e7, item.y / 1e7, item.z
        )
    else:
        vehicle.conn.mav.mission_item_int_send(
            sysid, 1, seq, item.frame, item.command, 0, 1, *item.params, item.x, item.y, item.z
        )


def upload(vehicle, items):
    """MISSION_COUNT -> (MISSION_REQUEST_INT -> MISSION_ITEM_INT)* -> MISSION_ACK, resending on vehicle-time
    time-outs."""
    vehicle.conn.mav.mission_count_send(vehicle.system_id, 1, len(items))
    requested: set[int] = set()
    last_sent = None
    retries = 0
    kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
    while True:
        msg = vehicle.next_message(ITEM_TIMEOUT_S, lambda m: m.get_type() in kinds)
        if msg is None:
            retries += 1
            if retries > RETRIES:
                raise CheckFailed(f"mission upload: no answer after {RETRIES} resends (requested {sorted(requested)})")
            if last_sent is None:
                vehicle.conn.mav.mission_count_send(vehicle.system_id, 1, len(items))
            else:
                send_item(vehicle, last_sent[0], items[last_sent[0]], last_sent[1])
            continue
        retries = 0
        if msg.get_type() == "MISSION_ACK":
            if msg.type != mavlink.MAV_MISSION_ACCEPTED:
                name = mavlink.enums["MAV_MISSION_RESULT"][msg.type].name
                texts = "; ".join(t for (_, _, t) in vehicle.statustexts[-3:])
                raise CheckFailed(f"mission upload refused: {name} ({texts})")
            if len(requested) < len(items):
                raise CheckFailed(f"mission upload: ACK after only {len(requested)} of {len(items)} items")
            return
        seq = msg.seq
        if not 0 <= seq < len(items):
            raise CheckFailed(f"mission upload: the vehicle asked for item {seq} of {len(items)}")
        legacy = msg.get_type() == "MISSION_REQUEST"
        send_item(vehicle, seq, items[seq], legacy)
        requested.add(seq)
        last_sent = (seq, legacy)


def download(vehicle):
    """MISSION_REQUEST_LIST -> MISSION_COUNT -> (MISSION_REQUEST_INT -> MISSION_ITEM_INT)* -> MISSION_ACK."""
    count = None
    for _ in range(RETRIES):
        vehicle.conn.mav.mission_request_list_send(vehicle.system_id, 1)
        msg = vehicle.next_message(ITEM_TIMEOUT_S, lambda m: m.get_type() == "MISSION_COUNT")
        if msg is not None:
            count = msg.count
            break
    if count is None:
        raise CheckFailed("mission download: no MISSION_COUNT")
    items = []
    for seq in range(count):
        for _ in range(RETRIES):
            vehicle.conn.mav.mission_request_int_send(vehicle.system_id, 1, seq)
            msg = vehicle.next_message(
                ITEM_TIMEOUT_S, lambda m, s=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == s
            )
            if msg is not None:
                params = (msg.param1, msg.param2, msg.param3, msg.param4)
                items.append(Item(msg.command, msg.frame, params, msg.x, msg.y, msg.z))
                break
        else:
            raise CheckFailed(f"mission download: no item {seq}")
    vehicle.conn.mav.mission_ack_send(vehicle.system_id, 1, mavlink.MAV_MISSION_ACCEPTED)
    return items


def parser():
    p = argparse.ArgumentParser(
        prog="aco-figure8-mission", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_link_args(p)
    p.add_argument("--alt", type=positive_float, default=1.5, help="mission height above home, m (default 1.5)")
    p.add_argument("--speed", type=positive_float, default=0.3, help="DO_CHANGE_SPEED ground speed, m/s (default 0.3)")
    p.add_argument("--png", help="write the track plot to this PNG (default: no plot)")
    p.add_argument("--csv", help="write the track samples to this CSV (default: none)")
    p.add_argument(
        "--mission-s", type=positive_float, default=240.0, help="vehicle seconds the mission may take (default 240)"
    )
    return p


def cross_track_m(point, polyline):
    """Distance (m) from `point` (n, e) to the nearest segment of `polyline`."""
    best = math.inf
    for (n0, e0), (n1, e1) in itertools.pairwise(polyline):
        dn, de = n1 - n0, e1 - e0
        length2 = dn * dn + de * de
        u = 0.0 if length2 == 0 else max(0.0, min(1.0, ((point[0] - n0) * dn + (point[1] - e0) * de) / length2))
        best = min(best, math.hypot(point[0] - (n0 + u * dn), point[1] - (e0 + u * de)))
    return best


def run(args):
    vehicle = Vehicle.from_args(args)
    flight.say(f"vehicle: system {vehicle.system_id} on {vehicle.connect}")
    ground, _ = flight.wait_ready(vehicle)
    if vehicle.home is None:
        # HOME_POSITION streams at ~0.5 Hz; give it a few seconds before falling back on the position.
        vehicle.next_message(3.0, lambda m: m.get_type() == "HOME_POSITION")
    if vehicle.home is not None:
        home_lat, home_lon = vehicle.home.latitude / 1e7, vehicle.home.longitude / 1e7
        origin = (vehicle.home.x, vehicle.home.y)
        source = "HOME_POSITION"
    else:
        vehicle.wait_until(5.0, "GLOBAL_POSITION_INT", lambda: vehicle.global_pos is not None)
        home_lat, home_lon = vehicle.global_pos.lat / 1e7, vehicle.global_pos.lon / 1e7
        origin = (ground[0], ground[1])
        source = "GLOBAL_POSITION_INT"
    flight.say(f"home ({source}): {home_lat:.7f}, {home_lon:.7f}")

    items = build_mission(home_lat, home_lon, args.alt, args.speed)
    upload(vehicle, items)
    flight.say(f"uploaded {len(items)} items")
    back = download(vehicle)
    if len(back) != len(items):
        raise CheckFailed(f"downloaded {len(back)} items, uploaded {len(items)}")
    for seq, (sent, got) in enumerate(zip(items, back, strict=True)):
        if not sent.matches(got):
            raise CheckFailed(f"item {seq} came back different: sent {sent}, got {got}")
    flight.say(f"downloaded {len(back)} items: identical")

    waypoint_seqs = [s for s, it in enumerate(items) if it.command == mavlink.MAV_CMD_NAV_SPLINE_WAYPOINT]
    track = []  # (t_s, n_m, e_m, d_m, current_seq)
    reached = []
    current = [None]

    def record(msg):
        kind = msg.get_type()
        if kind == "LOCAL_POSITION_NED":
            track.append((vehicle.now_s(), msg.x - origin[0], msg.y - origin[1], msg.z, current[0]))
        elif kind == "MISSION_CURRENT" and msg.seq != current[0]:
            current[0] = msg.seq
            flight.say(f"  t={vehicle.now_s():7.2f} s  current item {msg.seq}")
        elif kind == "MISSION_ITEM_REACHED" and msg.seq not in reached:
            reached.append(msg.seq)
            flight.say(f"  t={vehicle.now_s():7.2f} s  reached item {msg.seq}")

    vehicle.listeners.append(record)
    vehicle.require("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    vehicle.wait_until(2.0, "armed HEARTBEAT", lambda: vehicle.armed)
    vehicle.set_px4_mode(PX4_MAIN_AUTO, PX4_AUTO_MISSION, "AUTO MISSION")
    start = vehicle.now_s()
    flew = [False]

    def finished():
        flew[0] = flew[0] or (vehicle.pos is not None and vehicle.pos[2] < ground[2] - 0.5)
        return flew[0] and not vehicle.armed

    vehicle.wait_until(args.mission_s, "mission flown, landed and disarmed", finished)
    duration = vehicle.now_s() - start
    vehicle.listeners.remove(record)

    pts = FIGURE8_NE_M
    airborne = [r for r in track if r[4] is not None and waypoint_seqs[0] <= r[4] <= waypoint_seqs[-1]]
    xt = [cross_track_m((r[1], r[2]), pts) for r in airborne]
    from .plot import figure, save, write_csv

    if args.csv:
        write_csv(args.csv, ["t_s", "north_m", "east_m", "down_m", "mission_seq"], track)
    if args.png:
        fig, ax = figure(size=(7, 6))
        ax.plot([r[2] for r in track], [r[1] for r in track], lw=1.2, label="flown (LOCAL_POSITION_NED)")
        ax.plot([p[1] for p in pts], [p[0] for p in pts], "o--", color="tab:red", lw=0.8, label="waypoints")
        labels: dict[tuple[float, float], list[str]] = {}
        for k, point in enumerate(pts):
            labels.setdefault(point, []).append(str(waypoint_seqs[k]))
        for (n, e), seqs in labels.items():
            ax.annotate(",".join(seqs), (e, n), textcoords="offset points", xytext=(6, 4), fontsize=8)
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
        ax.set_title(f"Figure-8 mission at {args.speed:g} m/s, {args.alt:g} m: {len(reached)} items reached")
        save(fig, args.png)

    flight.say(f"items reached: {len(reached)} of {len(items)} ({sorted(reached)})")
    if xt:
        rms_m = math.sqrt(sum(v * v for v in xt) / len(xt))
        flight.say(f"cross-track to the waypoint polyline: max {max(xt):.3f} m, rms {rms_m:.3f} m")
    flight.say(f"mission flown in {duration:.1f} s of vehicle time")
    for what, path in (("plot", args.png), ("track samples", args.csv)):
        if path:
            flight.say(f"wrote the {what} to {path}")
    lost = vehicle.lost()
    flight.say(f"messages lost on the link: {lost}")
    missing = [s for s in waypoint_seqs if s not in reached]
    if missing:
        hint = (
            f" ({lost} messages were lost: this script read slower than the vehicle sent; run the SITL at a"
            " lower --speed)"
            if lost
            else ""
        )
        print(f"waypoints never reported reached: {missing}{hint}", file=sys.stderr)
        return 1
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
