"""One reference step of a run as summary.json gives it (bench/metrics.py measures it): the figures a control
engineer's spec bounds, and how a message names the step."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Step:
    """A step of a reference (summary.json `steps[]`): settling in periods (None: it never settles within its
    window, the 2 % band of bench/metrics.py), overshoot in % of the step and in A, steady-state error in A
    (signed: measured - reference over the last fifth of the window)."""

    signal: str
    at_period: int
    from_A: float
    to_A: float
    periods_to_settle: int | None
    overshoot_pct: float | None
    overshoot_A: float | None
    steady_state_error_A: float | None
    window_periods: int | None = None
    extra: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_summary(cls, d: dict[str, Any]) -> Step:
        known = {f for f in cls.__dataclass_fields__ if f != "extra"}
        return cls(
            signal=str(d.get("signal", "?")),
            at_period=int(d.get("at_period", -1)),
            from_A=float(d.get("from_A", math.nan)),
            to_A=float(d.get("to_A", math.nan)),
            periods_to_settle=None if d.get("periods_to_settle") is None else int(d["periods_to_settle"]),
            overshoot_pct=_number(d.get("overshoot_pct")),
            overshoot_A=_number(d.get("overshoot_A")),
            steady_state_error_A=_number(d.get("steady_state_error_A")),
            window_periods=None if d.get("window_periods") is None else int(d["window_periods"]),
            extra={k: v for k, v in d.items() if k not in known},
        )

    def describe(self) -> str:
        """'iq step at period 20 (0.00 → 1.00 A)'."""
        return f"{self.signal} step at period {self.at_period} ({self.from_A:.2f} → {self.to_A:.2f} A)"


def _number(v: Any) -> float | None:
    """A figure of summary.json: None when absent or not a finite number (the JSON writer's null)."""
    if v is None:
        return None
    x = float(v)
    return x if math.isfinite(x) else None


def fmt(x: float) -> str:
    """A measured figure, 3 significant digits (59.5, 0.0261, 1.2e-05)."""
    return f"{x:.3g}"
