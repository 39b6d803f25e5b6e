"""The examples in python/examples run as a user runs them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_the_quickstart_runs_and_draws_its_figure(tmp_path):
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / "quickstart.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "ACO: gust peak" in done.stdout and "64 hovers, 2 s" in done.stdout
    assert ", 0 ended," in done.stdout  # the hand-written ctbr policy keeps all 64 up
    assert (tmp_path / "gust-hover.png").stat().st_size > 10_000
