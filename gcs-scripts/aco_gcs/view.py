"""The live-view bridge into Rerun: `python -m aco_gcs.view` (`aco-view`) reads the simulator's frames
(newline-delimited JSON on stdin, as `sitl run --view` writes them) or an autopilot ULog (`--ulog FILE.ulg`,
as `sitl view FILE.ulg` passes it), logs them to Rerun with a default blueprint (3D world, time plots,
event log; see `aco_gcs.view_log`), and shows them in the web viewer or the native one, optionally
recording everything to an .rrd.

Frames (one JSON object a line; unknown kinds and fields are ignored, a malformed line is counted and
reported once on stderr): every frame has `kind`, `src` (the vehicle or run: `v0`, `aco`, ...) and `t_us`
(simulated time, µs). Kinds: `meta` (title, sources, rate_hz), `truth` (the plant: pos_ned_m, q_ned_frd,
vel_ned_mps, euler_rad, wind_ned_mps), `vehicle` (the autopilot: armed, mode, the estimate, sp_pos_ned_m,
sp_euler_rad, pwm_us, battery_v, battery_pct, telemetry), `ahead` (points_ned_m), `plan` (home, mission,
geofence, rally) and `event` (severity, text). Positions are NED metres from the plant's start point;
quaternions Hamilton [w, x, y, z], body FRD -> NED.

A ULog has no truth: the 3D view and the plots show the estimate where the truth would be (the position
error is setpoint - estimate).

Viewer: `--web` serves the web viewer (prints its URL), `--native` spawns the native viewer, `--no-viewer`
only records; the default is native when $DISPLAY or $WAYLAND_DISPLAY is set, else web. Once the sinks are up
it prints `ready <url-or-path>` on stdout. At the end of the input it keeps serving the web viewer until
Ctrl-C (unless `--exit-at-eof`). `--record FILE.rrd` is written as FILE.rrd.tmp and renamed when the
bridge ends cleanly (end of input, SIGINT or SIGTERM). Exit status: 0, or 2 when Rerun is not installed or
the arguments are wrong.
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import sys
import time
import urllib.parse
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from aco_gcs.view_log import FrameLogger

INSTALL_HINT = (
    "aco-view needs the Rerun SDK: pip install 'rerun-sdk[catalog]==0.41.0' "
    "(or the whole venv: pip install -r gcs-scripts/requirements.txt, as scripts/test sets it up)"
)
IDLE_FLUSH_S = 0.1  # send the buffered rows when the input pauses this long
STOP_DRAIN_S = 0.5  # after SIGINT or SIGTERM: keep reading while lines still come this often


class StopFlag:
    """SIGTERM or SIGINT: finish the recording and exit. The handler only records the signal; the loops look
    at it. An exception raised from the handler would land in whatever code runs at that moment, and Rerun's
    logging calls catch every `Exception` and turn it into a warning, so a Ctrl-C inside `rr.log` was lost
    (the bridge then served on, and its recording was never finalized)."""

    def __init__(self) -> None:
        self.signal: str | None = None

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        if self.signal is None:
            self.signal = signal.Signals(signum).name


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog="aco-view", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--ulog", type=Path, help="show this ULog flight log (else: frames from stdin)")
    viewer = p.add_mutually_exclusive_group()
    viewer.add_argument(
        "--auto",
        dest="viewer",
        action="store_const",
        const="auto",
        help="the native viewer when there is a display ($DISPLAY or $WAYLAND_DISPLAY), else the web viewer (default)",
    )
    viewer.add_argument("--web", dest="viewer", action="store_const", const="web", help="serve the web viewer")
    viewer.add_argument("--native", dest="viewer", action="store_const", const="native", help="spawn `rerun`")
    viewer.add_argument("--no-viewer", dest="viewer", action="store_const", const="none", help="record only")
    p.set_defaults(viewer="auto")
    p.add_argument("--web-port", type=int, default=9090, help="the web viewer's HTTP port (default 9090)")
    p.add_argument("--grpc-port", type=int, default=9876, help="the gRPC port the viewer reads from (default 9876)")
    p.add_argument("--record", type=Path, help="also save everything to this .rrd")
    p.add_argument("--exit-at-eof", action="store_true", help="exit at the end of the input even when serving")
    p.add_argument("--title", default="aco", help="the recording's application id (default aco)")
    args = p.parse_args(argv)
    if args.viewer == "auto":
        args.viewer = "native" if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") else "web"
    if args.viewer == "none" and args.record is None:
        p.error("--no-viewer needs --record FILE.rrd (there is nothing else to do)")
    return args


def read_stdin(logger: FrameLogger, stop: StopFlag) -> None:
    """Feeds stdin's lines to the logger until EOF; sends the buffered rows whenever the input pauses. Once
    `stop` has a signal: only what arrives within STOP_DRAIN_S of the last line (the stream's writer stops
    with us, Ctrl-C reaches the whole process group), then returns."""
    fd = sys.stdin.fileno()
    pending = b""
    while True:
        stopping = stop.signal is not None
        ready, _, _ = select.select([fd], [], [], STOP_DRAIN_S if stopping else IDLE_FLUSH_S)
        if not ready:
            logger.flush()
            if stopping:
                break
            continue
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            break
        lines = (pending + chunk).split(b"\n")
        pending = lines.pop()
        for line in lines:
            logger.handle_line(line)
    if pending.strip():
        logger.handle_line(pending)
    logger.flush()


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        import rerun as rr
    except ImportError as e:
        print(f"aco-view: cannot import rerun ({e}). {INSTALL_HINT}", file=sys.stderr)
        return 2
    from aco_gcs.view_log import FrameLogger, blueprint

    frames = None
    if args.ulog is not None:
        from aco_gcs.view_ulog import ulog_frames

        try:
            frames = ulog_frames(args.ulog)
        except (OSError, ValueError, IndexError) as e:
            print(f"aco-view: cannot read the ULog {args.ulog}: {e}", file=sys.stderr)
            return 2

    stop = StopFlag()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    rr.init(args.title, spawn=False)
    bp = blueprint()
    sinks: list[rr.FileSink | rr.GrpcServerSink | rr.GrpcSink] = []
    tmp = final = None
    if args.record is not None:
        final = args.record
        tmp = final.with_name(final.name + ".tmp")
        sinks.append(rr.FileSink(str(tmp)))
    uri = f"rerun+http://127.0.0.1:{args.grpc_port}/proxy"
    where = str(final)
    clean = False  # the recording gets its final name only when the bridge ends cleanly
    try:
        if args.viewer == "web":
            sinks.append(rr.GrpcServerSink(bind_ip="127.0.0.1", port=args.grpc_port))
            rr.set_sinks(*sinks, default_blueprint=bp)
            rr.serve_web_viewer(web_port=args.web_port, open_browser=False, connect_to=uri)
            where = f"http://127.0.0.1:{args.web_port}/?url={urllib.parse.quote(uri, safe='')}"
        elif args.viewer == "native":
            rr.spawn(port=args.grpc_port, connect=False)
            sinks.append(rr.GrpcSink(uri))
            rr.set_sinks(*sinks, default_blueprint=bp)
            where = uri
        else:
            rr.set_sinks(*sinks, default_blueprint=bp)
        print(f"ready {where}", flush=True)
        if args.viewer != "none":
            print(f"aco-view: the view is at {where}", file=sys.stderr, flush=True)

        logger = FrameLogger(estimate_only=frames is not None)
        start = time.process_time()
        if frames is not None:
            for frame in frames:
                if stop.signal is not None:
                    break
                logger.handle(frame)
            logger.flush()
        else:
            read_stdin(logger, stop)
        cpu = time.process_time() - start
        note = f", {logger.malformed} malformed line(s) skipped" if logger.malformed else ""
        ended = "end of input" if stop.signal is None else f"{stop.signal}, the input read"
        print(f"aco-view: {ended}: {logger.frames} frames in {cpu:.2f} s of CPU{note}", file=sys.stderr)
        if args.viewer == "web" and not args.exit_at_eof and stop.signal is None:
            print(f"aco-view: the run ended; the view stays at {where} until Ctrl-C", file=sys.stderr, flush=True)
            while stop.signal is None:
                time.sleep(0.1)
        if stop.signal is not None:
            print(f"aco-view: {stop.signal}: finishing", file=sys.stderr)
        clean = True
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        finish(tmp if clean else None, final)
    return 0


def finish(tmp: Path | None, final: Path | None) -> None:
    """Flushes every sink and closes them (the file gets its footer), then gives the recording its final
    name (`tmp` None: an unclean end, which leaves the .tmp file)."""
    import rerun

    rec = rerun.get_global_data_recording()
    if rec is not None:
        rec.flush()
    rerun.disconnect()
    if tmp is not None and final is not None and tmp.exists():
        tmp.replace(final)
        print(f"aco-view: recorded {final}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
