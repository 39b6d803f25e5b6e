"""The simulator from numpy: the same metrics as the CLI, stepping, state, parameters and the trace."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import aco_sim

WALL_CLOCK = ("wall_s", "realtime_factor")


def without_wall_clock(metrics: dict) -> dict:
    return {k: v for k, v in metrics.items() if k not in WALL_CLOCK}


def test_sim_metrics_equal_the_cli_json_field_by_field(sitl_bin, tmp_path):
    cli = subprocess.run(
        [
            str(sitl_bin),
            "scenario",
            "gust-hover",
            "--controller",
            "aco",
            "--json",
            "--no-plots",
            "--out",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    from_cli = json.loads(cli.stdout.strip().splitlines()[-1])
    from_python = aco_sim.Sim("gust-hover", controller="aco").run()
    assert set(from_python) == set(from_cli)
    for key in from_cli:
        if key not in WALL_CLOCK:
            assert from_python[key] == from_cli[key], key
    # The trace is the CSV's columns.
    csv = (tmp_path / "gust-hover").glob("*.csv")
    header = next(iter(csv)).read_text().splitlines()[0].split(",")
    sim = aco_sim.Sim("gust-hover", controller="aco")
    sim.step(500)
    assert list(sim.trace) == header


def test_stepping_to_the_end_gives_the_same_run_as_run():
    whole = aco_sim.Sim("gust-hover", controller="pid", seed=3).run()
    sim = aco_sim.Sim("gust-hover", controller="pid", seed=3)
    ran = 0
    while True:
        n = sim.step(997)
        ran += n
        if n < 997:
            break
    assert ran == 15_000 and sim.ticks == (15_000, 15_000)
    assert without_wall_clock(sim.run()) == without_wall_clock(whole)


def test_state_gives_truth_estimate_and_reference_as_numpy():
    sim = aco_sim.Sim("gust-hover", controller="aco")
    assert sim.state is None
    sim.step(250)
    s = sim.state
    assert s["t_s"] == pytest.approx(0.5)
    assert s["truth"]["pos_ned_m"].dtype == np.float64 and s["truth"]["pos_ned_m"].shape == (3,)
    assert abs(s["truth"]["pos_ned_m"][2] + 1.5) < 0.1
    assert np.linalg.norm(s["truth"]["q_ned_frd"]) == pytest.approx(1.0)
    # gust-hover feeds the controller the paper's noise: the estimate is not the truth.
    assert not np.array_equal(s["estimate"]["pos_ned_m"], s["truth"]["pos_ned_m"])
    assert s["reference"]["pos_ned_m"].tolist() == [0.0, 0.0, -1.5]
    assert s["pwm_us"].shape == (4,)


def test_trace_columns_are_arrays_at_the_trace_rate():
    sim = aco_sim.Sim("paper-attitude", controller="ca", trace_hz=100)
    sim.run()
    trace = sim.trace
    assert trace["t"].shape == (1600,) and trace["t"][1] == pytest.approx(0.01)
    for name in ("pN", "roll", "pwm1", "ref_roll", "windE"):
        assert trace[name].dtype == np.float64 and len(trace[name]) == 1600


def test_set_param_reaches_the_plant_and_the_controller():
    base = aco_sim.Sim("gust-hover", controller="pid")
    base.step(2500)
    base_pos = base.state["truth"]["pos_ned_m"]

    weak = aco_sim.Sim("gust-hover", controller="pid")
    weak.set_param("SIM_MOT1_EFF", 0.8)
    weak.step(2500)
    assert not np.array_equal(weak.state["truth"]["pos_ned_m"], base_pos)

    gains = aco_sim.Sim("gust-hover", controller="pid")
    gains.set_param("PID_POS_P", 0.5)
    gains.step(2500)
    assert not np.array_equal(gains.state["truth"]["pos_ned_m"], base_pos)


def test_listings_name_the_built_ins():
    names = aco_sim.scenarios()
    assert {"gust-hover", "figure8", "paper-attitude", "rate-steps"} <= set(names)
    assert all(isinstance(d, str) and d for d in names.values())
    kinds = aco_sim.controllers()
    assert {"aco", "ca", "pid", "se3", "example_pd"} <= set(kinds)
    assert kinds["aco"]["flies_rates"] is True and kinds["ca"]["flies_rates"] is False


def test_a_scenario_file_loads_with_the_cli_parser(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(
        'name = "short"\nduration_s = 2.0\nplant = "nominal"\nmetrics = ["steps"]\n'
        "[initial]\npos_ned_m = [0.0, 0.0, -2.0]\n"
        '[reference]\nkind = "position"\nsteps = [{ t_s = 0.0, pos_ned_m = [0.5, 0.0, -2.0] }]\n'
    )
    m = aco_sim.Sim(str(path), controller="aco").run()
    assert m["scenario"] == "short" and m["sim_s"] == pytest.approx(2.0)
    assert m["segments"][0]["axis"] == "n"
