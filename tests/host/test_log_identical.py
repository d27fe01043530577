"""Two identical runs write byte-identical bus.log files, whatever the string hash seed (issue 27): a direct run's
log carries simulated time from SIMULATED_T0_US, and everything the master sends (its SDO configuration, its
end-of-run reads) is in a fixed order. Each run is a `bench run` process of its own: the hash seed is a process's
(hil_run would run both in this one)."""

from __future__ import annotations

from pathlib import Path

from bench_cli import bench_cli

from bench.paths import REPO

SCENARIO = REPO / "scenarios" / "zhao2022_stability.toml"


def _run(tmp_path: Path, seed: str) -> bytes:
    out = tmp_path / f"seed-{seed}"
    bench_cli("run", SCENARIO, "--bus", "direct", "--no-viewer", "--out", out, env={"PYTHONHASHSEED": seed}, expect=0)
    return (out / "bus.log").read_bytes()


def test_two_identical_runs_write_the_same_log(tmp_path: Path) -> None:
    first = _run(tmp_path, "1")
    second = _run(tmp_path, "4242")
    assert first.count(b"\n") > 100  # a log with the run in it
    assert first == second
