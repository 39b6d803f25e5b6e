"""Bad input gets a Python exception with a clear message, never an abort, and changes nothing."""

from __future__ import annotations

import math

import pytest

import aco_sim
from aco_sim import _native


def test_an_unknown_scenario_controller_or_parameter_is_a_key_error():
    with pytest.raises(KeyError, match="no built-in scenario or file named `nowhere`"):
        aco_sim.Sim("nowhere")
    with pytest.raises(KeyError, match=r"unknown controller `lqr` \(registered: aco, ca, pid, se3"):
        aco_sim.Sim("gust-hover", controller="lqr")
    sim = aco_sim.Sim("gust-hover")
    with pytest.raises(KeyError, match="NOT_A_PARAM"):
        sim.set_param("NOT_A_PARAM", 1.0)
    with pytest.raises(KeyError, match="SIM_NOPE"):
        sim.set_param("SIM_NOPE", 1.0)


def test_an_out_of_range_or_non_controller_parameter_is_refused_and_changes_nothing():
    sim = aco_sim.Sim("gust-hover", controller="pid")
    with pytest.raises(ValueError, match="PID_POS_P"):
        sim.set_param("PID_POS_P", -5.0)
    with pytest.raises(ValueError, match="SIM_MOT1_EFF"):
        sim.set_param("SIM_MOT1_EFF", 7.0)
    with pytest.raises(ValueError, match="not a controller parameter"):
        sim.set_param("MIS_TAKEOFF_ALT", 3.0)
    refused = sim.run()
    untouched = aco_sim.Sim("gust-hover", controller="pid").run()
    for key in untouched:
        if key not in ("wall_s", "realtime_factor"):
            assert refused[key] == untouched[key], key


def test_a_controller_that_raises_stops_the_run_with_its_exception():
    def broken(inp, ref):
        if inp.t_s > 0.01:
            raise ZeroDivisionError("my law divided by zero")
        return [1500.0] * 4

    with pytest.raises(ZeroDivisionError, match="my law divided by zero"):
        aco_sim.run_scenario("gust-hover", controller=broken)


@pytest.mark.parametrize(
    ("action", "message"),
    [
        ([1500.0] * 3, "returned 3 values at t = 0 s; expected 4"),
        ([1500.0, math.nan, 1500.0, 1500.0], "returned NaN in component 1 at t = 0 s: actions must be finite"),
        ([1500.0, 1500.0, math.inf, 1500.0], "returned inf in component 2"),
        ("abcd", "expected a sequence of 4 numbers"),
        (None, "returned NoneType"),
    ],
)
def test_a_malformed_action_is_a_value_error_naming_it(action, message):
    with pytest.raises(ValueError, match=message):
        aco_sim.run_scenario("gust-hover", controller=lambda inp, ref: action)


def test_ctbr_needs_a_rate_loop():
    with pytest.raises(ValueError, match="the ctbr action needs a rate loop, and controller ca has none"):
        aco_sim.Sim("gust-hover", controller=lambda i, r: [0.5, 0, 0, 0], action="ctbr", rate_controller="ca")
    with pytest.raises(ValueError, match="action `thrust` is not one of: pwm, ctbr"):
        aco_sim.Sim("gust-hover", controller=lambda i, r: [0.5, 0, 0, 0], action="thrust")


def test_stepping_a_finished_run_is_an_error():
    sim = aco_sim.Sim("paper-attitude", controller="aco")
    sim.run()
    with pytest.raises(RuntimeError, match="the run has finished"):
        sim.step()
    sim = aco_sim.Sim("paper-attitude", controller="aco")
    sim.step(8000)
    with pytest.raises(RuntimeError, match="the run is over: all 8000 ticks have run"):
        sim.step()


def test_a_rust_panic_is_a_runtime_error_naming_the_call():
    with pytest.raises(RuntimeError, match="panic_for_test panicked inside Rust: a panic on purpose"):
        _native.panic_for_test()
