"""Turns an autopilot ULog flight log into live-view frames (see `aco_gcs.view`), so `aco-view --ulog
FILE.ulg` (`sitl view FILE.ulg`) shows a flight like a live run. A ULog has no truth: it yields `vehicle`
frames (the estimate, the setpoints, the motors, the battery, the ACO weights, the mode) and `event` frames
(the logged messages), and the view draws the estimate where the truth would be.

Topics read (as the autopilot writes them, autopilot/src/runtime/flight_log/topics.rs):
`vehicle_local_position` (x, y, z; vx, vy, vz: one vehicle frame per record, 50 Hz), `vehicle_attitude` (q),
`vehicle_local_position_setpoint` (x, y, z), `vehicle_attitude_setpoint` (roll_body, pitch_body, yaw_body),
`actuator_outputs` (output[0..4]), `battery_status` (voltage_v, remaining), `aco_weights` (w_t, b_t, c_r,
d_r, mass_est, [3] each) and `vehicle_status` (nav_state -> mode, arming_state); each frame takes every
other topic's latest record at or before its time. The logged messages ('L') become events.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

# vehicle_status.nav_state -> the autopilot's mode names (px4_nav_state in topics.rs, FlightMode's Display).
NAV_STATE_MODE = {
    0: "Manual",
    1: "Altitude",
    2: "Position",
    3: "Mission",
    4: "Hold",
    5: "Return",
    10: "Acro",
    14: "Offboard",
    15: "Stabilized",
    17: "Takeoff",
    18: "Land",
}
# aco_weights' fields -> the controller's telemetry names (ACO_WEIGHTS in topics.rs).
ACO_TELEMETRY = {
    "w_t": ["aco.w_t_n", "aco.w_t_e", "aco.w_t_d"],
    "b_t": ["aco.b_t_n_mps2", "aco.b_t_e_mps2", "aco.b_t_d_mps2"],
    "c_r": ["aco.c_r_x", "aco.c_r_y", "aco.c_r_z"],
    "d_r": ["aco.d_r_x_radps2", "aco.d_r_y_radps2", "aco.d_r_z_radps2"],
    "mass_est": ["aco.mass_est_n_kg", "aco.mass_est_e_kg", "aco.mass_est_d_kg"],
}


def euler_of_quat(q: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (roll, pitch, yaw) of Hamilton [w, x, y, z] quaternions, one per row."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=1)


class _Topic:
    """One topic's records, looked up by time: the latest at or before t."""

    def __init__(self, data: dict[str, np.ndarray] | None) -> None:
        self.data = data
        self.t = data["timestamp"] if data is not None else np.zeros(0, dtype=np.uint64)

    def index(self, t: np.ndarray) -> np.ndarray:
        """For each time, the index of the latest record at or before it (-1: none yet)."""
        return np.searchsorted(self.t, t, side="right") - 1

    def cols(self, names: list[str]) -> np.ndarray | None:
        if self.data is None or any(n not in self.data for n in names):
            return None
        return np.stack([np.asarray(self.data[n], dtype=np.float64) for n in names], axis=1)


def _finite3(row: np.ndarray | None, i: int) -> list[float] | None:
    if row is None or i < 0:
        return None
    v = row[i]
    return [float(x) for x in v] if np.all(np.isfinite(v)) else None


def ulog_frames(path: Path | str, src: str = "v0") -> list[dict[str, Any]]:
    """The frames of a ULog file, in time order (a meta frame first)."""
    from pyulog import ULog

    log = ULog(str(path))
    topics = {d.name: d.data for d in log.data_list if d.multi_id == 0}
    pos_t = topics.get("vehicle_local_position")
    if pos_t is None:
        raise ValueError("the log has no vehicle_local_position")
    pos = _Topic(pos_t)
    att, sp, asp = (
        _Topic(topics.get(n))
        for n in ("vehicle_attitude", "vehicle_local_position_setpoint", "vehicle_attitude_setpoint")
    )
    out, bat, aco, status = (
        _Topic(topics.get(n)) for n in ("actuator_outputs", "battery_status", "aco_weights", "vehicle_status")
    )
    t = pos.t
    p, v = pos.cols(["x", "y", "z"]), pos.cols(["vx", "vy", "vz"])
    q = att.cols(["q[0]", "q[1]", "q[2]", "q[3]"])
    euler = euler_of_quat(q) if q is not None else None
    sp_xyz = sp.cols(["x", "y", "z"])
    sp_euler = asp.cols(["roll_body", "pitch_body", "yaw_body"])
    pwm = out.cols([f"output[{i}]" for i in range(4)])
    volts, remaining = bat.cols(["voltage_v"]), bat.cols(["remaining"])
    weights = {g: aco.cols([f"{g}[{i}]" for i in range(3)]) for g in ACO_TELEMETRY}
    nav, arming = status.cols(["nav_state"]), status.cols(["arming_state"])
    i_att, i_sp, i_asp, i_out = att.index(t), sp.index(t), asp.index(t), out.index(t)
    i_bat, i_aco, i_st = bat.index(t), aco.index(t), status.index(t)

    title = f"{Path(path).name} ({log.msg_info_dict.get('controller', 'ULog')})"
    frames: list[dict[str, Any]] = [{"kind": "meta", "src": src, "t_us": 0, "title": title, "sources": [src]}]
    for k in range(len(t)):
        telemetry: dict[str, float] = {}
        if i_aco[k] >= 0:
            for g, names in ACO_TELEMETRY.items():
                w = weights[g]
                if w is not None:
                    telemetry.update({n: float(x) for n, x in zip(names, w[i_aco[k]], strict=True) if math.isfinite(x)})
        volt = float(volts[i_bat[k], 0]) if volts is not None and i_bat[k] >= 0 else None
        rem = float(remaining[i_bat[k], 0]) if remaining is not None and i_bat[k] >= 0 else None
        nav_state = int(nav[i_st[k], 0]) if nav is not None and i_st[k] >= 0 else None
        frames.append(
            {
                "kind": "vehicle",
                "src": src,
                "t_us": int(t[k]),
                "armed": arming is not None and i_st[k] >= 0 and int(arming[i_st[k], 0]) == 2,
                "mode": NAV_STATE_MODE.get(nav_state, f"nav_state {nav_state}") if nav_state is not None else None,
                "pos_ned_m": _finite3(p, k),
                "vel_ned_mps": _finite3(v, k),
                "q_ned_frd": [float(x) for x in q[i_att[k]]] if q is not None and i_att[k] >= 0 else None,
                "euler_rad": _finite3(euler, int(i_att[k])),
                "sp_pos_ned_m": _finite3(sp_xyz, int(i_sp[k])),
                "sp_euler_rad": _finite3(sp_euler, int(i_asp[k])),
                "pwm_us": [float(x) for x in pwm[i_out[k]]] if pwm is not None and i_out[k] >= 0 else None,
                "battery_v": volt if volt is not None and volt > 0 else None,
                "battery_pct": rem * 100.0 if rem is not None and rem >= 0 else None,
                "telemetry": telemetry,
            }
        )
    for m in log.logged_messages:
        level = m.log_level - 48 if m.log_level >= 48 else m.log_level  # PX4 writes ASCII '0'..'7'
        frames.append(
            {
                "kind": "event",
                "src": src,
                "t_us": int(m.timestamp),
                "severity": min(max(level, 0), 7),
                "text": m.message,
            }
        )
    frames[1:] = sorted(frames[1:], key=lambda f: f["t_us"])
    return frames
