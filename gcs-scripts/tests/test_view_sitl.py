"""The live view of the real binaries: `sitl run --view web` flown with pymavlink through a gust and looked at
in headless Chromium (the vehicle's orange body in the 3D panel, plots whose time axis moves on); `sitl run
--view web --record` still paced at 1.00 +- 0.02 of the wall clock over its first 10 s, as
sitl/tests/e2e_sitl_run.rs measures it without the view; and `sitl scenario --record` opened by Rerun's own
reader with every 50 Hz sample of each controller's truth pose, setpoint and motors, equal to the CSV
trace of the same run."""

import csv
import os
import re
import signal
import socket
import subprocess
import time

import pytest
from sitl_harness import binary, connect, free_instance, start_sitl
from test_view import read_rrd, samples
from view_browser import check_live_view

from aco_gcs import flight
from aco_gcs.link import Params, Plant, api_port, mavutil

PACING_WINDOW_S = 10.0
PACING_TOLERANCE = 0.02


def free_tcp_ports(count):
    """`count` TCP ports on loopback that nothing holds now."""
    socks = [socket.socket() for _ in range(count)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def view_url(sitl, timeout_s=90.0):
    """The web viewer's address, from the line `sitl run --view` prints once its view is up."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        m = re.search(r"sitl: the view of instance \d+: (http://\S+)", sitl.log_path.read_text())
        if m:
            return m.group(1)
        if sitl.proc.poll() is not None:
            pytest.fail(f"sitl run --view exited ({sitl.proc.returncode}): {sitl.log_tail()}")
        time.sleep(0.2)
    pytest.fail(f"no view address within {timeout_s:g} s: {sitl.log_tail()}")


def test_sitl_run_view_in_chromium_shows_the_vehicle_in_a_gust_and_plots_that_move_on(tmp_path):
    web, grpc = free_tcp_ports(2)
    sitl = start_sitl(tmp_path, "--view", "web", "--view-web-port", str(web), "--view-grpc-port", str(grpc), speed=1)
    try:
        url = view_url(sitl)
        assert url.startswith(f"http://127.0.0.1:{web}/"), url
        vehicle = connect(sitl)
        ground, _ = flight.wait_ready(vehicle, 60.0)
        flight.takeoff(vehicle, 3.0, ground, climb_s=30.0)
        plant = Plant(sitl.instance, 60.0)
        plant.hello()
        sim = Params(plant, plant.component)
        sim.require_set("SIM_GUST_SPD", 6.7)
        sim.require_set("SIM_GUST_DIR", 90.0)
        sim.require_set("SIM_GUST_ON", 1)
        flight.hold(vehicle, 3.0)
        seen = check_live_view(url, tmp_path / "shots", timeout_s=120.0, airborne=True)
        print(
            f"live view: orange blob {seen.orange_px} px; in 2 s {seen.plot_changed_px} plot px and "
            f"{seen.tick_labels_changed_px} tick-label px changed ({seen.a}, {seen.b})"
        )
    finally:
        sitl.stop()
    assert "the view of instance" in sitl.log_path.read_text()


def vehicle_over_wall(samples_at, window_s):
    """Vehicle time over wall time across `window_s` from the first (arrival s, time_boot_ms) sample, each end
    the sample that arrived earliest for its vehicle time among the window's first and last 250 ms (as
    sitl/tests/e2e_sitl_run.rs measures it)."""
    t0 = samples_at[0][0]
    edge = 0.25

    def offset(s):
        return (s[0] - t0) - s[1] * 1e-3

    window = [s for s in samples_at if s[0] - t0 <= window_s]
    start = min((s for s in window if s[0] - t0 <= edge), key=offset)
    ends = [s for s in window if s[0] - t0 + edge >= window_s]
    end = min(ends, key=offset) if ends else (t0 + window_s, max(s[1] for s in window))
    return (end[1] - start[1]) * 1e-3 / (end[0] - start[0])


def test_sitl_run_with_the_view_and_a_recording_keeps_vehicle_time_within_2_percent_of_wall_time(tmp_path):
    web, grpc = free_tcp_ports(2)
    rrd = tmp_path / "live.rrd"
    listen = None
    sitl = None
    try:
        n = free_instance()
        listen = mavutil.mavlink_connection(f"udpin:127.0.0.1:{api_port(n)}", source_system=255)
        sitl = start_sitl(
            tmp_path,
            *("--view", "web", "--view-web-port", str(web), "--view-grpc-port", str(grpc), "--record", str(rrd)),
            speed=1,
            instance=n,
        )
        got: list[tuple[float, int]] = []
        spawned = time.monotonic()
        while not got or time.monotonic() - got[0][0] < PACING_WINDOW_S + 0.1:
            assert time.monotonic() - spawned < 180, f"no vehicle clock: {sitl.log_tail()}"
            msg = listen.recv_match(type=["ATTITUDE", "LOCAL_POSITION_NED", "SYSTEM_TIME"], blocking=True, timeout=0.1)
            if msg is not None and msg.get_srcSystem() == n + 1:
                got.append((time.monotonic(), msg.time_boot_ms))
    finally:
        if sitl is not None:
            sitl.stop()
        if listen is not None:
            listen.close()
    ratio = vehicle_over_wall(got, PACING_WINDOW_S)
    print(f"pacing with the view and a recording: vehicle time / wall time {ratio:.4f} over {PACING_WINDOW_S:g} s")
    assert got[0][1] < 1000, f"the first message is {got[0][1]} ms into the vehicle's clock"
    assert abs(ratio - 1.0) <= PACING_TOLERANCE, f"{ratio:.4f} outside 1 +- {PACING_TOLERANCE}"
    log = sitl.log_path.read_text()
    assert "the view of instance" in log and "the view fell behind" not in log, log[-2000:]
    assert rrd.exists(), f"the recording was not finalized: {log[-2000:]}"


def test_a_scenario_recording_holds_every_sample_of_each_controller_as_its_trace_has_it(tmp_path):
    rrd = tmp_path / "gust.rrd"
    out = tmp_path / "out"
    run = subprocess.run(
        [str(binary("sitl")), "scenario", "gust-hover", "--record", str(rrd), "--no-plots", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    table = read_rrd(rrd)
    duration_s, rate_hz = 30.0, 50
    n = int(duration_s * rate_hz)
    times = table.column("sim_time").to_pylist()
    for controller in ("aco", "ca", "pid"):
        assert samples(table, f"/world/{controller}/truth:Transform3D:translation") == n, controller
        assert samples(table, f"/world/{controller}/truth:Transform3D:quaternion") == n, controller
        assert samples(table, f"/world/{controller}/setpoint:Points3D:positions") == n, controller
        motors = table.column(f"/plots/motors/{controller}:Scalars:scalars").drop_null().to_pylist()
        assert len(motors) == n and all(len(m) == 4 for m in motors), controller
        # The truth in the recording is the run's: the CSV trace (50 Hz, the same instants) to float32.
        (trace,) = (out / "gust-hover").glob(f"{controller}_*.csv")
        rows = list(csv.DictReader(trace.open()))

        def at_time(column):
            values = table.column(column).to_pylist()
            return {round(t.total_seconds() * 1e6): v[0] for t, v in zip(times, values, strict=True) if v is not None}

        truth = at_time(f"/world/{controller}/truth:Transform3D:translation")
        setpoint = at_time(f"/world/{controller}/setpoint:Points3D:positions")
        assert len(rows) == n, (controller, len(rows))
        for row in rows[:: n // 50]:
            t_us = round(float(row["t"]) * 1e6)
            want = [float(row[c]) for c in ("pN", "pE", "pD")]
            assert truth[t_us] == pytest.approx(want, abs=1e-5), (controller, t_us)
            want = [float(row[c]) for c in ("refN", "refE", "refD")]
            assert setpoint[t_us] == pytest.approx(want, abs=1e-5), (controller, t_us)
        motor_cols = [float(rows[-1][f"pwm{i}"]) for i in range(1, 5)]
        assert motors[-1] == pytest.approx(motor_cols, abs=1e-3), controller


def test_sitl_view_of_a_missing_or_foreign_file_is_refused_before_anything_starts(tmp_path):
    sitl = str(binary("sitl"))
    missing = subprocess.run([sitl, "view", str(tmp_path / "no.ulg")], capture_output=True, text=True, timeout=60)
    assert missing.returncode != 0 and "no such file" in missing.stderr, missing.stderr
    other = tmp_path / "x.csv"
    other.write_text("t\n")
    foreign = subprocess.run([sitl, "view", str(other)], capture_output=True, text=True, timeout=60)
    assert foreign.returncode != 0 and ".ulg" in foreign.stderr, foreign.stderr
    bad = subprocess.run(
        [sitl, "scenario", "gust-hover", "--record", str(tmp_path / "x.mcap")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode != 0 and ".rrd" in bad.stderr, bad.stderr
    assert not list(tmp_path.glob("x.mcap*"))


def test_a_swarm_recorded_holds_every_vehicle_with_its_estimate_on_its_truth(tmp_path):
    first = free_instance(count=2)
    rrd = tmp_path / "swarm.rrd"
    sitl = start_sitl(tmp_path, "-n", "2", "--duration", "6", "--record", str(rrd), speed=4, instance=first)
    assert sitl.proc.wait(timeout=180) == 0, sitl.log_tail()
    table = read_rrd(rrd)
    times = table.column("sim_time").to_pylist()

    def at_time(column):
        values = table.column(column).to_pylist()
        return {round(t.total_seconds() * 1e3): v[0] for t, v in zip(times, values, strict=True) if v is not None}

    starts = []
    for n in (first, first + 1):
        truth = at_time(f"/world/v{n}/truth:Transform3D:translation")
        estimate = at_time(f"/world/v{n}/estimate:Transform3D:translation")
        # 6 s of plant time at 50 Hz, live: nothing dropped at 4x.
        assert len(truth) >= 295 and len(estimate) >= 295, (n, len(truth), len(estimate))
        both = sorted(set(truth) & set(estimate))
        assert len(both) >= 250, (n, len(both))
        gaps = sorted(max(abs(a - b) for a, b in zip(truth[t], estimate[t], strict=True)) for t in both)
        # The estimate, moved into the plant's frame by its origin, sits on the truth (GPS noise apart).
        assert gaps[len(gaps) // 2] < 0.5, (n, gaps[len(gaps) // 2])
        starts.append(truth[both[0]])
    # The grid: the second vehicle starts 3 m east of the first.
    assert abs(starts[1][1] - starts[0][1] - 3.0) < 0.05 and abs(starts[1][0] - starts[0][0]) < 0.05, starts


def test_sitl_scenario_view_without_a_display_serves_the_web_viewer_until_ctrl_c(tmp_path):
    # `--view` alone is `auto`: with no display, the web viewer, which stays up after the run until Ctrl-C.
    web, grpc = free_tcp_ports(2)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    args = [str(binary("sitl")), "scenario", "gust-hover", "--controller", "aco", "--no-plots", "--out", str(tmp_path)]
    args += ["--view", "--view-web-port", str(web), "--view-grpc-port", str(grpc)]
    log = tmp_path / "scenario.log"
    with log.open("w") as err:
        proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=err, env=env, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while "the run ended; the view stays at" not in log.read_text():
            assert proc.poll() is None, f"sitl scenario --view exited ({proc.returncode}): {log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, log.read_text()[-3000:]
            time.sleep(0.2)
        assert f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy" in log.read_text()
        with socket.create_connection(("127.0.0.1", web), timeout=10) as s:
            s.sendall(b"GET / HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
            assert s.recv(64).startswith(b"HTTP/1."), "the web viewer is served after the run"
        assert proc.poll() is None, "the view stays up until Ctrl-C"
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(60)
    assert proc.returncode == 0, log.read_text()[-3000:]
