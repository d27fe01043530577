"""The papers' quantitative claims, each run on the bench and judged.

A claim module runs scenarios through the same capture path as `bench run` (over vcan
or in direct mode) and returns :class:`ClaimResult` records: what the paper states, what
the bench measured, the tolerance, the verdict and why they differ where they do.
Tests assert on them; `bench reproduce` reports them.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.run import RunOptions, RunResult, run_scenario
from bench.scenario import parse


@dataclass
class ClaimResult:
    paper: str  # "You 2019"
    claim_id: str  # "you2019-1a"
    figure: str  # "Fig. 8 / You 2019 Eq. 20-21"
    statement: str  # what the paper says
    paper_value: Any
    bench_value: Any
    tolerance: str
    reproduced: bool  # the bench agrees with the paper's statement within the tolerance
    why_differs: str = ""
    details: dict[str, Any] = field(default_factory=dict)
    plots: list[str] = field(default_factory=list)
    # The runs (folder names under RUN_ROOT, Run.name) whose figure shows this claim; None: the claim
    # function's runs (bench reproduce then shows the figure only when the function made one result).
    runs: list[str] | None = None
    # Where the bench differs from the paper for a known reason (a typo, an approximation), the bench's
    # own derived expectation is checked instead; None = same as `reproduced`.
    bench_ok: bool | None = None

    @property
    def verdict(self) -> str:
        return "reproduced" if self.reproduced else "differs"

    @property
    def ok(self) -> bool:
        """What the tests assert: the loop behaves as the equations predict."""
        return self.reproduced if self.bench_ok is None else self.bench_ok

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["verdict"] = self.verdict
        d["bench_check"] = "pass" if self.ok else "FAIL"
        return d


@dataclass
class Run:
    result: RunResult
    tr: dict[str, np.ndarray]
    out: Path | None  # the run's folder (bus.log, summary.json) when kept
    frames: np.ndarray | None = None  # every frame, when asked for

    @property
    def name(self) -> str:
        return self.out.name if self.out is not None else self.result.scenario

    @property
    def cap(self) -> RunResult:  # the claims' name for the run's own values (plant, counters, ...)
        return self.result


# When set (by `bench reproduce`), every run of a claim is kept under this folder and its
# name is appended to RUNS_USED, so that the report can link its plots and recording.
RUN_ROOT: Path | None = None
RUNS_USED: list[str] = []
# The drive signals traced per period by the runs inside `traced(...)` (scenario [trace]).
_TRACE: dict[int, tuple[str, ...]] | None = None


@contextmanager
def traced(pdos: dict[int, tuple[str, ...]]) -> Iterator[None]:
    """Map the drive's synchronous trace TPDOs to other EDS entries for the runs inside."""
    global _TRACE
    old = _TRACE
    _TRACE = pdos
    try:
        yield
    finally:
        _TRACE = old


def with_sections(raw: dict[str, Any], sections: dict[str, Any]) -> dict[str, Any]:
    """A claim's base scenario with a run's own tables merged in, key by key (its events replace the base's)."""
    for key, value in sections.items():
        if key == "events":
            raw["events"] = value
        else:
            raw.setdefault(key, {}).update(value)
    return raw


def run_raw(raw: dict[str, Any], bus: str, out: Path | None = None, keep_frames: bool = False) -> Run:
    """Run a scenario given as a TOML-shaped dict on `bus` ('direct' or a CAN channel), in memory.
    Under `bench reproduce` (RUN_ROOT set) the run's CAN log, decoded trace (traces.npy) and summary are kept in
    RUN_ROOT/NAME (or `out`); `bench reproduce` makes its plots and Rerun recording from that trace
    (bench/reproduce/views.py)."""
    import json

    from bench.run.bus.buses import choose_bus
    from bench.run.record.canlog import CandumpWriter
    from bench.run.sinks import TRACES_FILE, FrameCollector, TraceFileSink

    kind = choose_bus(bus, box=False)  # what the run writes itself and needs (run_scenario chooses the box)

    if _TRACE is not None and "trace" not in raw:
        raw = {**raw, "trace": {f"pdo{n}": list(names) for n, names in _TRACE.items()}}
    sc = parse(raw, f"<{raw['scenario']['name']}>")
    if out is None and RUN_ROOT is not None:
        out = RUN_ROOT / sc.name
        n = 2
        while out.exists():
            out = RUN_ROOT / f"{sc.name}-{n}"
            n += 1
        RUNS_USED.append(out.name)
    frame_sinks: list[Any] = []
    sinks: list[Any] = []
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        sinks.append(TraceFileSink(out / TRACES_FILE))
        if kind.log_from_frames:  # else candump's own log is the log
            frame_sinks.append(CandumpWriter(out / "bus.log", bus))
    collector = FrameCollector() if keep_frames else None
    if collector is not None:
        frame_sinks.append(collector)
    tmp = None
    if out is None and not kind.in_process:  # a folder for candump's log and the nodes' output
        tmp = Path(tempfile.mkdtemp(prefix=f"claim-{sc.name}-"))
    try:
        res = run_scenario(sc, RunOptions(bus=bus, out=out or tmp), sinks, frame_sinks, keep_trace=True)
    finally:
        for fs in frame_sinks:
            fs.close()
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    if out is not None:
        if (out / "candump.log").exists():
            (out / "candump.log").rename(out / "bus.log")
        (out / "summary.json").write_text(json.dumps(res.summary, indent=2, default=str))
    assert res.trace is not None
    if not res.expected:  # a claim never rests on a run that went wrong (lost frames, a trip, ...)
        s = res.summary
        raise RuntimeError(
            f"run {sc.name} on {bus} ended {res.status} (expected {', '.join(sc.expect)}): "
            f"flags {s['status_flags']}, lost frames {s['bus_stats']['lost_frames']}, "
            f"periods {s['periods']} of {sc.periods}; interference {s['bus_stats']['interference']}"
        )
    return Run(res, res.trace, out, collector.frames if collector is not None else None)
