"""What the fault checks measure of a pair of runs (the faulted and the fault-free one): the EMCYs, the
periods the plant held its command, and how the loop recovers, judged against the law's own step."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.claims import Run
from bench.eds import bits
from bench.emcy import emcy_codes

HELD = bits("plant", "Measurement", "status")["held"]  # no command frame since the previous SYNC (plant.eds)


def emcys(run: Run, name: str, node: str | None = None) -> list[dict[str, Any]]:
    """The run's EMCYs of this name (the EDS's [EmergencyCodes]: bench/emcy.py), from this node when given."""
    (code,) = emcy_codes(name)
    return [e for e in run.result.summary["emcy"] if int(e["code"], 16) == code and (node is None or e["node"] == node)]


def at(events: list[dict[str, Any]], p: int) -> bool:
    """EMCYs of one event at period p: a node sends an EMCY after the command of the same measurement, so on
    a bus it may follow the next SYNC (period p + 1); in direct mode it is always in p."""
    return bool(events) and all(e["period"] in (p, p + 1) for e in events)


def held(run: Run) -> list[int]:
    st = np.nan_to_num(run.tr["status"]).astype(np.int64)
    return run.tr["period"][(st & HELD) != 0].astype(int).tolist()


def deviation_after(a: Run, b: Run, col: str, start: int) -> float:
    pa, pb = a.tr["period"], b.tr["period"]
    n = min(len(pa), len(pb))
    m = pa[:n] >= start
    return float(np.nanmax(np.abs(a.tr[col][:n][m] - b.tr[col][:n][m]))) if m.any() else float("nan")


def settling_bound(clean: Run) -> int | None:
    """The periods the law's own fault-free step takes to enter its 2 % band (the run's step metrics), at least
    the 2 of the drive's one-period delay: a held or stale sample is a disturbance the loop absorbs in about
    that time. None when the fault-free step never settles (the check fails)."""
    steps = [s for s in clean.result.summary["steps"] if s["signal"] == "iq"]
    n = steps[0]["periods_to_settle"] if steps else None
    return None if n is None else max(2, int(n))


def recovered(hit: Run, clean: Run, p: int, step_A: float) -> dict[str, Any]:
    """The deviation of iq from the fault-free run once the law has had its settling time after the fault at
    period p, and its bound: a loop that settles within its two periods of delay (a deadbeat law) leaves no
    residual (1e-5 A: float rounding); an asymptotic one must be back inside its own 2 % band of the step."""
    n = settling_bound(clean)
    if n is None:
        return {"iq_deviation_after_recovery_A": None, "bound_A": None, "from_period": None}
    if p + 1 + n >= len(clean.tr["period"]):  # the law settles later than this run lasts: not judged
        note = f"the law's step settles in {n} periods: beyond the run's end"
        return {"iq_deviation_after_recovery_A": None, "bound_A": None, "from_period": p + 1 + n, "note": note}
    dev = deviation_after(hit, clean, "iq_A", p + 1 + n)
    return {
        "iq_deviation_after_recovery_A": dev,
        "bound_A": 1e-5 if n <= 2 else 0.02 * step_A,
        "from_period": p + 1 + n,
    }


RECOVERS = (
    "the loop recovers within its own step's settling periods (3 periods after the fault for a deadbeat law, "
    "then equal to the fault-free run to 1e-5 A; an asymptotic law: back inside its 2 % band)"
)


def back(r: dict[str, Any]) -> bool:
    return r["bound_A"] is not None and r["iq_deviation_after_recovery_A"] < r["bound_A"]


def recovery(hit: Run, clean: Run, held_at: int, step_A: float = 1.0) -> dict[str, Any]:
    """How the loop comes back after the command held over period `held_at`: its effect shows in the sample
    at held_at + 1; `periods_to_5pct` counts from there to the first sample from which |iq - iq_clean| stays
    under 5 % of the step (a digital drive's correction lands one period after it sees the error: 2 at
    best), and the time constant (periods) of what is left (a log-linear fit over 20 periods)."""
    held_at += 1
    p = hit.tr["period"]
    d = np.abs(hit.tr["iq_A"] - clean.tr["iq_A"][: len(p)])
    after = np.flatnonzero(p >= held_at)
    big = after[d[after] >= 0.05 * step_A]
    back = int(p[big[-1]] + 1) if len(big) else held_at
    tail = np.flatnonzero((p >= back) & (p < back + 20) & (d > 1e-9))
    tau = None
    if len(tail) >= 5:
        slope = np.polyfit(p[tail], np.log(d[tail]), 1)[0]
        tau = float(-1.0 / slope) if slope < 0 else None
    return {
        "periods_to_5pct": back - held_at,
        "peak_deviation_A": float(np.nanmax(d[after])),
        "residual_A": float(d[np.flatnonzero(p == back)[0]]) if back in p else None,
        "residual_time_constant_periods": tau,
    }
