"""A real-time run (scenario.timing = "realtime": the plant's Run control.mode is `realtime`) in numbers:
summary.json's "realtime" block, and what the status realtime_overrun rests on. Lockstep runs have no block.

    "realtime": {
      "period_us": the plant's period Ts, in us, as its deadline grid has it (round(Ts_s * 1e9) ns),
      "plant": the plant's own measurement: every entry of plant.eds "Realtime timing" (0x2007) by its EDS name,
               read by SDO at the end of the run (so it is in the log), and Run control's missed_commands and
               late_commands,
      "bus": what the frames' time stamps show (null when the decoder gave no time stamps)}

The bus view, per period k (a run is split into segments at its holds, the master's writes of Run control.
run_periods: the plant starts a new deadline grid after each):
  SYNC lateness   l_k = (t_k - k Ts) - min_j (t_j - j Ts), j over the segment's SYNCs: the ideal grid anchored so
                  that the segment's earliest SYNC is on time (the bus shows when SYNCs went out, not the plant's
                  deadlines: the plant's own figures include its wake-up latency, these do not);
  SYNC interval   t_k - t_(k-1), within a segment;
  turnaround      the time stamp of period k's voltage command minus that of SYNC k; a command that came after
                  SYNC k+1 is not its period's (the decoder counts it missing): an overrun here;
each as min, mean, p50, p99, p99_9, max (percentiles by nearest rank: the smallest value with at least that share
of the values at or below it); with them "periods" (SYNCs timed), "segments" (each one's first period and Ts),
"commands_timed", "overruns" (periods whose command was not on the bus before the next SYNC), "sync_overruns"
(SYNCs more than a period late on their grid), "worst_period" (the latest SYNC's), "overrun_causes" (each period
that missed its deadline by its cause: CAUSES, `causes`) and "first_overrun_period" (the first of either kind:
where a realtime_overrun status is placed among the others). A direct run adds "floor": the host's own wake-up
lateness at Ts, probed before the run (bench/run/loop/direct_loop.py). Time stamps are the
recorder's (candump: the kernel's; direct real time: the in-process bus's monotonic clock) and bus.log keeps them
to the microsecond, so `bench replay` of the log gives the same figures as the run.

The view's processes (bench/view/) import this module for the per-period figures: what needs the EDS (canopen) is
imported where it is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.run.verdict.stats import Envelope

if TYPE_CHECKING:
    from bench.run.decode.decoder import Decoder

# The decoder's per-period columns in real-time runs (not trace signals: traces.npy does not keep them): the time
# stamp, in us, of the period's SYNC and of its voltage command (NaN where the period has none).
SYNC_T, COMMAND_T = "sync_t_us", "command_t_us"
TIMING_COLUMNS = (SYNC_T, COMMAND_T)
STATS = ("min", "mean", "p50", "p99", "p99_9", "max")
QUANTILES = {"p50": 0.5, "p99": 0.99, "p99_9": 0.999}
# The overview's timing panel (bench/view/plots.py) takes its series from the run's envelopes under these names:
# the bus-side lateness and turnaround per bucket of periods, and the plant's figures (PLANT_FIGURES) as constants.
ENVELOPE = "realtime."
LATENESS_ENV, TURNAROUND_ENV = ENVELOPE + "sync_lateness_us", ENVELOPE + "turnaround_us"
PLANT_ENV = ENVELOPE + "plant."
PLANT_FIGURES = ("sync_lateness_p99_us", "sync_lateness_max_us", "turnaround_p99_us", "turnaround_max_us")


def _number(v: float | None) -> float | int | None:
    """An entry's value as JSON shows it best: an integer, or a REAL32 by its shortest decimal (13.014, not
    13.013999938964844: the same float32)."""
    if v is None:
        return None
    if float(v).is_integer() and abs(v) < 2**53:
        return int(v)
    return float(np.format_float_positional(np.float32(v), unique=True, trim="-"))


def is_realtime(dec: Decoder) -> bool:
    """The run's plant ran in real time (Run control.mode as the bus showed it)."""
    from bench.eds import enum

    if not dec.hil:
        return False
    return dec.sdo.plant.get("Run control", "mode") == enum("plant", "Run control", "mode")["realtime"]


def period_us(ts_s: float) -> float:
    """The plant's period in us as its deadline grid has it: Ts_s rounded to whole nanoseconds (plant_app.c)."""
    return math.floor(float(ts_s) * 1e9 + 0.5) / 1e3


# ---------------------------------------------------------------------------------------------- segments
def segments(dec: Decoder) -> list[tuple[int, float]]:
    """(first period, Ts in us) of each segment: the loop's start and every run_periods write after it (the plant
    holds before it and restarts its deadline grid after), with the Ts in effect then."""
    starts = [p for p, v in dec.sdo.changes("Run control.run_periods", node="plant") if v > 0]
    return _segments(starts, dec.sdo.changes("Inverter.Ts_s", node="plant"), dec.ts_s)


def _segments(starts: list[int], ts_changes: list[tuple[int, float]], ts0_s: float) -> list[tuple[int, float]]:
    out = []
    for s in sorted({0, *starts}):
        before = [v for p, v in ts_changes if p <= s]
        out.append((s, period_us(before[-1] if before else ts0_s)))
    return out


def summary_segments(summary: dict[str, Any]) -> list[tuple[int, float]] | None:
    """The segments a summary's realtime block names (None: not a real-time run, or no bus view)."""
    bus = (summary.get("realtime") or {}).get("bus") or {}
    segs = bus.get("segments")
    return [(int(s["from_period"]), float(s["period_us"])) for s in segs] if segs else None


# ---------------------------------------------------------------------------------------------- per period
@dataclass
class PerPeriod:
    period: np.ndarray  # int64
    lateness: np.ndarray  # us; NaN: no SYNC in the period
    interval: np.ndarray  # us since the segment's SYNC before; NaN at a segment's start or beside a lost SYNC
    turnaround: np.ndarray  # us; NaN: no SYNC or no command in the period
    missing: np.ndarray  # bool: a SYNC and no command before the next one
    sync_late: np.ndarray  # bool: the SYNC more than one period late on its segment's grid
    ts: np.ndarray | None = None  # us: the period of each period's segment


_WINDOW = 65_536


def _lateness(seg: np.ndarray, off: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Each SYNC's lateness on the plant's deadline grid, which the plant starts afresh in two cases
    (plant_pacing.c): at each segment, and after a SYNC more than 101 periods late ("far behind: re-grid": its next
    deadline is then that SYNC's time + Ts, i.e. the new grid's offset t_k - k Ts is that SYNC's). A segment's first
    grid is anchored so that its earliest SYNC is on time. `off`: t_k - k Ts; `ts`: Ts of each SYNC's segment."""
    lat = np.full(len(off), np.nan)
    ok = np.isfinite(off)
    bounds = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1], True])
    for s0, s1 in zip(bounds[:-1], bounds[1:], strict=True):
        start, anchor = int(s0), None
        while start < s1:
            o, good = off[start:s1], ok[start:s1]
            if not good.any():
                break
            if anchor is None:  # the segment's first grid: anchored on its earliest SYNC before a re-grid
                a = float(np.min(o[good]))
                for _ in range(3):
                    far = np.flatnonzero(good & (o - a > 101 * ts[start]))
                    a2 = float(np.min(o[: far[0] + 1][good[: far[0] + 1]])) if len(far) else float(np.min(o[good]))
                    if a2 == a:
                        break
                    a = a2
                anchor = a
            w = min(len(o), _WINDOW)  # in windows: a run with many re-grids stays linear in its periods
            far = np.flatnonzero(good[:w] & (o[:w] - anchor > 101 * ts[start]))
            end = start + (int(far[0]) + 1 if len(far) else w)
            lat[start:end] = off[start:end] - anchor
            if len(far):
                anchor = float(off[end - 1])  # the late SYNC's own time is the new grid's origin
            start = end
    return lat


def per_period(period: np.ndarray, sync_t: np.ndarray, cmd_t: np.ndarray, segs: list[tuple[int, float]]) -> PerPeriod:
    """The bus-side timing of each period from its SYNC's and command's time stamps (any common origin: subtract
    one first so that float64 keeps them to the nanosecond); `segs` as `segments` gives them."""
    period = np.asarray(period, dtype=np.int64)
    sync_t, cmd_t = np.asarray(sync_t, dtype=np.float64), np.asarray(cmd_t, dtype=np.float64)
    starts = np.array([s for s, _ in segs] or [0], dtype=np.int64)
    ts = np.array([t for _, t in segs] or [np.nan], dtype=np.float64)
    seg = np.clip(np.searchsorted(starts, period, side="right") - 1, 0, None)
    off = sync_t - period * ts[seg]
    lateness = _lateness(seg, off, ts[seg])
    interval = np.full(len(period), np.nan)
    if len(period) > 1:
        same = (np.diff(period) == 1) & (seg[1:] == seg[:-1])
        interval[1:][same] = np.diff(sync_t)[same]
    with np.errstate(invalid="ignore"):
        sync_late = np.nan_to_num(lateness, nan=-np.inf) > ts[seg]
    missing = np.isfinite(sync_t) & ~np.isfinite(cmd_t)
    return PerPeriod(period, lateness, interval, cmd_t - sync_t, missing, sync_late, ts[seg])


# Where an overrun's period went, by the larger share of it (the plant's SYNC lateness against the time from the
# SYNC to the command): the names of summary.json realtime.bus.overrun_causes and of the console's line.
CAUSES = {
    "plant_late": "the plant's SYNC went out late (the plant woke or worked late)",
    "drive_late": "the drive's command came after the deadline (the drive or its way to the bus)",
    "drive_missing": "no command before the next SYNC (a drive frozen, lost or slower than a period)",
    "bus_late": "counted by the plant, yet in time on the bus's stamps: the way from the bus to the plant (a bridge, "
    "an adapter; in direct mode, where there is none, the bus view's grid, anchored on the earliest SYNC, a few us "
    "off the plant's deadlines)",
}


def causes(pp: PerPeriod) -> dict[str, int]:
    """Each period that missed its deadline (its command not in by the next SYNC's ideal time, on the bus) by its
    cause: `plant_late` when the SYNC's lateness took the larger share of the period (a missing command: at least
    half of it), else `drive_late` (a command after the deadline) or `drive_missing` (none before the next SYNC).
    `bus_late` is the plant's own count beyond these (block): the bus cannot see it."""
    if pp.ts is None or not len(pp.period):
        return dict.fromkeys(CAUSES, 0)
    lat = np.nan_to_num(pp.lateness, nan=0.0)
    with np.errstate(invalid="ignore"):
        late_cmd = np.isfinite(pp.turnaround) & (lat + pp.turnaround > pp.ts)
        plant = (late_cmd & (lat >= pp.turnaround)) | (pp.missing & (2 * lat >= pp.ts))
    return {
        "plant_late": int(plant.sum()),
        "drive_late": int((late_cmd & ~plant).sum()),
        "drive_missing": int((pp.missing & ~plant).sum()),
        "bus_late": 0,
    }


def stats(x: np.ndarray) -> dict[str, float | None]:
    """min, mean, p50, p99, p99_9, max of the finite values (nearest rank), in us to the nanosecond; None when none."""
    v = np.sort(np.asarray(x, dtype=np.float64)[np.isfinite(x)])
    if len(v) == 0:
        return dict.fromkeys(STATS)
    out = {"min": v[0], "mean": float(v.mean())}
    out |= {k: v[max(0, math.ceil(q * len(v) - 1e-9) - 1)] for k, q in QUANTILES.items()}
    out["max"] = v[-1]
    return {k: round(float(out[k]), 3) for k in STATS}


class BusTiming:
    """The timing columns of a run's trace chunks, kept whole (24 bytes a period, real-time runs only: the
    anchor of a segment's grid and the percentiles need all of its periods)."""

    def __init__(self) -> None:
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def add(self, chunk: dict[str, np.ndarray]) -> None:
        if SYNC_T not in chunk:
            return
        sync = np.asarray(chunk[SYNC_T], dtype=np.float64)
        cmd = np.asarray(chunk[COMMAND_T], dtype=np.float64) if COMMAND_T in chunk else np.full(len(sync), np.nan)
        self._parts.append((np.asarray(chunk["period"], dtype=np.int64), sync, cmd))

    def __bool__(self) -> bool:
        return bool(self._parts)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(period, SYNC time, command time), the times in us from the first SYNC's (exact: whole microseconds)."""
        if not self._parts:
            empty = np.zeros(0)
            return empty.astype(np.int64), empty, empty
        period, sync, cmd = (np.concatenate(p) for p in zip(*self._parts, strict=True))
        self._parts = [(period, sync, cmd)]
        finite = sync[np.isfinite(sync)]
        ref = float(finite[0]) if len(finite) else 0.0
        return period, sync - ref, cmd - ref

    def per_period(self, segs: list[tuple[int, float]]) -> PerPeriod:
        return per_period(*self.arrays(), segs)


def bus_view(pp: PerPeriod, segs: list[tuple[int, float]]) -> dict[str, Any]:
    """The "bus" block from the periods' timing."""
    lat = pp.lateness
    worst = int(pp.period[np.nanargmax(lat)]) if np.isfinite(lat).any() else None
    over = np.flatnonzero(pp.missing | pp.sync_late)
    return {
        "periods": int(np.isfinite(lat).sum()),
        "segments": [{"from_period": s, "period_us": t} for s, t in segs],
        "sync_lateness_us": stats(lat),
        "sync_interval_us": stats(pp.interval),
        "turnaround_us": stats(pp.turnaround),
        "commands_timed": int(np.isfinite(pp.turnaround).sum()),
        "overruns": int(pp.missing.sum()),  # periods whose command was not on the bus before the next SYNC
        "sync_overruns": int(pp.sync_late.sum()),  # SYNCs more than one period late on the grid
        "worst_period": worst,
        "overrun_causes": causes(pp),
        "first_overrun_period": int(pp.period[over[0]]) if len(over) else None,
    }


# ---------------------------------------------------------------------------------------------- the plant's
def plant_view(dec: Decoder) -> dict[str, float | int | None]:
    """The plant's timing record as read at the end of the run (every entry the master reads: REALTIME_READS),
    and Run control's missed and late commands."""
    from bench.run.loop.reads import REALTIME_READS

    _, record, entries = REALTIME_READS
    plant = dec.sdo.plant
    out = {n: _number(plant.get(record, n)) for n in entries}
    for n in ("missed_commands", "late_commands"):
        out[n] = _number(plant.get("Run control", n))
    return out


# ---------------------------------------------------------------------------------------------- the block
def block(dec: Decoder, bus: dict[str, Any] | None) -> dict[str, Any] | None:
    """summary.json's "realtime" (None in lockstep); `bus`: `bus_view` of the run's chunks (None: no time stamps)."""
    if not is_realtime(dec):
        return None
    plant = plant_view(dec)
    if bus and "overrun_causes" in bus:  # what the plant counted beyond what the bus shows: late on the way to it
        seen = sum(bus["overrun_causes"].values())
        bus["overrun_causes"]["bus_late"] = max(0, int(plant.get("overruns") or 0) - seen)
    return {"period_us": period_us(dec.ts_s), "plant": plant, "bus": bus}


def overran(rt: dict[str, Any] | None) -> bool:
    """The plant counted an overrun: a command not at the plant by the next SYNC deadline, or a SYNC more than
    one period late (status realtime_overrun)."""
    plant = (rt or {}).get("plant") or {}
    return bool(plant.get("overruns")) or bool(plant.get("sync_overruns"))


def first_overrun(rt: dict[str, Any], first_lost: int | None) -> int | None:
    """The period the overruns began, as the bus shows it: its first period whose command was not on the bus
    before the next SYNC, or whose SYNC was a period late. Without time stamps, the first period with a lost
    frame (in real time a command that misses its period is missing from it)."""
    bus = rt.get("bus")
    if bus and bus.get("periods") and bus.get("first_overrun_period") is not None:
        return int(bus["first_overrun_period"])
    return first_lost  # also when only the plant saw it (a command after its deadline, before a late SYNC)


def envelopes(pp: PerPeriod, plant: dict[str, Any]) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The overview's timing series: lateness and turnaround per bucket of periods (as every signal's envelope),
    and the plant's figures each as a one-bucket constant."""
    out = {}
    for name, x in ((LATENESS_ENV, pp.lateness), (TURNAROUND_ENV, pp.turnaround)):
        env = Envelope()
        env.add(x)
        out[name] = env.arrays()
    for name in PLANT_FIGURES:
        v = plant.get(name)
        if v is not None:
            out[PLANT_ENV + name] = (np.zeros(1), np.full(1, float(v)), np.full(1, float(v)))
    return out
