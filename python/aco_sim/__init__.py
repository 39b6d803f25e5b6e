"""aco_sim: the ACO quadrotor's lockstep simulator from Python.

- ``Sim`` flies one scenario (a built-in name or a scenario TOML file, the parser ``sitl scenario`` uses)
  with a registered controller or a Python callable; ``.run()`` gives the metrics ``sitl scenario --json``
  prints, ``.trace`` the CSV's columns as numpy arrays, ``.step(n)`` / ``.state`` / ``.set_param`` drive it.
- ``run_scenario`` and ``sweep`` fly a Python controller ``(input, reference) -> action`` through the same
  runner and metrics as the built-in ones.
- Importing ``aco_sim`` registers the Gymnasium environments ``aco_sim/Hover-v0`` and ``aco_sim/Track-v0``
  (``aco_sim.envs``), whose vector form steps every environment in Rust.

Reference and quick start: docs/python.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Callable, Union

import numpy as np

from . import _native
from . import envs as envs  # registers the Gymnasium environments
from ._native import ControlInput, Reference, Sim

__all__ = [
    "ControlInput",
    "Reference",
    "Sim",
    "controllers",
    "run_scenario",
    "scenarios",
    "sweep",
]

Controller = Union[str, Callable[[ControlInput, Reference], Sequence[float]]]


def scenarios() -> dict[str, str]:
    """The built-in scenarios: name -> description."""
    return dict(_native.scenarios())


def controllers() -> dict[str, dict[str, Any]]:
    """The registered controllers: name -> {"summary", "table", "flies_rates"}."""
    return dict(_native.controllers())


def run_scenario(
    scenario: str,
    controller: Controller = "aco",
    *,
    plant: str | None = None,
    seed: int = 1,
    mode: str | None = None,
    rate_hz: int = 500,
    action: str = "pwm",
    rate_controller: str = "aco",
) -> dict[str, Any]:
    """Flies ``scenario`` once and returns its metrics (the dict ``sitl scenario --json`` prints).

    ``controller`` is a registered name or a callable ``(input, reference) -> action`` called every control
    tick (500 Hz by default). With ``action="pwm"`` the action is four rotor PWM commands (µs, rotors 1 right,
    2 rear, 3 front, 4 left; the plant clamps them to 1000-2000). With ``action="ctbr"`` it is
    ``[collective 0-1, p, q, r]`` (body rates FRD, rad/s), flown by the rate loop of ``rate_controller``.
    An exception raised by the callable, or a malformed action, stops the run and is raised here.
    """
    sim = Sim(
        scenario,
        controller=controller,
        plant=plant,
        seed=seed,
        mode=mode,
        rate_hz=rate_hz,
        action=action,
        rate_controller=rate_controller,
    )
    return dict(sim.run())


def sweep(
    path: str, controller: Controller, *, action: str = "pwm", rate_controller: str = "aco"
) -> dict[str, np.ndarray]:
    """Flies every case of a sweep file (``sitl sweep``'s format) with ``controller``; returns the table as
    columns {name: array}: ``case``, ``seed``, the varied values, then ``sitl sweep``'s metric columns."""
    return dict(_native.sweep_native(path, controller, action, rate_controller))
