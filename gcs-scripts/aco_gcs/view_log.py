"""Turns the live-view frames (one JSON object each: `meta`, `truth`, `vehicle`, `ahead`, `plan`, `event`; see
`aco_gcs.view`) into Rerun logging calls, and builds the default blueprint.

Everything is logged on the `sim_time` timeline (the frame's `t_us` as a duration). Positions are NED metres
used as they are: `world` is declared RIGHT_HAND_Z_DOWN, so up is up on screen. Per source (`v0`, `aco`, ...):

- `world/<src>/truth`: the plant's pose (Transform3D) carrying a small quadrotor in the source's colour;
  `world/<src>/estimate`: the autopilot's estimate, a thinner translucent body tinted blue; `setpoint`,
  `ahead` (the trajectory ahead), `trail` (the last ~10 s flown, fading), `wind` (an arrow from the vehicle,
  length in m/s), `home`, `mission`, `fence`, `rally`.
- `plots/pos_err/<src>` (setpoint - truth, N/E/D), `plots/attitude/<src>/{truth,sp}` (deg),
  `plots/motors/<src>` (µs), `plots/battery/{volts,pct}/<src>`, `plots/aco/<w_t|b_t|c_r|d_r|mass_est>/<src>`,
  `plots/events/<src>` (each event's severity as a marker) and `events/<src>` (the event texts).

The high-rate data (poses, setpoints and every time series) is buffered and sent as columns
(`rr.send_columns`) at most every `flush_interval_s` of wall time, so one frame costs a few list appends
rather than a dozen `rr.log` calls; `flush()` sends what is buffered (call it when the input pauses or ends).
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from collections.abc import Sequence
from itertools import pairwise
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

# Source 0's truth is pure orange (the browser test looks for it); then distinct colours.
PALETTE: list[tuple[int, int, int]] = [
    (255, 128, 0),
    (0, 160, 255),
    (220, 0, 220),
    (0, 200, 120),
    (230, 200, 0),
    (255, 70, 90),
    (140, 110, 255),
    (120, 200, 255),
]
SETPOINT_GREEN = (0, 230, 0)
AHEAD_GREEN = (60, 220, 60)
MISSION_YELLOW = (240, 220, 0)
MISSION_CURRENT = (255, 255, 160)
FENCE_RED = (240, 30, 30)
RALLY_PURPLE = (170, 60, 255)
WIND_CYAN = (0, 230, 230)
HOME_WHITE = (255, 255, 255)

TRAIL_S = 10.0  # the trail's length, seconds of simulated time
TRAIL_SAMPLE_S = 0.1  # one trail point per this much simulated time
TRAIL_PERIOD_S = 0.25  # the trail and the wind arrow are re-logged this often (simulated time)
TRAIL_SEGMENTS = 10  # the trail is drawn as this many strips of growing opacity
ARM_M = 0.25  # the drawn quadrotor's arm length (centre to rotor)
ROTOR_M = 0.12  # and its rotor discs' radius
WINDOW_S = 20.0  # the time series' sliding window
ACO_GROUPS = ["w_t", "b_t", "c_r", "d_r", "mass_est"]
ACO_TITLES = {
    "w_t": "ACO w_t (translation weights)",
    "b_t": "ACO b_t (m/s²)",
    "c_r": "ACO c_r (rotation weights)",
    "d_r": "ACO d_r (rad/s²)",
    "mass_est": "ACO mass estimate (kg)",
}
SEVERITY_LEVEL = ["CRITICAL", "CRITICAL", "CRITICAL", "ERROR", "WARN", "INFO", "INFO", "DEBUG"]
MODE_SEVERITY = 6  # MAV_SEVERITY_INFO, for the synthesised mode-change events


def shade(rgb: Sequence[int], i: int) -> list[int]:
    """The i-th shade of a colour, to tell apart the series of one source: itself, darker, lighter, greyer."""
    r, g, b = rgb[:3]
    k = i % 4
    if k == 0:
        return [r, g, b]
    if k == 1:
        return [int(r * 0.55), int(g * 0.55), int(b * 0.55)]
    if k == 2:
        return [(r + 255) // 2, (g + 255) // 2, (b + 255) // 2]
    return [(r + 128) // 2, (g + 128) // 2, (b + 128) // 2]


def estimate_tint(rgb: Sequence[int]) -> list[int]:
    """The estimate's colour: the source's mixed half-and-half with blue, translucent."""
    return [(rgb[0] + 60) // 2, (rgb[1] + 130) // 2, (rgb[2] + 255) // 2, 150]


def circle_ne(n: float, e: float, r: float, d: float, steps: int = 48) -> list[list[float]]:
    """A closed polyline of the circle of radius r around (n, e) at down-coordinate d."""
    return [
        [n + r * math.cos(2 * math.pi * k / steps), e + r * math.sin(2 * math.pi * k / steps), d]
        for k in range(steps + 1)
    ]


def _vec3(v: Any) -> list[float] | None:
    """v as three finite floats, or None (null, wrong length, NaN)."""
    if not isinstance(v, list | tuple) or len(v) != 3:
        return None
    try:
        out = [float(x) for x in v]
    except (TypeError, ValueError):
        return None
    return out if all(math.isfinite(x) for x in out) else None


def _quat(v: Any) -> list[float] | None:
    """A Hamilton [w, x, y, z] as Rerun's [x, y, z, w], or None."""
    if not isinstance(v, list | tuple) or len(v) != 4:
        return None
    try:
        w, x, y, z = (float(c) for c in v)
    except (TypeError, ValueError):
        return None
    return [x, y, z, w] if all(math.isfinite(c) for c in (w, x, y, z)) else None


def _num(v: Any) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) else None


class _Columns:
    """Rows of one entity buffered for `rr.send_columns`: times and fixed-width float rows."""

    __slots__ = ("kind", "rows", "times")

    def __init__(self, kind: str) -> None:
        self.kind = kind  # "scalars", "transform" (translation + quaternion), "point"
        self.times: list[float] = []
        self.rows: list[list[float]] = []


class FrameLogger:
    """Logs frames to the current Rerun recording. `estimate_only` (a ULog, which has no truth): the
    estimate is drawn and plotted where the truth would be (full colour body, trail, position error).
    """

    def __init__(
        self,
        *,
        estimate_only: bool = False,
        flush_interval_s: float = 0.2,
    ) -> None:
        self.estimate_only = estimate_only
        self.flush_interval_s = flush_interval_s
        self.sources: dict[str, int] = {}
        self.malformed = 0
        self.frames = 0
        self._buf: dict[str, _Columns] = {}
        self._last_flush = time.monotonic()
        self._truth_pos: dict[str, list[float]] = {}
        self._trail: dict[str, deque[tuple[float, list[float]]]] = {}
        self._trail_logged: dict[str, float] = {}
        self._wind: dict[str, list[float]] = {}
        self._mode: dict[str, str] = {}
        self._plans: dict[str, Any] = {}
        self._styled: set[str] = set()
        rr.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)

    # --- input -----------------------------------------------------------------------------------------

    def handle_line(self, line: bytes | str) -> None:
        """One line of the stream; a malformed one is counted (and reported on stderr the first time)."""
        import json

        if not line.strip():
            return
        try:
            frame = json.loads(line)
            if not isinstance(frame, dict):
                raise ValueError("not a JSON object")
            self.handle(frame)
        except (ValueError, TypeError, KeyError, IndexError) as e:
            self.malformed += 1
            if self.malformed == 1:
                text = line if isinstance(line, str) else line.decode("utf-8", "replace")
                print(f"aco-view: skipping a malformed frame ({e}): {text.strip()[:120]}", file=sys.stderr)

    def handle(self, frame: dict[str, Any]) -> None:
        """One frame; unknown kinds and fields are ignored."""
        kind = frame.get("kind")
        src = frame.get("src")
        if not isinstance(src, str) or not src:
            src = "v0"
        if kind == "meta":
            self._meta(frame)
            return
        handler = _HANDLERS.get(kind) if isinstance(kind, str) else None
        if handler is None:
            return
        t = int(frame["t_us"]) / 1e6
        self.frames += 1
        self._source(src)
        handler(self, src, t, frame)
        if time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()

    def flush(self) -> None:
        """Sends every buffered column."""
        self._last_flush = time.monotonic()
        for path, col in self._buf.items():
            if not col.times:
                continue
            index = [rr.TimeColumn("sim_time", duration=col.times)]
            rows = np.asarray(col.rows, dtype=np.float64)
            if col.kind == "scalars":
                width = rows.shape[1]
                columns: Any = rr.Scalars.columns(scalars=rows.reshape(-1))
                if width > 1:
                    columns = columns.partition([width] * len(col.times))
            elif col.kind == "transform":
                columns = rr.Transform3D.columns(translation=rows[:, :3], quaternion=rows[:, 3:])
            else:
                columns = rr.Points3D.columns(positions=rows)
            rr.send_columns(path, indexes=index, columns=columns)
            col.times.clear()
            col.rows.clear()

    # --- buffered rows -----------------------------------------------------------------------------------

    def _row(self, path: str, kind: str, t: float, row: list[float]) -> None:
        col = self._buf.get(path)
        if col is None:
            col = self._buf[path] = _Columns(kind)
        elif col.rows and len(col.rows[0]) != len(row):
            self.flush()  # the width changed (another telemetry set): send what we have first
        col.times.append(t)
        col.rows.append(row)

    def _series(self, path: str, src: str, names: list[str], width: float = 2.0) -> None:
        """The static style of a time series: the source's shades, named."""
        if path in self._styled:
            return
        self._styled.add(path)
        colors = [shade(self.color(src), i) for i in range(len(names))]
        rr.log(path, rr.SeriesLines(colors=colors, names=names, widths=[width] * len(names)), static=True)

    # --- sources ---------------------------------------------------------------------------------------

    def color(self, src: str) -> tuple[int, int, int]:
        return PALETTE[self._source(src) % len(PALETTE)]

    def _source(self, src: str) -> int:
        index = self.sources.get(src)
        if index is None:
            index = self.sources[src] = len(self.sources)
            self._draw_bodies(src)
        return index

    def _draw_bodies(self, src: str) -> None:
        """The static quadrotor geometry under the truth and the estimate transforms (FRD body axes)."""
        c = list(self.color(src))
        a = ARM_M / math.sqrt(2.0)
        rotors = [[a, a, -0.03], [-a, -a, -0.03], [a, -a, -0.03], [-a, a, -0.03]]
        arms = [[[a, a, 0.0], [-a, -a, 0.0]], [[a, -a, 0.0], [-a, a, 0.0]]]
        nose = [[[0.0, 0.0, 0.0], [ARM_M * 1.1, 0.0, 0.0]]]
        # Without a truth (a ULog) the estimate is the full-colour body.
        bodies = [("estimate" if self.estimate_only else "truth", c, 0.025, 1.0)]
        if not self.estimate_only:
            bodies.append(("estimate", estimate_tint(c), 0.01, 0.8))
        for name, color, width, scale in bodies:
            base = f"world/{src}/{name}"
            rr.log(f"{base}/arms", rr.LineStrips3D(arms, radii=width, colors=[color]), static=True)
            rr.log(f"{base}/nose", rr.LineStrips3D(nose, radii=width * 0.8, colors=[shade(c, 2)]), static=True)
            rr.log(
                f"{base}/rotors",
                rr.Cylinders3D(
                    lengths=[0.02] * 4,
                    radii=[ROTOR_M * scale] * 4,
                    centers=rotors,
                    colors=[color] * 4,
                    fill_mode=rr.components.FillMode.Solid
                    if width == bodies[0][2]
                    else rr.components.FillMode.MajorWireframe,
                ),
                static=True,
            )
            rr.log(f"{base}/hub", rr.Points3D([[0.0, 0.0, 0.0]], radii=width * 2.5, colors=[color]), static=True)
        label = rr.Points3D.from_fields(radii=0.05, colors=[SETPOINT_GREEN])
        rr.log(f"world/{src}/setpoint", label, static=True)
        rr.log(
            f"plots/events/{src}", rr.SeriesPoints(colors=[c], names=[f"{src} event"], markers="diamond"), static=True
        )
        rr.log(f"plots/events/{src}", rr.SeriesPoints(marker_sizes=[6.0]), static=True)

    # --- frames ------------------------------------------------------------------------------------------

    def _meta(self, frame: dict[str, Any]) -> None:
        sources = frame.get("sources")
        if isinstance(sources, list):
            for s in sources:
                if isinstance(s, str) and s:
                    self._source(s)
        title = frame.get("title")
        if isinstance(title, str) and title:
            rr.send_recording_name(title)

    def _pose(self, src: str, t: float, body: str, pos: list[float] | None, q: list[float] | None) -> None:
        if pos is not None and q is not None:
            self._row(f"world/{src}/{body}", "transform", t, pos + q)

    def _track(self, src: str, t: float, pos: list[float] | None, euler: list[float] | None) -> None:
        """The truth (or, estimate_only, the estimate): trail, wind arrow, attitude plot."""
        if pos is not None:
            self._truth_pos[src] = pos
            trail = self._trail.setdefault(src, deque())
            if not trail or t - trail[-1][0] >= TRAIL_SAMPLE_S or t < trail[-1][0]:
                if trail and t < trail[-1][0]:
                    trail.clear()  # time went back (a new run)
                trail.append((t, pos))
                while trail and t - trail[0][0] > TRAIL_S:
                    trail.popleft()
            last = self._trail_logged.get(src)
            if last is None or t - last >= TRAIL_PERIOD_S or t < last:
                self._trail_logged[src] = t
                self._log_trail(src, t)
        if euler is not None:
            what = "est" if self.estimate_only else "truth"
            path = f"plots/attitude/{src}/{what}"
            self._series(path, src, [f"{src} roll {what}", f"{src} pitch {what}", f"{src} yaw {what}"])
            self._row(path, "scalars", t, [math.degrees(x) for x in euler])

    def _log_trail(self, src: str, t: float) -> None:
        trail = self._trail[src]
        pts = [p for _, p in trail]
        rr.set_time("sim_time", duration=t)
        if len(pts) >= 2:
            n = len(pts)
            cuts = sorted({round(i * (n - 1) / TRAIL_SEGMENTS) for i in range(TRAIL_SEGMENTS + 1)})
            strips = [pts[a : b + 1] for a, b in pairwise(cuts) if b > a]
            c = self.color(src)
            colors = [[c[0], c[1], c[2], int(255 * (i + 1) / len(strips))] for i in range(len(strips))]
            rr.log(f"world/{src}/trail", rr.LineStrips3D(strips, radii=0.015, colors=colors))
        wind = self._wind.get(src)
        pos = self._truth_pos.get(src)
        if wind is not None and pos is not None:
            rr.log(f"world/{src}/wind", rr.Arrows3D(vectors=[wind], origins=[pos], radii=0.02, colors=[WIND_CYAN]))

    def _truth(self, src: str, t: float, f: dict[str, Any]) -> None:
        pos = _vec3(f.get("pos_ned_m"))
        self._pose(src, t, "truth", pos, _quat(f.get("q_ned_frd")))
        wind = _vec3(f.get("wind_ned_mps"))
        if wind is not None:
            self._wind[src] = wind
        self._track(src, t, pos, _vec3(f.get("euler_rad")))

    def _vehicle(self, src: str, t: float, f: dict[str, Any]) -> None:
        pos = _vec3(f.get("pos_ned_m"))
        euler = _vec3(f.get("euler_rad"))
        self._pose(src, t, "estimate", pos, _quat(f.get("q_ned_frd")))
        if self.estimate_only:
            self._track(src, t, pos, euler)
        sp = _vec3(f.get("sp_pos_ned_m"))
        if sp is not None:
            self._row(f"world/{src}/setpoint", "point", t, sp)
            truth = self._truth_pos.get(src)
            if truth is not None:
                path = f"plots/pos_err/{src}"
                self._series(path, src, [f"{src} N", f"{src} E", f"{src} D"])
                self._row(path, "scalars", t, [sp[0] - truth[0], sp[1] - truth[1], sp[2] - truth[2]])
        sp_euler = _vec3(f.get("sp_euler_rad"))
        if sp_euler is not None:
            path = f"plots/attitude/{src}/sp"
            self._series(path, src, [f"{src} roll sp", f"{src} pitch sp", f"{src} yaw sp"], width=1.0)
            self._row(path, "scalars", t, [math.degrees(x) for x in sp_euler])
        pwm = f.get("pwm_us")
        if isinstance(pwm, list) and len(pwm) >= 4 and all(_num(x) is not None for x in pwm[:4]):
            path = f"plots/motors/{src}"
            self._series(path, src, [f"{src} m{i + 1}" for i in range(4)])
            self._row(path, "scalars", t, [float(x) for x in pwm[:4]])
        for key, name in (("battery_v", "volts"), ("battery_pct", "pct")):
            value = _num(f.get(key))
            if value is not None:
                path = f"plots/battery/{name}/{src}"
                self._series(path, src, [f"{src} {'V' if name == 'volts' else '%'}"])
                self._row(path, "scalars", t, [value])
        telemetry = f.get("telemetry")
        if isinstance(telemetry, dict):
            self._aco(src, t, telemetry)
        mode = f.get("mode")
        if isinstance(mode, str) and mode != self._mode.get(src):
            old = self._mode.get(src)
            self._mode[src] = mode
            text = f"mode {mode}" if old is None else f"mode {old} -> {mode}"
            self._log_event(src, t, MODE_SEVERITY, text)

    def _aco(self, src: str, t: float, telemetry: dict[str, Any]) -> None:
        groups: dict[str, tuple[list[str], list[float]]] = {}
        for name, value in telemetry.items():
            if not name.startswith("aco."):
                continue
            v = _num(value)
            for g in ACO_GROUPS:
                if name.startswith(f"aco.{g}_") and v is not None:
                    names, values = groups.setdefault(g, ([], []))
                    names.append(name[len(g) + 5 :])
                    values.append(v)
                    break
        for g, (names, values) in groups.items():
            path = f"plots/aco/{g}/{src}"
            self._series(path, src, [f"{src} {n}" for n in names])
            self._row(path, "scalars", t, values)

    def _ahead(self, src: str, t: float, f: dict[str, Any]) -> None:
        pts = f.get("points_ned_m")
        good = [p for p in (_vec3(x) for x in pts) if p is not None] if isinstance(pts, list) else []
        rr.set_time("sim_time", duration=t)
        path = f"world/{src}/ahead"
        if len(good) >= 2:
            rr.log(path, rr.LineStrips3D([good], radii=0.012, colors=[AHEAD_GREEN]))
        else:
            rr.log(path, rr.Clear(recursive=False))

    def _plan(self, src: str, t: float, f: dict[str, Any]) -> None:
        keys = (
            "home_ned_m",
            "mission_ned_m",
            "mission_current",
            "fence_polygons_ne_m",
            "fence_circles_ne_m",
            "fence_max_alt_m",
            "rally_ned_m",
        )
        plan = {k: f.get(k) for k in keys}
        if self._plans.get(src) == plan:
            return
        self._plans[src] = plan
        rr.set_time("sim_time", duration=t)
        base = f"world/{src}"
        color = list(self.color(src))

        def points(v: Any) -> list[list[float]]:
            return [p for p in (_vec3(x) for x in v) if p is not None] if isinstance(v, list) else []

        home = _vec3(plan["home_ned_m"])
        if home is not None:
            rr.log(f"{base}/home", rr.Points3D([home], radii=0.12, colors=[HOME_WHITE], labels=[f"{src} home"]))
            rr.log(f"{base}/home/mast", rr.LineStrips3D([[home, [home[0], home[1], home[2] - 1.0]]], colors=[color]))
        else:
            rr.log(f"{base}/home", rr.Clear(recursive=True))
        mission = points(plan["mission_ned_m"])
        current = plan["mission_current"]
        if mission:
            rr.log(f"{base}/mission/items", rr.Points3D(mission, radii=0.08, colors=[MISSION_YELLOW]))
            rr.log(f"{base}/mission/path", rr.LineStrips3D([mission], radii=0.008, colors=[MISSION_YELLOW]))
            if isinstance(current, int) and 0 <= current < len(mission):
                rr.log(
                    f"{base}/mission/current",
                    rr.Points3D([mission[current]], radii=0.16, colors=[MISSION_CURRENT], labels=[f"#{current}"]),
                )
            else:
                rr.log(f"{base}/mission/current", rr.Clear(recursive=False))
        else:
            rr.log(f"{base}/mission", rr.Clear(recursive=True))
        self._fence(base, plan)
        rally = points(plan["rally_ned_m"])
        if rally:
            rr.log(f"{base}/rally", rr.Points3D(rally, radii=0.1, colors=[RALLY_PURPLE]))
        else:
            rr.log(f"{base}/rally", rr.Clear(recursive=False))

    def _fence(self, base: str, plan: dict[str, Any]) -> None:
        max_alt = _num(plan["fence_max_alt_m"])
        levels = [0.0] if max_alt is None else [0.0, -max_alt]
        strips: list[list[list[float]]] = []
        polygons = plan["fence_polygons_ne_m"] if isinstance(plan["fence_polygons_ne_m"], list) else []
        for poly in polygons:
            if not isinstance(poly, list):
                continue
            ne = [[float(p[0]), float(p[1])] for p in poly if isinstance(p, list) and len(p) >= 2]
            if len(ne) >= 2:
                for d in levels:
                    strips.append([[n, e, d] for n, e in [*ne, ne[0]]])
        circles = plan["fence_circles_ne_m"] if isinstance(plan["fence_circles_ne_m"], list) else []
        for c in circles:
            if isinstance(c, list) and len(c) >= 3:
                for d in levels:
                    strips.append(circle_ne(float(c[0]), float(c[1]), float(c[2]), d))
        if strips:
            rr.log(f"{base}/fence", rr.LineStrips3D(strips, radii=0.02, colors=[FENCE_RED]))
        else:
            rr.log(f"{base}/fence", rr.Clear(recursive=False))

    def _event(self, src: str, t: float, f: dict[str, Any]) -> None:
        sev = f.get("severity")
        severity = sev if isinstance(sev, int) and 0 <= sev <= 7 else 6
        text = f.get("text")
        self._log_event(src, t, severity, text if isinstance(text, str) else str(text))

    def _log_event(self, src: str, t: float, severity: int, text: str) -> None:
        rr.set_time("sim_time", duration=t)
        rr.log(f"events/{src}", rr.TextLog(f"[{src}] {text}", level=SEVERITY_LEVEL[severity]))
        rr.log(f"plots/events/{src}", rr.Scalars(float(severity)))


_HANDLERS = {
    "truth": FrameLogger._truth,
    "vehicle": FrameLogger._vehicle,
    "ahead": FrameLogger._ahead,
    "plan": FrameLogger._plan,
    "event": FrameLogger._event,
}


def blueprint() -> rrb.Blueprint:
    """The default layout: the 3D world big on the left; on the right the position error, attitude and
    motors one above the other, then tabs (battery, ACO weights, event markers) beside the event log. The
    time series follow the live time over the last WINDOW_S seconds. The 3D camera starts a few metres from
    the start point, looking at it (fitting the whole scene would make the vehicle a few pixels next to a
    geofence or a mission at their real scale)."""
    window = rrb.VisibleTimeRange(
        "sim_time",
        start=rrb.TimeRangeBoundary.cursor_relative(seconds=-WINDOW_S),
        end=rrb.TimeRangeBoundary.cursor_relative(seconds=0.0),
    )

    def plot(name: str, origin: str) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(origin=origin, name=name, time_ranges=[window], plot_legend=rrb.Corner2D.LeftTop)

    tabs = rrb.Tabs(
        plot("Battery (V)", "plots/battery/volts"),
        plot("Battery (%)", "plots/battery/pct"),
        *[plot(ACO_TITLES[g], f"plots/aco/{g}") for g in ACO_GROUPS],
        plot("Events (severity)", "plots/events"),
    )
    right = rrb.Vertical(
        plot("Position error: setpoint - truth (m)", "plots/pos_err"),
        plot("Attitude (deg): truth and setpoint", "plots/attitude"),
        plot("Motors (µs)", "plots/motors"),
        rrb.Horizontal(tabs, rrb.TextLogView(origin="events", name="Events"), column_shares=[3, 2]),
        row_shares=[1, 1, 1, 1],
    )
    eye = rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital, position=[-4.5, -3.0, -3.5], look_target=[0.0, 0.0, -1.5], eye_up=[0.0, 0.0, -1.0]
    )
    world = rrb.Spatial3DView(origin="world", name="3D (NED, up is up)", eye_controls=eye)
    return rrb.Blueprint(rrb.Horizontal(world, right, column_shares=[3, 2]), collapse_panels=True)
