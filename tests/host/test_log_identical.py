"""Two identical runs write byte-identical bus.log files, whatever the string hash seed (issue 27): a direct run's
log carries simulated time from SIMULATED_T0_US, and everything the master sends (its SDO configuration, its
end-of-run reads) is in a fixed order."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from bench.paths import REPO

SCENARIO = REPO / "scenarios" / "zhao2022_stability.toml"


def _run(out: Path, seed: str) -> bytes:
    env = {**os.environ, "PYTHONHASHSEED": seed}
    cmd = [sys.executable, "-m", "bench.cli", "run", str(SCENARIO), "--bus", "direct", "--out", str(out), "--no-viewer"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return (out / "bus.log").read_bytes()


def test_two_identical_runs_write_the_same_log(tmp_path: Path) -> None:
    first = _run(tmp_path / "a", "1")
    second = _run(tmp_path / "b", "4242")
    assert first.count(b"\n") > 100  # a log with the run in it
    assert first == second
