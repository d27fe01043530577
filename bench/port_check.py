"""The port check: one scenario run twice in this process, once with a current law prototyped in Python
(bench/law_py.py) and once with the C port it stands in for, and every trace column compared period by period: per
signal the largest difference and the first period where the two part beyond a tolerance (0: bit for bit, NaN equal
to NaN).

    bench port-check examples/scenarios/complex_vector_pi_step.toml --law examples/laws/complex_vector_pi \\
        --py-law examples/laws/complex_vector_pi/prototype.py:ComplexVectorPI

A prototype that computes in float32 and a port that does the same operations agree bit for bit; the first period
they part, and on which signal, is where to look in the port. Both runs are direct runs of the same build (the law
folder's, with --law): the same plant, the same EDS, the same record."""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.scenario import Scenario, ScenarioError, add_set_argument, load, scenario_path, unselected_python_law


@dataclass
class Signal:
    """One trace column of the two runs: the largest |difference| (NaN where only one is NaN: inf), the first period
    beyond the tolerance and the first whose bits differ (None: none)."""

    name: str
    largest: float
    first_beyond: int | None
    first_bits: int | None


@dataclass
class PortReport:
    scenario: str
    law: str
    tolerance: float
    periods: tuple[int, int]  # of the Python run, of the C run
    status: tuple[str, str]
    signals: list[Signal] = field(default_factory=list)
    only_in_one: list[str] = field(default_factory=list)

    @property
    def agree(self) -> bool:
        """Both runs as long, with the same status, every column within the tolerance."""
        same = self.periods[0] == self.periods[1] and self.status[0] == self.status[1] and not self.only_in_one
        return same and all(s.first_beyond is None for s in self.signals)

    @property
    def first(self) -> Signal | None:
        """A signal that parts first beyond the tolerance, the first traced of those (None: none)."""
        parted = [s for s in self.signals if s.first_beyond is not None]
        return min(parted, key=lambda s: s.first_beyond or 0) if parted else None

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> PortReport:
        """A report `bench port-check --json` wrote."""
        signals = [
            Signal(**{**sig, "largest": math.inf if sig["largest"] is None else sig["largest"]})
            for sig in data["signals"]
        ]
        return cls(
            data["scenario"],
            data["law"],
            data["tolerance"],
            tuple(data["periods"]),  # type: ignore[arg-type]
            tuple(data["status"]),  # type: ignore[arg-type]
            signals,
            list(data["only_in_one"]),
        )

    def text(self) -> str:
        tol = "bit for bit" if self.tolerance == 0 else f"tolerance {self.tolerance:g}"
        lines = [
            f"port check of {self.law} on {self.scenario} ({tol}): Python {self.status[0]} over {self.periods[0]} "
            f"periods, C {self.status[1]} over {self.periods[1]}",
            f"{'signal':<28} {'largest |diff|':>15} {'parts at period':>16} {'first bit differs':>18}",
        ]
        for s in self.signals:
            beyond = "-" if s.first_beyond is None else str(s.first_beyond)
            bits = "-" if s.first_bits is None else str(s.first_bits)
            lines.append(f"{s.name:<28} {s.largest:>15.6g} {beyond:>16} {bits:>18}")
        lines += [f"{n:<28} traced in one run only" for n in self.only_in_one]
        first = self.first
        if self.agree:
            lines.append("the prototype and its port agree" + (" bit for bit" if self.tolerance == 0 else ""))
        elif first is not None:
            on = [s.name for s in self.signals if s.first_beyond == first.first_beyond]
            lines.append(f"they part at period {first.first_beyond}, on {', '.join(on)}")
        else:
            lines.append("they differ in length, status or traced signals")
        return "\n".join(lines)

    def expect_agree(self) -> PortReport:
        """AssertionError with the report when they do not agree (for a test)."""
        __tracebackhide__ = True
        if not self.agree:
            raise AssertionError(self.text())
        return self


def _column_bits(col: np.ndarray) -> np.ndarray:
    col = np.ascontiguousarray(col)
    return col.view(f"u{col.dtype.itemsize}") if col.dtype.kind in "fiu" else col


def compare(py: np.ndarray, c: np.ndarray, tolerance: float) -> tuple[list[Signal], list[str]]:
    """Every column both runs traced (but period and t_s), over the periods both have."""
    names_py, names_c = py.dtype.names or (), c.dtype.names or ()
    n = min(len(py), len(c))
    periods = py["period"][:n] if "period" in names_py else np.arange(n)
    out = []
    for name in (x for x in names_py if x in names_c and x not in ("period", "t_s")):
        a, b = py[name][:n].astype(np.float64), c[name][:n].astype(np.float64)
        both_nan = np.isnan(a) & np.isnan(b)
        diff = np.where(both_nan, 0.0, np.abs(a - b))
        diff = np.where(np.isnan(diff), np.inf, diff)  # one NaN, the other not
        beyond = np.flatnonzero(diff > tolerance)
        bits = np.flatnonzero(_column_bits(py[name][:n]) != _column_bits(c[name][:n]))
        out.append(
            Signal(
                name,
                float(diff.max()) if n else 0.0,
                int(periods[beyond[0]]) if len(beyond) else None,
                int(periods[bits[0]]) if len(bits) else None,
            )
        )
    only = sorted(set(names_py) ^ set(names_c))
    return out, only


def port_check(sc: Scenario, py_law: Any, tolerance: float = 0.0) -> PortReport:
    """`sc` run with the Python law `py_law` and with the registered law it stands in for, compared."""
    from bench.run import RunOptions, TraceRows, run_scenario

    if not tolerance >= 0:  # NaN too: no difference is beyond it, and everything would agree
        raise ScenarioError(f"tolerance = {tolerance}: must be >= 0 (0: bit for bit)")

    runs = []
    for law in (py_law, None):
        rows = TraceRows()
        res = run_scenario(sc, RunOptions(bus="direct", py_law=law), sinks=[rows], envelopes=False)
        empty = np.zeros(0, dtype=[("period", "<i8")])
        runs.append((res, rows.rows if rows.rows is not None else empty))
    (res_py, py), (res_c, c) = runs
    signals, only = compare(py, c, tolerance)
    return PortReport(sc.name, py_law.law, tolerance, (len(py), len(c)), (res_py.status, res_c.status), signals, only)


def arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", type=scenario_path, help="scenario TOML file (it must select the law)")
    add_set_argument(p, "override a scenario value (repeatable), as bench run --set")
    p.add_argument(
        "--py-law",
        required=True,
        metavar="FILE.py:CLASS",
        help="the prototype: a class with the C interface's face whose `law` names its C port (bench run --py-law)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=0.0,
        help="largest |difference| that is agreement, in each signal's unit (default 0: bit for bit)",
    )
    p.add_argument("--json", type=Path, default=None, metavar="FILE", help="also write the report as JSON")


def cmd_port_check(args: argparse.Namespace) -> int:
    """Exit 0: they agree; 1: they part (the report says where); 2: bad input."""
    from bench.law_py import LawError, checked

    try:
        if not args.tolerance >= 0:
            raise ScenarioError(f"--tolerance = {args.tolerance}: must be >= 0 (0: bit for bit)")
        sc = load(args.scenario, args.overrides)
        law = checked(None, args.py_law)
        if (unselected := unselected_python_law(sc, law.law)) is not None:
            raise ScenarioError(unselected)
    except (ScenarioError, LawError) as exc:
        print(f"bench port-check: {exc}", file=sys.stderr)
        return 2
    report = port_check(sc, law, args.tolerance)
    print(report.text())
    if args.json is not None:
        data = {**asdict(report), "agree": report.agree}
        for sig in data["signals"]:  # JSON has no infinity: a NaN in one run only
            sig["largest"] = None if sig["largest"] == float("inf") else sig["largest"]
        args.json.write_text(json.dumps(data, indent=2))
    return 0 if report.agree else 1
