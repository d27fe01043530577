"""A run's result as a test reads it (HilRun): the summary, the step metrics, the status and exit code, the traces
as numpy columns, the run folder and its files; what a failing test's report and the JUnit properties show."""

from __future__ import annotations

import json
import shutil
import sys
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import bench.pytest_plugin.expect as spec  # not `from bench.pytest_plugin import`: no arrow to the package's face
from bench.pytest_plugin.steps import Step, fmt

if TYPE_CHECKING:
    import numpy as np

SUMMARY = "summary.json"


class RunFolderError(Exception):
    """A folder without a readable summary.json."""


@dataclass(eq=False)
class HilRun:
    """One `bench run`: its folder, exit status (the verdict, README "exit status") and summary.json, the steps'
    metrics, the files it wrote, the tail of its output. `run["iq_A"]` is a trace column (traces.npy, one row per
    period); the expect_* methods assert on it (bench.pytest_plugin.expect) and return the run, so they chain."""

    folder: Path
    exit_code: int
    summary: dict[str, Any]
    status: str
    steps: list[Step]
    bus_log: Path
    recording: Path | None
    scenario: Path | None = None
    bus: str | None = None
    stdout: str = field(default="", repr=False)
    stderr: str = field(default="", repr=False)

    # ------------------------------------------------------------------ the files
    @property
    def status_expected(self) -> bool:
        """Whether the status is one the scenario expects (`scenario.expect`; exit status 0)."""
        return bool(self.summary.get("status_expected", self.exit_code == 0))

    @property
    def emcy(self) -> list[dict[str, Any]]:
        return list(self.summary.get("emcy") or [])

    @property
    def plots(self) -> list[Path]:
        return [self.folder / p for p in (self.summary.get("files") or {}).get("plots") or []]

    @property
    def traces_file(self) -> Path:
        return self.folder / ((self.summary.get("files") or {}).get("traces") or "traces.npy")

    @cached_property
    def traces(self) -> np.ndarray:
        """traces.npy: a numpy structured array, a row per period, a field per signal (`columns`)."""
        import numpy as np

        if not self.traces_file.is_file():
            raise FileNotFoundError(f"{self.traces_file}: the run wrote no traces")
        return np.load(self.traces_file)

    @property
    def columns(self) -> tuple[str, ...]:
        """The trace columns: period, t_s, then the signals (i_a_A, iq_A, iq_ref_A, v_alpha_V, ...)."""
        return tuple(self.traces.dtype.names or ())

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.columns:
            raise KeyError(f"no trace column {name!r} in {self.traces_file}; columns: {', '.join(self.columns)}")
        return self.traces[name]

    def step(self, signal: str | None = None, index: int | None = None) -> Step:
        """The step of `signal` (its `index`-th when it has several; None: the only one), any signal when None."""
        __tracebackhide__ = True
        chosen = [s for s in self.steps if signal is None or s.signal == signal]
        have = ", ".join(s.describe() for s in self.steps) or "none"
        if index is None and len(chosen) != 1:
            what = "step" if signal is None else f"{signal} step"
            raise LookupError(f"the run has {len(chosen)} {what}s, give index=; its steps: {have} ({self.folder})")
        i = 0 if index is None else index
        if not -len(chosen) <= i < len(chosen):
            raise LookupError(f"no step {signal or ''}[{i}]: the run's steps: {have} ({self.folder})")
        return chosen[i]

    # ------------------------------------------------------------------ the spec (bench.pytest_plugin.expect)
    def expect_status(self, *statuses: str) -> HilRun:
        __tracebackhide__ = True
        spec.expect_status(self, *statuses)
        return self

    def expect_settles_within(self, periods: int, signal: str | None = None) -> HilRun:
        __tracebackhide__ = True
        spec.expect_settles_within(self, periods, signal)
        return self

    def expect_overshoot_below(self, percent: float, signal: str | None = None) -> HilRun:
        __tracebackhide__ = True
        spec.expect_overshoot_below(self, percent, signal)
        return self

    def expect_steady_state_error_below(self, amps: float, signal: str | None = None) -> HilRun:
        __tracebackhide__ = True
        spec.expect_steady_state_error_below(self, amps, signal)
        return self

    def expect_no_emcy(self) -> HilRun:
        __tracebackhide__ = True
        spec.expect_no_emcy(self)
        return self


def load_run(
    folder: Path | str,
    exit_code: int = 0,
    *,
    scenario: Path | None = None,
    bus: str | None = None,
    stdout: str = "",
    stderr: str = "",
) -> HilRun:
    """A run folder (a `bench run --out`) as a HilRun; RunFolderError when it holds no readable summary.json."""
    folder = Path(folder).resolve()
    try:
        summary = json.loads((folder / SUMMARY).read_text())
    except OSError as exc:
        raise RunFolderError(f"{folder / SUMMARY}: {exc.strerror}") from None
    except ValueError as exc:
        raise RunFolderError(f"{folder / SUMMARY}: not valid JSON ({exc})") from None
    if not isinstance(summary, dict):
        raise RunFolderError(f"{folder / SUMMARY}: not a JSON object")
    files = summary.get("files") or {}
    recording = files.get("recording")
    return HilRun(
        folder=folder,
        exit_code=exit_code,
        summary=summary,
        status=str(summary.get("status", "unknown")),
        steps=[Step.from_summary(s) for s in summary.get("steps") or []],
        bus_log=folder / (files.get("log") or "bus.log"),
        recording=folder / recording if recording else None,
        scenario=scenario,
        bus=bus if bus is not None else summary.get("bus"),
        stdout=stdout,
        stderr=stderr,
    )


def viewer_command(recording: Path) -> str:
    """`rerun FILE`: the Rerun viewer of this environment (the venv's when it is not on PATH)."""
    exe = shutil.which("rerun") or next(
        (str(p) for p in [Path(sys.executable).parent / "rerun"] if p.is_file()), "rerun"
    )
    return f"{exe} {recording}"


def step_line(s: Step) -> str:
    settle = "never settles" if s.periods_to_settle is None else f"settles in {s.periods_to_settle} periods"
    over = "n/a" if s.overshoot_pct is None else f"{fmt(s.overshoot_pct)} %"
    err = "n/a" if s.steady_state_error_A is None else f"{fmt(s.steady_state_error_A)} A"
    return f"{s.describe()}: {settle}, overshoot {over}, steady-state error {err}"


def report_text(run: HilRun) -> str:
    """What a failing test's report shows of the run: where it is, how to look at it, what it measured."""
    expected = ", a status the scenario expects" if run.status_expected else ""
    rec = "none written" if run.recording is None else f"{run.recording}\n  view it:   {viewer_command(run.recording)}"
    lines = [
        f"run folder:  {run.folder}",
        f"scenario:    {run.scenario or run.summary.get('scenario')} on bus {run.bus}",
        f"status:      {run.status} (exit status {run.exit_code}{expected})",
        *_motor_line(run.summary.get("motor")),
        f"summary:     {run.folder / 'summary.json'}",
        f"traces:      {run.folder / 'traces.npy'} (numpy.load)",
        f"plots:       {', '.join(p.name for p in sorted(run.folder.glob('*.svg'))) or 'none written'}",
        f"bus log:     {run.bus_log}",
        f"recording:   {rec}",
    ]
    lines += [f"step:        {step_line(s)}" for s in run.steps]
    return "\n".join(lines)


def _motor_line(block: Any) -> list[str]:
    """The report's line on a motor folder or FMU (summary.json "motor"); none for a built-in motor."""
    if not isinstance(block, dict) or not (block.get("folder") or block.get("fmu")):
        return []
    return [f"motor:       {block.get('folder') or block.get('fmu')} (content {block.get('digest')})"]


def junit_properties(run: HilRun, prefix: str = "hil_") -> list[tuple[str, object]]:
    """The key figures as JUnit properties (CI servers show them): status, exit code, folder, per step
    <prefix><signal>_p<period>_settle_periods / _overshoot_pct / _ss_error_A."""
    props: list[tuple[str, object]] = [
        (f"{prefix}status", run.status),
        (f"{prefix}exit_code", run.exit_code),
        (f"{prefix}run_folder", str(run.folder)),
    ]
    for s in run.steps:
        p = f"{prefix}{s.signal}_p{s.at_period}"
        props.append((f"{p}_settle_periods", "never" if s.periods_to_settle is None else s.periods_to_settle))
        props.append((f"{p}_overshoot_pct", "n/a" if s.overshoot_pct is None else f"{s.overshoot_pct:.6g}"))
        props.append((f"{p}_ss_error_A", "n/a" if s.steady_state_error_A is None else f"{s.steady_state_error_A:.6g}"))
    return props
