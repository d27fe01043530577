"""The papers' quantitative claims, each run on the bench and judged.

A claim module runs scenarios through the same capture path as `bench run` (over vcan
or in direct mode) and returns :class:`ClaimResult` records: what the paper states, what
the bench measured, the tolerance, the verdict and why they differ where they do.
Tests assert on them; `bench reproduce` reports them.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..layout import BusLayout
from ..runner import Capture, RunOptions, capture
from ..scenario import parse
from ..traces import decode


@dataclass
class ClaimResult:
    paper: str               # "You 2019"
    claim_id: str            # "you2019-1a"
    figure: str              # "Fig. 8 / Eq. 20-21"
    statement: str           # what the paper says
    paper_value: Any
    bench_value: Any
    tolerance: str
    reproduced: bool         # the bench agrees with the paper's statement within the tolerance
    why_differs: str = ""
    details: dict[str, Any] = field(default_factory=dict)
    plots: list[str] = field(default_factory=list)
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
    cap: Capture
    tr: dict[str, np.ndarray]
    out: Path


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


def run_raw(raw: dict[str, Any], bus: str, out: Path | None = None) -> Run:
    """Run a scenario given as a TOML-shaped dict on `bus` ('direct' or a CAN channel)."""
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
    out = out or Path(tempfile.mkdtemp(prefix=f"claim-{sc.name}-"))
    cap = capture(sc, RunOptions(bus=bus, out=out))
    frames = np.load(out / "frames.npy")
    tr = decode(frames, BusLayout.load(out / "layout.json"), int(cap.plant["pole_pairs"]), cap.plant["Ts_s"],
                cap.references)
    return Run(cap, tr, out)
