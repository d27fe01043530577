"""Step-response metrics of a current trace: periods to settle, overshoot, steady-state error."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

BAND = 0.02  # settled: within 2 % of the step size, and staying there


@dataclass
class StepMetrics:
    signal: str
    at_period: int
    from_A: float
    to_A: float
    periods_to_settle: int | None  # periods after the step until the current stays within the band
    overshoot_A: float
    overshoot_pct: float
    steady_state_error_A: float
    window_periods: int
    # peak-to-peak of the error over the last fifth of the window (streamed runs only; None elsewhere):
    # a loop that never settles and still swings by half its step there is oscillating, not slow
    tail_peak_to_peak_A: float | None = None

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def step_metrics(x: np.ndarray, ref: np.ndarray, signal: str, min_step_A: float = 1e-6) -> list[StepMetrics]:
    """One record per change of `ref`, measured on `x` until the next change (or the end)."""
    changes = [int(i) + 1 for i in np.nonzero(np.abs(np.diff(ref)) > min_step_A)[0]]
    out = []
    for j, p in enumerate(changes):
        end = changes[j + 1] if j + 1 < len(changes) else len(ref)
        r0, r1 = float(ref[p - 1]), float(ref[p])
        step = r1 - r0
        seg = x[p:end]
        if len(seg) < 3 or np.isnan(seg).all():
            continue
        band = BAND * abs(step)
        outside = np.nonzero(~(np.abs(seg - r1) <= band))[0]
        settle = None if len(outside) and outside[-1] == len(seg) - 1 else (int(outside[-1]) + 1 if len(outside) else 0)
        over = float(np.nanmax(np.sign(step) * (seg - r1)))
        over = max(over, 0.0)
        tail = seg[len(seg) - max(1, len(seg) // 5) :]
        out.append(
            StepMetrics(
                signal, p, r0, r1, settle, over, 100.0 * over / abs(step), float(np.nanmean(tail - r1)), len(seg)
            )
        )
    return out
