"""Shared fixtures: the repository root and the `sitl` binary the CLI comparisons run."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def sitl_bin() -> Path:
    """`$ACO_SITL_BIN`, else the test build's binary (scripts/test builds it), else a debug build made here."""
    given = os.environ.get("ACO_SITL_BIN")
    if given:
        return Path(given)
    for profile in ("debug", "release"):
        path = ROOT / "target" / profile / "sitl"
        if path.exists():
            return path
    subprocess.run(["cargo", "build", "--locked", "-p", "sitl", "--bin", "sitl"], cwd=ROOT, check=True)
    return ROOT / "target" / "debug" / "sitl"
