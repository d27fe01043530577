"""The CiA 402 run's record: every frame in a candump log, decoded ONCE into a per-SYNC trace by the run's
decoder (bench/run/decode/decoder.py, profile "cia402": no plant, no lockstep).

The decoder reads the layout off the bus: the SYNC's COB-ID and counter, the PDOs' COB-IDs and mappings and the
drive's rated values are in the master's SDO transfers in the log; the master's Layout (what it read and wrote,
bench/cia402/layout.py) is assumed before the first frame, so that a log without that traffic decodes too. The
decoder works on FRAME_DTYPE arrays (bench/run/bus/frames.py), never on a Python object per frame. Cycle k is
the time from SYNC k to SYNC k+1: the drive's TPDOs sent on SYNC k and the last RPDO the bench sent before
SYNC k belong to it. States are canopen's (State402.SW_MASK).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from canopen.profiles.p402 import State402

from bench.cia402.layout import Layout
from bench.run.decode.decoder import Decoder
from bench.run.decode.sdo_log import NodeState
from bench.run.record.canlog import read_frames
from bench.run.record.sources import sorted_chunks
from bench.signals import column_name

__all__ = [
    "Trace",
    "decode",
    "decode_log",
    "state_name",
    "states_passed",
    "tracking",
    "write_csv",
    "write_plot",
]

INC_PER_REV = 65536
STATES = tuple(State402.SW_MASK)  # the statusword's states, in canopen's order (the plot's axis)
# trace column <- the drive object a PDO carries it in, as sent (per mille of the rated value for 0x6077/0x6078)
RAW = {
    "statusword": 0x6041,
    "mode_display": 0x6061,
    "torque_actual_permille": 0x6077,
    "current_actual_permille": 0x6078,
    "position_inc": 0x6064,
    "velocity_inc_s": 0x606C,
    "controlword": 0x6040,
    "target_torque_permille": 0x6071,
}


def state_name(statusword: int) -> str:
    """The CiA 402 state a statusword says (canopen's BaseNode402.state, for a recorded value)."""
    for name, (mask, bits) in State402.SW_MASK.items():
        if statusword & mask == bits:
            return name
    return "UNKNOWN"


@dataclass
class Trace:
    columns: dict[str, np.ndarray]
    state: list[str]
    cycles_without_statusword: int
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.state)


def decoder(layout: Layout, eds: Path | None = None) -> Decoder:
    """The run's decoder for a CiA 402 master's bus (eds: the drive's, when it is not drive.eds)."""
    dec = Decoder(drive_id=layout.drive_id, profile="cia402", drive_eds=eds)
    dec.sdo.drive.assume(layout.od_values())
    return dec


def decode(frames: np.ndarray, layout: Layout, eds: Path | None = None) -> Trace:
    """Frames in bus order -> one row per SYNC cycle (NaN where the cycle had no such PDO)."""
    dec = decoder(layout, eds)
    return _trace(dec, [dec.feed(frames), dec.finish()])


def decode_log(path: Path, layout: Layout, eds: Path | None = None) -> Trace:
    dec = decoder(layout, eds)
    chunks = [dec.feed(chunk) for chunk in sorted_chunks(read_frames(path))]
    return _trace(dec, [*chunks, dec.finish()])


def _trace(dec: Decoder, chunks: list[dict[str, np.ndarray] | None]) -> Trace:
    """The decoder's rows as the CiA 402 trace: its drive objects by index, in SI units where they have one."""
    parts = [c for c in chunks if c is not None]
    rows = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]} if parts else {}
    n = len(rows.get("period", ()))
    drive = dec.sdo.drive
    raw = {name: _column(rows, drive, index, n) for name, index in RAW.items()}
    i_rated = float(drive.values.get((0x6075, 0)) or 0) / 1000.0  # the rated values as the master read them
    t_rated = float(drive.values.get((0x6076, 0)) or 0) / 1000.0
    rad = 2 * math.pi / INC_PER_REV
    sw = raw["statusword"]
    cols: dict[str, np.ndarray] = {
        "t_s": rows.get("t_s", np.zeros(0)),
        "cycle": rows.get("period", np.zeros(0, dtype=np.int64)).astype(np.float64),
        "statusword": sw,
        "mode_display": raw["mode_display"],
        "torque_actual_permille": raw["torque_actual_permille"],
        "torque_actual_Nm": raw["torque_actual_permille"] / 1000 * t_rated,
        "current_actual_permille": raw["current_actual_permille"],
        "current_actual_A": raw["current_actual_permille"] / 1000 * i_rated,
        "position_rad": raw["position_inc"] * rad,
        "velocity_rad_s": raw["velocity_inc_s"] * rad,
        "controlword": raw["controlword"],
        "target_torque_permille": raw["target_torque_permille"],
    }
    states = ["" if math.isnan(v) else state_name(int(v)) for v in sw.tolist()]
    return Trace(cols, states, int(np.count_nonzero(np.isnan(sw))))


def _column(rows: dict[str, np.ndarray], drive: NodeState, index: int, n: int) -> np.ndarray:
    """The decoder's column of a drive object (sub-index 0), NaN when no PDO maps it."""
    name = drive.qualname(index, 0)
    col = rows.get(column_name(name)) if name is not None else None
    return col if col is not None else np.full(n, np.nan)


def states_passed(trace: Trace) -> list[str]:
    out: list[str] = []
    for s in trace.state:
        if s and (not out or out[-1] != s):
            out.append(s)
    return out


def _bridged(tgt: np.ndarray) -> np.ndarray:
    """The targets with each gap (cycles whose RPDO the log lacks: a periodic sender late by a cycle, a frame a
    tap dropped) between two cycles of the same target filled with it: a gap does not end a run of one
    target, whose window would then depend on where the gap fell."""
    out = tgt.copy()
    known = np.flatnonzero(~np.isnan(tgt))
    for a, b in zip(known[:-1], known[1:], strict=True):
        if b > a + 1 and tgt[a] == tgt[b]:
            out[a + 1 : b] = tgt[a]
    return out


def tracking(trace: Trace) -> list[dict[str, Any]]:
    """Per run of one target (as sent; a gap in the log between two cycles of the same target does not end
    it): mean torque actual over the second half of the run, with the cycles in OPERATION ENABLED only."""
    tgt = _bridged(trace.columns["target_torque_permille"])
    act = trace.columns["torque_actual_permille"]
    enabled = np.array([s == "OPERATION ENABLED" for s in trace.state], dtype=bool)
    out: list[dict[str, Any]] = []
    start = 0
    for k in range(1, len(tgt) + 1):
        if k < len(tgt) and (tgt[k] == tgt[start] or (np.isnan(tgt[k]) and np.isnan(tgt[start]))):
            continue
        if not np.isnan(tgt[start]):
            half = slice(start + (k - start) // 2, k)
            sel = act[half][enabled[half] & ~np.isnan(act[half])]
            mean = float(np.mean(sel)) if len(sel) else None
            target = float(tgt[start])
            err = None if mean is None or target == 0 else (mean - target) / abs(target)
            out.append(
                {
                    "start_cycle": start,
                    "cycles": k - start,
                    "target_permille": target,
                    "mean_actual_permille": mean,
                    "samples": len(sel),
                    "relative_error": err,
                }
            )
        start = k
    return out


def write_csv(trace: Trace, path: Path) -> None:
    names = list(trace.columns)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*names[:3], "state", *names[3:]])
        rows = zip(*(trace.columns[c].tolist() for c in names), strict=True)
        for row, state in zip(rows, trace.state, strict=True):
            cells = ["" if isinstance(v, float) and math.isnan(v) else f"{v:.9g}" for v in row]
            w.writerow([*cells[:3], state, *cells[3:]])


def write_plot(trace: Trace, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = trace.columns
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 6), height_ratios=(3, 1))
    ax1.step(c["t_s"], c["target_torque_permille"], where="post", label="target torque 0x6071")
    ax1.plot(c["t_s"], c["torque_actual_permille"], label="torque actual 0x6077")
    ax1.plot(c["t_s"], c["current_actual_permille"], ":", label="current actual 0x6078")
    ax1.set_ylabel("per mille of rated")
    ax1.legend(loc="best")
    ax1.set_title(title)
    codes = np.array([STATES.index(s) if s in STATES else np.nan for s in trace.state], dtype=np.float64)
    ax2.step(c["t_s"], codes, where="post")
    ax2.set_yticks(range(len(STATES)), [n.title() for n in STATES], fontsize=6)
    ax2.set_xlabel("time from the first SYNC, s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
