"""Boundary search: where along one key a row's condition changes, e.g. where Zhao 2022's incremental
deadbeat loop turns unstable as L/L0 falls (the error grows instead of decaying):

    --bisect controller.L_hat_ratio=1.25:1.6667 --until "error_growth_per_period>=1"

Both ends are run first and must disagree on the condition. Then each round runs as many interior points
as the cluster has workers (k-section: the interval shrinks by workers + 1 per round, not 2) until the
interval is narrower than --tol. With --grid on other keys, each grid point gets its own search (a
boundary line); their rounds run side by side.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from bench.sweep.space import SpaceError, _dec, _key_value

OPS: dict[str, Callable[[Any, Any], bool]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<=": operator.le,
    ">=": operator.ge,
    "<": operator.lt,
    ">": operator.gt,
}
_COND = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*(==|!=|<=|>=|<|>)\s*(\S+)\s*$")


@dataclass(frozen=True)
class Condition:
    """METRIC OP VALUE on a row. A number compares numerically; a metric a point does not have (a step that
    never settles: periods_to_settle) counts as +inf. A word compares as text (status!=ok)."""

    metric: str
    op: str
    value: float | str

    def __call__(self, row: dict[str, Any]) -> bool:
        v = row.get(self.metric)
        if isinstance(self.value, float):
            x = math.inf if v is None else float(v)
            return bool(OPS[self.op](x, self.value))
        if self.op not in ("==", "!="):
            raise SpaceError(f"--until {self}: {self.value!r} is a word; only == and != compare words")
        return bool(OPS[self.op](str(v), self.value))

    def __str__(self) -> str:
        return f"{self.metric}{self.op}{self.value}"


def parse_condition(text: str, metrics: tuple[str, ...]) -> Condition:
    m = _COND.match(text)
    if not m:
        raise SpaceError(
            f"--until {text!r}: expected METRIC OP VALUE, e.g. 'status!=ok' or 'error_growth_per_period>=1'"
        )
    metric, op, value = m.groups()
    if metric not in metrics and not metric.startswith("identified."):
        raise SpaceError(f"--until {text!r}: unknown metric {metric!r}; allowed: {', '.join(metrics)}, identified.*")
    try:
        num: float | str = float(value)
    except ValueError:
        num = value
    if isinstance(num, str) and op not in ("==", "!="):
        raise SpaceError(f"--until {text!r}: {value!r} is a word; only == and != compare words")
    return Condition(metric, op, num)


@dataclass
class Search:
    """The search along `key` at one grid point (`fixed`: the grid point's values)."""

    key: str
    lo: float
    hi: float
    fixed: dict[str, str]
    at_lo: bool | None = None
    at_hi: bool | None = None
    rounds: int = 0
    points: list[tuple[float, bool]] = field(default_factory=list)
    note: str | None = None

    def values(self, x: float) -> dict[str, str]:
        return {**self.fixed, self.key: repr(x)}

    def done(self, tol: float) -> bool:
        return self.note is not None or (self.at_lo is not None and self.hi - self.lo <= tol)

    def ask(self, k: int) -> list[float]:
        if self.at_lo is None:
            return [self.lo, self.hi]
        return [self.lo + (self.hi - self.lo) * i / (k + 1) for i in range(1, k + 1)]

    def tell(self, xs: list[float], results: list[bool]) -> None:
        self.points += list(zip(xs, results, strict=True))
        self.rounds += 1
        if self.at_lo is None:
            self.at_lo, self.at_hi = results[0], results[-1]
            if self.at_lo == self.at_hi:
                self.note = f"the condition is {self.at_lo} at both ends: no boundary in [{self.lo:g}, {self.hi:g}]"
            return
        lo, hi = self.lo, self.hi
        for x, r in zip(xs, results, strict=True):  # the first interior point that agrees with the far end
            if r == self.at_hi:
                hi = x
                break
            lo = x
        self.lo, self.hi = lo, hi

    def result(self) -> dict[str, Any]:
        return {
            **self.fixed,
            "key": self.key,
            "lo": self.lo,
            "hi": self.hi,
            "boundary": None if self.note else 0.5 * (self.lo + self.hi),
            "condition_at_lo": self.at_lo,
            "condition_at_hi": self.at_hi,
            "rounds": self.rounds,
            "runs": len(self.points),
            "note": self.note,
        }


def parse_bisect(item: str) -> tuple[str, float, float]:
    key, text = _key_value(item, "--bisect", "controller.L_hat_ratio=1.25:1.6667")
    parts = text.split(":")
    if len(parts) != 2:
        raise SpaceError(f"--bisect {item!r}: expected KEY=LO:HI")
    lo, hi = (float(_dec(p, f"--bisect {item}")) for p in parts)
    if not lo < hi:
        raise SpaceError(f"--bisect {item!r}: LO must be < HI")
    return key, lo, hi


def run_searches(
    engine: Any,
    text: str,
    where: str,
    fixed: list[str],
    space: Any,
    bis: tuple[str, float, float],
    cond: Condition,
    tol: float | None,
    done: dict[str, dict[str, Any]],
    writer: Any,
) -> tuple[list[dict[str, Any]], list[str], int]:
    """Every search (one per grid point) to its tolerance; rows of points already in `done` (a resumed
    study) are used, not run again. Returns the searches' results, the point order and how many ran."""
    key, lo, hi = bis
    tol = tol if tol is not None else (hi - lo) / 1000.0
    searches = [Search(key, lo, hi, g) for g in (space.points() or [{}])]
    cache = dict(done)
    order: list[str] = []
    ran = 0
    k = max(1, engine.workers // len(searches))  # interior points per search and round: the workers kept busy
    while True:
        live = [s for s in searches if not s.done(tol)]
        if not live:
            break
        asks = [(s, s.ask(k)) for s in live]
        wanted = [s.values(x) for s, xs in asks for x in xs]
        todo = [v for v in wanted if _pid(v) not in cache]
        for rows in engine.run(text, where, fixed, [[v] for v in todo]):
            writer.add(rows)
            ran += len(rows)
            for r in rows:
                cache[r["point_id"]] = r
        for s, xs in asks:
            rows = [cache[_pid(s.values(x))] for x in xs]
            order += [r["point_id"] for r in rows if r["point_id"] not in order]
            s.tell(xs, [cond(r) for r in rows])
        width = max(s.hi - s.lo for s in searches if s.note is None) if any(s.note is None for s in searches) else 0
        print(f"  round {max(s.rounds for s in searches)}: {ran} points run, widest bracket {width:.6g}", flush=True)
    return [s.result() for s in searches], order, ran


def _pid(values: dict[str, str]) -> str:
    from bench.sweep.space import point_id

    return point_id(values)
