"""Plot one flight from the ULog the autopilot wrote while it was armed (`<state dir>/log/<date>/<time>.ulg`):
position against its setpoint (vehicle_local_position, vehicle_local_position_setpoint), attitude against
the controller's attitude setpoint (vehicle_attitude, vehicle_attitude_setpoint), the four motor commands
(actuator_outputs), the battery (battery_status) and the ACO adaptive weights (aco_weights; with another
controller, the panel says so), on the vehicle's clock, to a PNG. `--list` prints the topics and the logged
messages instead. Exit 1 if the log lacks vehicle_local_position or vehicle_attitude, 2 if it cannot be
read as a ULog."""

import argparse
import math
import os
import sys

from .link import CheckFailed, GcsError, run_main


def parser():
    p = argparse.ArgumentParser(
        prog="aco-ulog-plot", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("ulog", help="the .ulg file")
    p.add_argument("--png", help="output plot (default: the log's name with .png)")
    p.add_argument(
        "--list", action="store_true", help="print the topics, their record counts and the logged messages, and exit"
    )
    return p


class Unreadable(GcsError):
    """The file is missing or not a ULog: exit 2."""

    exit_code = 2


def read(path):
    if not os.path.isfile(path):
        raise Unreadable(f"{path}: no such file")
    from pyulog import ULog

    try:
        return ULog(path)
    except Exception as e:  # pyulog raises whatever its parser hits
        raise Unreadable(f"{path}: cannot read as ULog: {e}") from e


def topic(log, name):
    """The first instance of topic `name`'s data (field name -> numpy array), or None."""
    for d in log.data_list:
        if d.name == name and d.multi_id == 0:
            return d.data
    return None


def seconds(log, data):
    return (data["timestamp"] - log.start_timestamp) / 1e6


def euler_deg(q):
    """(roll, pitch, yaw) in degrees of quaternion arrays (w, x, y, z), ZYX as the autopilot's."""
    import numpy as np

    from .view_ulog import euler_of_quat

    return tuple(np.degrees(euler_of_quat(np.stack([np.asarray(c, dtype=np.float64) for c in q], axis=1))).T)


def run(args):
    log = read(args.ulog)
    if args.list:
        for d in sorted(log.data_list, key=lambda d: d.name):
            print(f"{d.name:34} {len(d.data['timestamp']):7d}")
        for m in log.logged_messages:
            print(f"{m.timestamp / 1e6:10.3f} s  [{m.log_level_str()}] {m.message}")
        return 0
    pos, att = topic(log, "vehicle_local_position"), topic(log, "vehicle_attitude")
    if pos is None or att is None:
        raise CheckFailed(f"{args.ulog}: no vehicle_local_position or vehicle_attitude")
    sp, att_sp = topic(log, "vehicle_local_position_setpoint"), topic(log, "vehicle_attitude_setpoint")
    out, bat, weights = topic(log, "actuator_outputs"), topic(log, "battery_status"), topic(log, "aco_weights")

    from .plot import figure, save

    fig, axes = figure(5, 1, size=(9, 13), sharex=True)
    ax_pos, ax_att, ax_pwm, ax_bat, ax_w = axes
    t = seconds(log, pos)
    for axis, label in (("x", "north"), ("y", "east"), ("z", "down")):
        line = ax_pos.plot(t, pos[axis], lw=1.0, label=label)[0]
        if sp is not None:
            ax_pos.plot(seconds(log, sp), sp[axis], lw=0.8, ls="--", color=line.get_color(), label=f"{label} setpoint")
    ax_pos.set_ylabel("position (m, NED)")
    ax_pos.legend(loc="best", fontsize=7, ncol=2)
    t = seconds(log, att)
    euler = euler_deg([att[f"q[{i}]"] for i in range(4)])
    for k, label in enumerate(("roll", "pitch", "yaw")):
        line = ax_att.plot(t, euler[k], lw=1.0, label=label)[0]
        if att_sp is not None:
            body = [math.degrees(v) for v in att_sp[f"{label}_body"]]
            ax_att.plot(seconds(log, att_sp), body, lw=0.8, ls="--", color=line.get_color(), label=f"{label} setpoint")
    ax_att.set_ylabel("attitude (deg)")
    ax_att.legend(loc="best", fontsize=7, ncol=2)
    if out is not None:
        for i in range(int(out["noutputs"][0]) if len(out["noutputs"]) else 0):
            ax_pwm.plot(seconds(log, out), out[f"output[{i}]"], lw=0.8, label=f"rotor {i + 1}")
        ax_pwm.legend(loc="best", fontsize=7, ncol=4)
    ax_pwm.set_ylabel("motor command (us)")
    if bat is not None and any(bat["connected"]):
        ax_bat.plot(seconds(log, bat), bat["voltage_v"], lw=1.0, label="voltage (V)")
        ax_bat.set_ylabel("battery voltage (V)")
        ax_soc = ax_bat.twinx()
        ax_soc.plot(seconds(log, bat), [100 * r for r in bat["remaining"]], lw=1.0, color="tab:red")
        ax_soc.set_ylabel("remaining (%)", color="tab:red")
    else:
        ax_bat.text(0.5, 0.5, "no battery reading", ha="center", va="center", transform=ax_bat.transAxes)
    if weights is not None:
        tw = seconds(log, weights)
        for vector in ("w_t", "c_r"):
            for i, axis in enumerate("xyz" if vector == "c_r" else "ned"):
                ax_w.plot(tw, weights[f"{vector}[{i}]"], lw=0.9, label=f"{vector} {axis}")
        ax_w.legend(loc="best", fontsize=7, ncol=3)
        ax_w.set_ylabel("ACO LMS weights")
    else:
        ax_w.text(
            0.5, 0.5, "no aco_weights (not the ACO controller)", ha="center", va="center", transform=ax_w.transAxes
        )
    for ax in axes:
        ax.grid(True, alpha=0.3)
    ax_w.set_xlabel("time since arming (s, vehicle clock)")
    ax_pos.set_title(os.path.basename(args.ulog))
    png = args.png or os.path.splitext(args.ulog)[0] + ".png"
    save(fig, png)
    span = (pos["timestamp"][-1] - pos["timestamp"][0]) / 1e6 if len(pos["timestamp"]) else 0.0
    positions, texts = len(pos["timestamp"]), len(log.logged_messages)
    print(f"{positions} positions over {span:.1f} s of flight, {texts} logged messages: {png}")
    return 0


def main(argv=None):
    p = parser()
    return run_main(run, p.parse_args(argv), p.prog)


if __name__ == "__main__":
    sys.exit(main())
