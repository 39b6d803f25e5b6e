"""Plot a `.tlog` the autopilot wrote (`sitl run --log-dir DIR`): position (LOCAL_POSITION_NED) and
attitude (ATTITUDE) of the vehicle against its time_boot_ms, to a PNG; `--list` prints the message counts
instead. Exit 1 if the log has no LOCAL_POSITION_NED or ATTITUDE, 2 if it holds no vehicle HEARTBEAT (or
cannot be read)."""

import argparse
import math
import os
import sys
from collections import Counter

from .link import (
    AUTOPILOT_COMPONENT,
    CheckFailed,
    GcsError,
    NoVehicle,
    mavlink,
    mavutil,
    run_main,
)


def parser():
    p = argparse.ArgumentParser(
        prog="aco-tlog-plot", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("tlog", help="the .tlog file")
    p.add_argument("--png", help="output plot (default: the tlog's name with .png)")
    p.add_argument("--list", action="store_true", help="print the count of each message type and exit")
    p.add_argument("--system", type=int, help="the vehicle's system id (default: the first autopilot HEARTBEAT's)")
    return p


def read(path):
    """Every message of the log, in order."""
    if not os.path.isfile(path):
        raise NoVehicle(f"{path}: no such file")
    try:
        log = mavutil.mavlink_connection(path)
    except Exception as e:  # pymavlink raises whatever its reader hits
        raise GcsError(f"{path}: cannot read: {e}") from e
    out = []
    while True:
        msg = log.recv_match()
        if msg is None:
            break
        if msg.get_type() != "BAD_DATA":
            out.append(msg)
    log.close()
    return out


def run(args):
    messages = read(args.tlog)
    if args.list:
        counts = Counter((m.get_srcSystem(), m.get_srcComponent(), m.get_type()) for m in messages)
        for (sysid, comp, kind), n in sorted(counts.items()):
            print(f"{kind:28} {n:8d}  (system {sysid}, component {comp})")
        print(f"{len(messages)} messages")
        return 0
    sysid = args.system
    if sysid is None:
        for m in messages:
            if (
                m.get_type() == "HEARTBEAT"
                and m.get_srcComponent() == AUTOPILOT_COMPONENT
                and m.autopilot != mavlink.MAV_AUTOPILOT_INVALID
                and m.type != mavlink.MAV_TYPE_GCS
            ):
                sysid = m.get_srcSystem()
                break
    if sysid is None:
        raise NoVehicle(f"{args.tlog}: no vehicle HEARTBEAT in {len(messages)} messages")
    ours = [m for m in messages if m.get_srcSystem() == sysid and m.get_srcComponent() == AUTOPILOT_COMPONENT]
    pos = [(m.time_boot_ms / 1000.0, m.x, m.y, m.z) for m in ours if m.get_type() == "LOCAL_POSITION_NED"]
    att = [(m.time_boot_ms / 1000.0, m.roll, m.pitch, m.yaw) for m in ours if m.get_type() == "ATTITUDE"]
    if not pos or not att:
        raise CheckFailed(f"{args.tlog}: {len(pos)} LOCAL_POSITION_NED and {len(att)} ATTITUDE from system {sysid}")
    pos.sort()
    att.sort()

    from .plot import figure, save

    fig, (ax_pos, ax_att) = figure(2, 1, size=(9, 6.5), sharex=True)
    for k, label in enumerate(("north", "east", "down"), 1):
        ax_pos.plot([p[0] for p in pos], [p[k] for p in pos], lw=1.0, label=label)
    ax_pos.set_ylabel("position (m, NED)")
    ax_pos.grid(True, alpha=0.3)
    ax_pos.legend(loc="best", fontsize=8)
    for k, label in enumerate(("roll", "pitch", "yaw"), 1):
        ax_att.plot([a[0] for a in att], [math.degrees(a[k]) for a in att], lw=1.0, label=label)
    ax_att.set_ylabel("attitude (deg)")
    ax_att.set_xlabel("vehicle time (s, time_boot_ms)")
    ax_att.grid(True, alpha=0.3)
    ax_att.legend(loc="best", fontsize=8)
    ax_pos.set_title(f"{os.path.basename(args.tlog)}: system {sysid}")
    png = args.png or os.path.splitext(args.tlog)[0] + ".png"
    save(fig, png)
    span = pos[-1][0] - pos[0][0]
    print(f"{len(pos)} positions and {len(att)} attitudes over {span:.1f} s of vehicle time: {png}")
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
