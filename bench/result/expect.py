"""Assertions that read like a control engineer's spec, on a run's result (HilRun, or anything with its fields):

    expect_status(run, "ok")                          # the run's status (none given: the one its scenario expects)
    expect_settles_within(run, 3)                     # every step settles within 3 periods (2 % band)
    expect_overshoot_below(run, 5.0, signal="iq")     # the iq steps overshoot by less than 5 % of the step
    expect_steady_state_error_below(run, 0.01)        # |steady-state error| below 0.01 A on every step
    expect_no_emcy(run)                               # no node sent an EMCY message

Each raises AssertionError whose message gives the measured value, the bound, the step (signal, period,
from → to) and the run folder; HilRun's methods of the same names call these. No helper passes vacuously: a
run without the steps asked for, or a figure the run could not measure, fails.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from bench.result.steps import Step, fmt

__all__ = [
    "expect_no_emcy",
    "expect_overshoot_below",
    "expect_settles_within",
    "expect_status",
    "expect_steady_state_error_below",
]


class Measured(Protocol):
    """What the helpers read of a run (HilRun has it)."""

    folder: Path | None  # None: a run without files (bench.api.run without out=)
    exit_code: int
    status: str
    summary: dict[str, Any]
    steps: list[Step]


def _fail(lines: list[str], run: Measured) -> None:
    __tracebackhide__ = True
    where = run.folder if run.folder is not None else "in memory, no files (bench.api.run(..., out=DIR) writes them)"
    raise AssertionError("\n".join(lines) + f"\nRun: {where}")


def _steps(run: Measured, signal: str | None, what: str) -> list[Step]:
    """The steps a check covers: all, or those of `signal`; none is a failure (a bound on nothing is no check)."""
    __tracebackhide__ = True
    chosen = [s for s in run.steps if signal is None or s.signal == signal]
    if not chosen:
        have = ", ".join(s.describe() for s in run.steps) or "none"
        which = "reference step" if signal is None else f"{signal} step"
        _fail([f"no {which} to check {what} on; the run's steps: {have}"], run)
    return chosen


def _check_steps(
    run: Measured, signal: str | None, what: str, verdict: Callable[[Step], str | None], bound: str
) -> None:
    """Fails with one line per step whose `verdict` (None when the step meets the bound, else what it measured)."""
    __tracebackhide__ = True
    bad = [f"{s.describe()} {v}" for s in _steps(run, signal, what) if (v := verdict(s)) is not None]
    if bad:
        _fail([f"{line}; bound: {bound}." for line in bad], run)


def _bound(x: float, what: str) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float) or not x >= 0:
        raise ValueError(f"{what}: expected a number >= 0, got {x!r}")
    return float(x)


def expect_status(run: Measured, *statuses: str) -> None:
    """The run ended with one of `statuses` (ok, tripped, diverged, non_finite, frames_lost, node_lost,
    interference, law_fault, realtime_overrun, plant_fault); with none given, with a status its scenario expects
    (`scenario.expect`: exit 0)."""
    __tracebackhide__ = True
    got = f"the run's status is {run.status} (exit status {run.exit_code})"
    if statuses:
        if run.status not in statuses:
            _fail([f"{got}; expected: {' or '.join(statuses)}."], run)
        return
    expected = run.summary.get("expect") or ["ok"]
    if not run.summary.get("status_expected", run.exit_code == 0):
        _fail([f"{got}; expected: {' or '.join(map(str, expected))} (the scenario's expect)."], run)


def expect_settles_within(run: Measured, periods: int, signal: str | None = None) -> None:
    """Every step (of `signal`) settles, into the 2 % band and staying there, within `periods` periods."""
    __tracebackhide__ = True
    if isinstance(periods, bool) or not isinstance(periods, int) or periods < 0:
        raise ValueError(f"expect_settles_within: expected a whole number of periods >= 0, got {periods!r}")
    unit = "period" if periods == 1 else "periods"

    def verdict(s: Step) -> str | None:
        if s.periods_to_settle is None:
            window = f" of its {s.window_periods}-period window" if s.window_periods else ""
            return f"never settles (it is still outside the 2 % band at the end{window})"
        if s.periods_to_settle > periods:
            return f"settles in {s.periods_to_settle} periods"
        return None

    _check_steps(run, signal, "settling", verdict, f"within {periods} {unit}")


def expect_overshoot_below(run: Measured, percent: float, signal: str | None = None) -> None:
    """Every step (of `signal`) overshoots its target by less than `percent` % of the step's size."""
    __tracebackhide__ = True
    bound = _bound(percent, "expect_overshoot_below")

    def verdict(s: Step) -> str | None:
        if s.overshoot_pct is None:
            return "has no measured overshoot (not a finite number in summary.json)"
        if not s.overshoot_pct < bound:
            amps = "" if s.overshoot_A is None else f" ({fmt(s.overshoot_A)} A)"
            return f"overshoots by {fmt(s.overshoot_pct)} %{amps}"
        return None

    _check_steps(run, signal, "the overshoot", verdict, f"below {bound:g} %")


def expect_steady_state_error_below(run: Measured, amps: float, signal: str | None = None) -> None:
    """Every step (of `signal`) ends with a steady-state error smaller than `amps` A in magnitude."""
    __tracebackhide__ = True
    bound = _bound(amps, "expect_steady_state_error_below")

    def verdict(s: Step) -> str | None:
        if s.steady_state_error_A is None:
            return "has no measured steady-state error (not a finite number in summary.json)"
        if not abs(s.steady_state_error_A) < bound:
            return f"has a steady-state error of {fmt(s.steady_state_error_A)} A"
        return None

    _check_steps(run, signal, "the steady-state error", verdict, f"below {bound:g} A in magnitude")


def expect_no_emcy(run: Measured) -> None:
    """No node sent an EMCY message during the run (summary.json `emcy`)."""
    __tracebackhide__ = True
    emcy = run.summary.get("emcy")
    if emcy is None:
        _fail(["the run's summary has no emcy list to check"], run)
    elif emcy:
        shown = ", ".join(f"{e.get('node')} {e.get('code')} at period {e.get('period')}" for e in emcy[:6])
        more = f" (and {len(emcy) - 6} more)" if len(emcy) > 6 else ""
        _fail([f"the run saw {len(emcy)} EMCY message(s): {shown}{more}; expected: none."], run)
