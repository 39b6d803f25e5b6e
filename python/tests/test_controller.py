"""Python controllers in the paper's experiments: the runner and metrics of the built-in ones, the same
numbers as the law's Rust twin, the rate action, and a sweep."""

from __future__ import annotations

import math

import numpy as np
import pytest

import aco_sim
from aco_sim.pd import PdHover

WALL_CLOCK = ("wall_s", "realtime_factor", "controller")


def without_labels(metrics: dict) -> dict:
    return {k: v for k, v in metrics.items() if k not in WALL_CLOCK}


def test_a_python_pd_hovers_in_the_gust_with_a_peak_under_half_a_metre():
    m = aco_sim.run_scenario("gust-hover", controller=PdHover())
    assert m["controller"] == "python"
    assert not m["non_finite"]
    assert m["gust"]["peak_m"] < 0.5, m["gust"]


def test_the_python_pd_and_its_rust_twin_give_identical_metrics():
    python = aco_sim.run_scenario("gust-hover", controller=PdHover(), seed=4)
    rust = aco_sim.run_scenario("gust-hover", controller="example_pd", seed=4)
    assert rust["controller"] == "example_pd"
    assert without_labels(python) == without_labels(rust)
    # And the traces, row for row.
    a = aco_sim.Sim("figure8", controller=PdHover(), seed=2)
    b = aco_sim.Sim("figure8", controller="example_pd", seed=2)
    a.step(4000)
    b.step(4000)
    for column in ("pN", "pE", "pD", "roll", "pwm1", "pwm4"):
        assert np.array_equal(a.trace[column], b.trace[column]), column


def test_a_ctbr_controller_flies_the_rate_steps_through_acos_rate_loop():
    def rates(inp, ref):
        # Fly the scenario's own rate reference: collective plus the body rates it asks.
        return [ref.collective_frac, *ref.rate_frd_radps.tolist()]

    python = aco_sim.run_scenario("rate-steps", controller=rates, action="ctbr", rate_controller="aco")
    built_in = aco_sim.run_scenario("rate-steps", controller="aco")
    assert without_labels(python) == without_labels(built_in)


def test_the_controller_sees_the_tick_time_and_is_called_every_tick():
    calls = []

    def hover(inp, ref):
        calls.append(inp.t_s)
        return [1500.0] * 4

    sim = aco_sim.Sim("gust-hover", controller=hover)
    sim.step(10)
    assert calls == pytest.approx([k * 0.002 for k in range(10)])


def test_a_sweep_flies_every_case_with_a_python_controller(tmp_path):
    spec = tmp_path / "sweep.toml"
    spec.write_text(
        'name = "python-sweep"\nscenario = "gust-hover"\nsamples = 3\nseed = 5\n'
        "[vary]\nmass_kg = { uniform = [5.0, 5.6] }\n"
    )
    table = aco_sim.sweep(str(spec), PdHover())
    assert table["case"].tolist() == [0.0, 1.0, 2.0]
    assert len(set(table["mass_kg"].tolist())) == 3
    peaks = [c for c in table if "peak" in c]
    assert peaks and all(np.isfinite(table[c]).all() for c in peaks)
    assert all(math.isfinite(v) and v < 0.5 for v in table["gust_peak_m"].tolist())
