"""Step-response metrics of a current trace: periods to settle, overshoot, steady-state error; and whether the
error after a step decays (error_growth: the Zhao 2022 stability claim and `bench sweep`'s error_growth_per_period)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

BAND = 0.02  # settled: within 2 % of the step size, and staying there
# The float32 floor of the loop: an error envelope below this fraction of the step has decayed.
FLOOR = 1e-5
# An error whose envelope still reaches this fraction of the step at the end has not decayed, whatever its trend:
# past the stability boundary the drive's voltage limit holds an unstable loop in a bounded cycle that no longer grows.
HELD = 0.5


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


@dataclass(frozen=True)
class ErrorGrowth:
    """How the envelope of a current error changed between two windows after a reference step (error_growth)."""

    early_A: float  # max |error| over the early window
    late_A: float  # max |error| over the late window
    ratio_per_period: float  # (late_A / early_A) ** (1 / periods between the windows' starts); 0.0 when either is 0
    decays: bool  # late_A below HELD x the step, and below early_A or down at the float32 floor (FLOOR x the step)
    at_floor: bool  # late_A below FLOOR x the step

    @property
    def per_period(self) -> float:
        """The growth per period as a study reads it, < 1 exactly when the error decays: 0.0 at the float32 floor,
        ratio_per_period while the error decays, and at least 1.0 when it does not (a cycle held by the voltage
        limit whose envelope shrinks by a hair, ratio 0.9999998, has not decayed)."""
        if self.at_floor:
            return 0.0
        return self.ratio_per_period if self.decays else max(self.ratio_per_period, 1.0)


def error_growth(err: np.ndarray, step_A: float, early: slice, late: slice) -> ErrorGrowth:
    """Whether the current error `err` (per period, either sign) decays after a reference step of `step_A`.

    It measures the envelope max |err| over two windows (`early` and `late`, slices of `err` with a start: e.g.
    the second and the last quarter after the step, growth_windows) and its geometric growth per period between
    the windows' starts. The error decays when its late envelope is below half the step and below the early
    one, or down at the loop's float32 floor. The envelope is that of the error itself, not of its swing about a
    level: a steady-state error that stays (a law that leaves one under a mismatch) reads a ratio of about 1.
    Non-finite values in a window: an infinite envelope, not decaying."""
    a, b = err[early], err[late]
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return ErrorGrowth(math.inf, math.inf, math.inf, False, False)
    m1, m2 = float(np.max(np.abs(a))), float(np.max(np.abs(b)))
    ratio = (m2 / m1) ** (1.0 / (late.start - early.start)) if m1 > 0 and m2 > 0 else 0.0
    floor = m2 < FLOOR * abs(step_A)
    return ErrorGrowth(m1, m2, ratio, bool(m2 < HELD * abs(step_A) and (m2 < m1 or floor)), bool(floor))


def growth_windows(n: int, start: int) -> tuple[slice, slice] | None:
    """The windows of error_growth in a record of n periods after a step at period `start`: the second and the last
    quarter of what follows it; None when fewer than 16 periods follow."""
    if n - start < 16:
        return None
    q = (n - start) // 4
    return slice(start + q, start + 2 * q), slice(n - q, n)
