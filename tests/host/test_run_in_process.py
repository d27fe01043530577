"""hil_run's direct runs run in the test's process (bench/cli_in_process.py): the same run as a `bench run` process,
bit for bit (traces.npy, bus.log, the summary but for its wall-clock timing), whatever ran in the process before
(the reused viewer and plot processes, the loaded C library), and the same files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner
from bench.pytest_plugin.state import RUN_VIEWS

SCENARIOS = [
    "scenarios/you2019_step.toml",  # You 2019, the deadbeat step
    "scenarios/yao2020_identification.toml",  # Yao 2020, the R/L identification
    "scenarios/zhao2022_stability.toml",  # Zhao 2022, a stability point
    "scenarios/faults/you2019_drop_command.toml",  # the fault injector
]


def _summary(folder: Path) -> dict[str, Any]:
    summary = json.loads((folder / "summary.json").read_text())
    summary.pop("timing")  # wall-clock figures
    return summary


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[Path(s).stem for s in SCENARIOS])
def test_a_run_in_process_is_the_run_of_a_process(
    hil_run: HilRunner, tmp_path: Path, scenario: str, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> None:
    import bench.pytest_plugin.fixture as fixture

    def no_process(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("hil_run started a `bench run` process for a direct run")

    monkeypatch.setattr(fixture, "execute", no_process)
    here = hil_run(REPO / scenario, bus="direct")
    again = hil_run(REPO / scenario, bus="direct")  # the process's second run of it: nothing carried over
    out = tmp_path / "process"
    bench_cli("run", REPO / scenario, "--bus", "direct", "--no-viewer", "--out", out)
    assert here.stdout == "" or "bench run:" in here.stdout  # the command's own output, captured
    data = {"bus.log", "summary.json", "traces.npy"}
    for run in (here, again):
        assert (run.folder / "traces.npy").read_bytes() == (out / "traces.npy").read_bytes()
        assert run.bus_log.read_bytes() == (out / "bus.log").read_bytes()
        # --hil-view=failed: the recording and plots are not drawn while the test passes ...
        assert {p.name for p in run.folder.iterdir()} == data
    # ... and drawn as the process drew them when it fails (bench/pytest_plugin/__init__.py: _draw)
    kept = request.node.stash[RUN_VIEWS]
    assert [later.run for later in kept] == [here, again]
    for later in kept:
        later.view.draw(later.run.folder)
    for run in (here, again):
        assert _summary(run.folder) == _summary(out)
        assert sorted(p.name for p in run.folder.iterdir()) == sorted(p.name for p in out.iterdir())
        assert (run.folder / "run.rrd").stat().st_size > 0


def test_bad_arguments_in_process_are_the_commands_refusal(tmp_path: Path) -> None:
    from bench.cli_in_process import run_here

    ran = run_here([str(REPO / SCENARIOS[0]), "--bus", "direct", "--out", str(tmp_path / "x"), "--no-such-option"])
    assert ran.exit_code == 2 and "unrecognized arguments: --no-such-option" in ran.stderr, ran
    ran = run_here([str(REPO / SCENARIOS[0]), "--bus", "direct", "--out", str(tmp_path / "y"), "--set", "a.b=1"])
    assert ran.exit_code == 2 and not (tmp_path / "y").exists(), ran
    assert "bench run:" in ran.stderr, ran


def test_which_runs_go_in_process() -> None:
    from bench.cli_in_process import runs_here

    assert runs_here(["s.toml", "--bus", "direct"]) and runs_here(["s.toml", "--bus=direct"])
    assert not runs_here(["s.toml"])  # bench run's default bus is vcan0
    assert not runs_here(["s.toml", "--bus", "vcan0"]) and not runs_here(["s.toml", "--channel", "can0"])
    assert not runs_here(["s.toml", "--bus", "direct", "--law", "laws/x"])  # a law's build: its own process
    assert not runs_here(["s.toml", "--bus", "direct", "--no-such-option"])  # the process says what is wrong


def test_the_kept_viewer_processes_are_replaced_after_their_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """rerun-sdk keeps memory of every recording a process made: a kept process serves REUSE_RUNS runs, then a new
    one serves the next (bench/view/worker_procs.py); every run still gets its recording and plots."""
    from bench.cli_in_process import run_here
    from bench.view import worker_procs

    monkeypatch.setattr(worker_procs, "REUSE_RUNS", 2)
    pids = []
    for i in range(5):
        out = tmp_path / f"r{i}"
        ran = run_here([str(REPO / SCENARIOS[0]), "--bus", "direct", "--out", str(out), "--set", "scenario.periods=40"])
        assert ran.exit_code == 0, ran.stderr
        assert (out / "run.rrd").is_file() and list(out.glob("*.svg")), sorted(out.iterdir())
        pids.append(worker_procs._STARTED["rerun"].proc.pid)
    assert len(set(pids)) >= 2 and pids[0] != pids[2], pids  # the runs' processes: kept for 2, then replaced


class Cancelled(BaseException):
    """What pytest's cancel raises in a running test (bench/pytest_plugin/cancel.py: pytest.skip.Exception)."""


@pytest.mark.parametrize("stop", [Cancelled("the test was cancelled"), KeyboardInterrupt()], ids=["cancel", "ctrl-c"])
def test_a_stop_while_the_results_are_written_keeps_the_run_and_reaches_the_caller(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stop: BaseException
) -> None:
    """The caller's exception (a cancelled test) or Ctrl-C after the loop: the complete run is kept in its folder
    (summary.json saying what was not written; no NAME.partial), and the exception reaches the caller (a Ctrl-C as
    KeyboardInterrupt: the pytest session stops, as it did when the run was a process of its own)."""
    from bench.cli_in_process import run_here
    from bench.run import outputs

    def finish(self: Any, result: Any) -> None:
        raise stop

    monkeypatch.setattr(outputs.Outputs, "finish", finish)
    out = tmp_path / "run"
    with pytest.raises(type(stop)):
        run_here([str(REPO / SCENARIOS[0]), "--bus", "direct", "--out", str(out), "--set", "scenario.periods=40"])
    assert not out.with_name("run.partial").exists() and (out / "traces.npy").is_file(), sorted(tmp_path.iterdir())
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["periods"] == 40 and summary["files"]["recording"] is None


def test_a_process_that_keeps_enough_draws_the_next_runs_as_they_go(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--hil-view=failed keeps the runs' chunks only up to deferred.KEEP_BYTES a process: beyond it a run draws its
    recording and plots as it goes, as with --hil-view=all, and nothing is kept for it."""
    import bench.view.deferred as deferred
    from bench.cli_in_process import run_here

    monkeypatch.setattr(deferred, "KEEP_BYTES", 1)  # every run is over the budget
    argv = [str(REPO / SCENARIOS[0]), "--bus", "direct", "--no-viewer", "--out"]
    ran = run_here([*argv, str(tmp_path / "over")], view_later=True)
    assert ran.exit_code == 0, ran.stderr
    assert ran.view is not None and ran.view.draw() == [] and deferred._HELD[0] == 0
    assert (tmp_path / "over" / "run.rrd").stat().st_size > 0 and (tmp_path / "over" / "overview.svg").is_file()
    monkeypatch.setattr(deferred, "KEEP_BYTES", 1 << 40)
    ran = run_here([*argv, str(tmp_path / "kept")], view_later=True)
    assert ran.view is not None and deferred._HELD[0] == ran.view.held > 0
    assert not (tmp_path / "kept" / "run.rrd").exists()
    ran.view.release()
    assert deferred._HELD[0] == 0
