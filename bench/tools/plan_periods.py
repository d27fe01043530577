"""A run's bus.log cut into the loop's periods, for `bench plan --from-log` (bench/tools/plan_log.py): which
identifiers are the loop's (the SYNC, each node's TPDOs and which of them the other node consumes, from the EDS
files at the run's node-IDs), where each period starts (at each SYNC; in a run without SYNC frames, issue 54's
[frames] period_mark = "measurement", at each of the plant's measurement frames that carry the period's sample) and
which frames are left out (the configuration before the first period, the teardown after the loop)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can


class LogPlanError(ValueError):
    """A log or an input the simulation cannot use; the message names it."""


@dataclass(frozen=True)
class LoopIds:
    """COB-IDs of the loop: the SYNC, each node's TPDOs, and which of them the other node consumes."""

    sync: int
    plant: frozenset[int]
    drive: frozenset[int]
    measurement: frozenset[int]  # plant TPDOs the drive receives
    command: frozenset[int]  # drive TPDOs the plant receives


def loop_ids(plant_id: int, drive_id: int) -> LoopIds:
    """The loop's COB-IDs from the EDS files (every TPDO, enabled or not: a run may enable one by SDO). Which plant
    TPDOs the drive consumes (and the reverse) is read at the EDS's own node-IDs, where each node's RPDOs name the
    other's TPDOs, and carried by TPDO number to the run's IDs (the bench points the RPDOs there by SDO)."""
    from bench.eds import default_node_id
    from bench.eds import load as load_od

    def cobs(od: Any, base: int, valid_only: bool) -> dict[int, int]:
        out = {}
        for n in range(4):
            try:
                value = int(od[base + n][1].default)
            except KeyError:
                continue
            if not (valid_only and value & 0x80000000):
                out[n] = value & 0x7FF
        return out

    plant0, drive0 = load_od("plant", default_node_id("plant")), load_od("drive", default_node_id("drive"))
    measured = {n for n, c in cobs(plant0, 0x1800, False).items() if c in cobs(drive0, 0x1400, True).values()}
    commanding = {n for n, c in cobs(drive0, 0x1800, False).items() if c in cobs(plant0, 0x1400, True).values()}
    plant, drive = load_od("plant", plant_id), load_od("drive", drive_id)
    p_tx, d_tx = cobs(plant, 0x1800, False), cobs(drive, 0x1800, False)
    measurement = {c for n, c in p_tx.items() if n in measured}
    command = {c for n, c in d_tx.items() if n in commanding}
    sync = int(plant[0x1005].default) & 0x7FF
    p, d = frozenset(p_tx.values()), frozenset(d_tx.values())
    return LoopIds(sync, p, d, frozenset(measurement) or p, frozenset(command) or d)


def run_node_ids(log: Path) -> tuple[int, int, str]:
    """(plant, drive, where from): summary.json beside the log when it records node_ids, else the EDS defaults."""
    from bench.eds import default_node_id

    summary = _summary(log)
    ids = summary.get("node_ids") if summary else None
    if isinstance(ids, dict) and isinstance(ids.get("plant"), int) and isinstance(ids.get("drive"), int):
        return ids["plant"], ids["drive"], "summary.json"
    return default_node_id("plant"), default_node_id("drive"), "the EDS defaults"


def run_ts(log: Path) -> float | None:
    """The run's control period from summary.json beside the log, None when there is none."""
    summary = _summary(log)
    ts = summary.get("Ts_s") if summary else None
    return float(ts) if isinstance(ts, (int, float)) and math.isfinite(ts) and ts > 0 else None


def _summary(log: Path) -> dict[str, Any] | None:
    path = log.parent / "summary.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


@dataclass
class Periods:
    periods: list[list[can.Message]]
    before: int  # frames before the first SYNC (configuration), left out
    after: int  # frames after the last period's loop frames (teardown), left out
    frames: int
    mark: int  # the identifier that starts each period: the SYNC's, or the plant's measurement frame


def read_periods(log: Path, ids: LoopIds) -> Periods:
    """The log's frames cut at each SYNC, or, in a log without any, at each of the plant's first measurement TPDO
    (python-can's log reader: candump -l, FD frames `id##Fdata` too)."""
    try:
        messages = [m for m in can.LogReader(str(log)) if not m.is_error_frame]
    except (OSError, ValueError) as exc:
        raise LogPlanError(f"{log}: not a CAN log python-can reads ({exc})") from exc

    def at(cob: int) -> list[int]:
        return [i for i, m in enumerate(messages) if m.arbitration_id == cob and not m.is_extended_id]

    mark, starts = ids.sync, at(ids.sync)
    sent = {m.arbitration_id for m in messages if not m.is_extended_id} & ids.measurement
    if sent and len(starts) < len(at(min(sent))) // 2:  # (almost) no SYNC: the measurement frame marks the period
        mark = min(sent)
        starts = at(mark)
    if not starts:
        raise LogPlanError(
            f"{log}: no SYNC (COB-ID 0x{ids.sync:03X}) and no measurement frame of the plant among its "
            f"{len(messages)} frames: nothing to cut into periods"
        )
    loop = ids.plant | ids.drive
    tail = messages[starts[-1] :]
    last_loop = max((i for i, m in enumerate(tail) if m.arbitration_id in loop), default=0)
    end = starts[-1] + last_loop + 1
    bounds = [*starts, end]
    periods = [messages[a:b] for a, b in zip(bounds, bounds[1:], strict=False)]
    return Periods(periods, starts[0], len(messages) - end, len(messages), mark)


def kind_of(m: can.Message, ids: LoopIds) -> str:
    """The frame's part in the loop: sync, measurement, plant, command, drive or other (simulate_period's)."""
    cob = m.arbitration_id
    if m.is_extended_id:
        return "other"
    if cob == ids.sync:
        return "sync"
    if cob in ids.plant:
        return "measurement" if cob in ids.measurement else "plant"
    if cob in ids.drive:
        return "command" if cob in ids.command else "drive"
    return "other"
