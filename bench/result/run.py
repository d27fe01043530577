"""A run's result as a test or a study reads it (HilRun): the summary, the step metrics, the status and exit code, the
traces as numpy columns, the run folder and its files when it has them. The pytest plugin's hil_run and the library's
bench.api.run return it; a folder that `bench run --out` wrote reads back with load_run."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import bench.result.expect as spec
from bench.result.steps import Step

if TYPE_CHECKING:
    import numpy as np

SUMMARY = "summary.json"


class RunFolderError(Exception):
    """A folder without a readable summary.json."""


@dataclass(eq=False)
class HilRun:
    """One run: its exit status (the verdict, README "exit status") and summary.json, the steps' metrics, its traces,
    and when it wrote files its folder, the files and the tail of its output. `run["iq_A"]` is a trace column (one row
    per period); the expect_* methods assert on it (bench.result.expect) and return the run, so they chain.

    A run of bench.api.run without out= has no folder (`folder`, `bus_log` None): its traces are in memory (`rows`),
    the same rows traces.npy would hold."""

    folder: Path | None
    exit_code: int
    summary: dict[str, Any]
    status: str
    steps: list[Step]
    bus_log: Path | None
    recording: Path | None
    scenario: Path | None = None
    bus: str | None = None
    stdout: str = field(default="", repr=False)
    stderr: str = field(default="", repr=False)
    rows: np.ndarray | None = field(default=None, repr=False)  # the traces of a run without files

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
        if self.folder is None:
            return []
        return [self.folder / p for p in (self.summary.get("files") or {}).get("plots") or []]

    @property
    def traces_file(self) -> Path | None:
        if self.folder is None:
            return None
        return self.folder / ((self.summary.get("files") or {}).get("traces") or "traces.npy")

    @cached_property
    def traces(self) -> np.ndarray:
        """traces.npy: a numpy structured array, a row per period, a field per signal (`columns`); in memory for a run
        without files."""
        import numpy as np

        if self.rows is not None:
            return self.rows
        if self.traces_file is None:
            raise FileNotFoundError("the run has no traces: no period of it reached the bus")
        if not self.traces_file.is_file():
            raise FileNotFoundError(f"{self.traces_file}: the run wrote no traces")
        return np.load(self.traces_file)

    @property
    def columns(self) -> tuple[str, ...]:
        """The trace columns: period, t_s, then the signals (i_a_A, iq_A, iq_ref_A, v_alpha_V, ...)."""
        return tuple(self.traces.dtype.names or ())

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.columns:
            where = self.traces_file or "the run's traces"
            raise KeyError(f"no trace column {name!r} in {where}; columns: {', '.join(self.columns)}")
        return self.traces[name]

    def step(self, signal: str | None = None, index: int | None = None) -> Step:
        """The step of `signal` (its `index`-th when it has several; None: the only one), any signal when None."""
        __tracebackhide__ = True
        chosen = [s for s in self.steps if signal is None or s.signal == signal]
        have = ", ".join(s.describe() for s in self.steps) or "none"
        where = self.folder or "in memory"
        if index is None and len(chosen) != 1:
            what = "step" if signal is None else f"{signal} step"
            raise LookupError(f"the run has {len(chosen)} {what}s, give index=; its steps: {have} ({where})")
        i = 0 if index is None else index
        if not -len(chosen) <= i < len(chosen):
            raise LookupError(f"no step {signal or ''}[{i}]: the run's steps: {have} ({where})")
        return chosen[i]

    # ------------------------------------------------------------------ the spec (bench.result.expect)
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
