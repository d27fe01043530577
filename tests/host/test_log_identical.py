"""Two identical runs write byte-identical bus.log files, whatever the string hash seed (issue 27): a direct run's
log carries simulated time from SIMULATED_T0_US, and everything the master sends (its SDO configuration, its
end-of-run reads) is in a fixed order."""

from __future__ import annotations

import pytest

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner

SCENARIO = REPO / "scenarios" / "zhao2022_stability.toml"


def _run(hil_run: HilRunner, monkeypatch: pytest.MonkeyPatch, seed: str) -> bytes:
    monkeypatch.setenv("PYTHONHASHSEED", seed)  # the run's environment: this process's
    run = hil_run(SCENARIO, bus="direct", name=f"seed-{seed}")
    assert run.exit_code == 0, run.stderr[-2000:]
    return run.bus_log.read_bytes()


def test_two_identical_runs_write_the_same_log(hil_run: HilRunner, monkeypatch: pytest.MonkeyPatch) -> None:
    first = _run(hil_run, monkeypatch, "1")
    second = _run(hil_run, monkeypatch, "4242")
    assert first.count(b"\n") > 100  # a log with the run in it
    assert first == second
