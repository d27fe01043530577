"""The CiA 402 run's record: every frame in a candump log, decoded ONCE into a per-SYNC trace.

The layout (SYNC COB-ID, the PDOs' COB-IDs and mappings) is what the master used; the decoder
works on FRAME_DTYPE arrays (bench/run/bus/frames.py), never on a Python object per frame. Cycle k
is the time from SYNC k to SYNC k+1: the statusword/position TPDOs the drive sends on SYNC k and
the last RPDO the bench sent before SYNC k+1 belong to it.
"""

from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.run.bus.frames import empty
from bench.run.record.canlog import read_frames

INC_PER_REV = 65536
STATES: tuple[tuple[str, int, int], ...] = (  # CiA 402 statusword masks (as canopen's State402.SW_MASK)
    ("NOT READY TO SWITCH ON", 0x4F, 0x00),
    ("SWITCH ON DISABLED", 0x4F, 0x40),
    ("READY TO SWITCH ON", 0x6F, 0x21),
    ("SWITCHED ON", 0x6F, 0x23),
    ("OPERATION ENABLED", 0x6F, 0x27),
    ("FAULT", 0x4F, 0x08),
    ("FAULT REACTION ACTIVE", 0x4F, 0x0F),
    ("QUICK STOP ACTIVE", 0x6F, 0x07),
)
SIGNED = {0x6061, 0x6064, 0x606C, 0x6071, 0x6077, 0x6078}


def state_name(statusword: int) -> str:
    for name, mask, bits in STATES:
        if statusword & mask == bits:
            return name
    return "UNKNOWN"


@dataclass(frozen=True)
class Pdo:
    cob_id: int
    entries: tuple[tuple[int, int], ...]  # (index, bits) in mapping order

    def fields(self) -> dict[int, tuple[int, int]]:
        """index -> (byte offset, bytes)."""
        out, off = {}, 0
        for index, bits in self.entries:
            out[index] = (off, bits // 8)
            off += bits // 8
        return out


@dataclass
class Layout:
    drive_id: int
    sync_cob: int
    rpdo: Pdo
    tpdos: list[Pdo]
    rated_current_mA: int
    rated_torque_mNm: int
    cycle_s: float

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def default_layout(drive_id: int | None = None, cycle_s: float = 0.001) -> Layout:
    """drive.eds' own PDOs: RPDO4 {0x6040, 0x6071}, TPDO3 {0x6041, 0x6061, 0x6077, 0x6078}, TPDO4
    {0x6064, 0x606C}, the rated values' defaults (drive_id None: drive.eds' NodeID)."""
    if drive_id is None:
        from bench.eds import default_node_id

        drive_id = default_node_id("drive")
    return Layout(
        drive_id,
        0x80,
        Pdo(0x500 + drive_id, ((0x6040, 16), (0x6071, 16))),
        [
            Pdo(0x380 + drive_id, ((0x6041, 16), (0x6061, 8), (0x6077, 16), (0x6078, 16))),
            Pdo(0x480 + drive_id, ((0x6064, 32), (0x606C, 32))),
        ],
        4000,
        1260,
        cycle_s,
    )


def _field(data: np.ndarray, off: int, size: int, signed: bool) -> np.ndarray:
    raw = np.ascontiguousarray(data[:, off : off + size]).view(f"<u{size}").reshape(-1)
    return raw.view(f"<i{size}").astype(np.float64) if signed else raw.astype(np.float64)


def _per_cycle(frames: np.ndarray, sync_pos: np.ndarray, cob: int) -> tuple[np.ndarray, np.ndarray]:
    """(cycle index of the last frame of `cob` in each cycle or -1, that frame's row)."""
    pos = np.flatnonzero(frames["cob_id"] == cob)
    cyc = np.searchsorted(sync_pos, pos, side="right") - 1
    keep = cyc >= 0
    pos, cyc = pos[keep], cyc[keep]
    last = np.full(len(sync_pos), -1, dtype=np.int64)
    last[cyc] = pos  # later frames of a cycle overwrite earlier ones
    return last, pos


@dataclass
class Trace:
    columns: dict[str, np.ndarray]
    state: list[str]
    cycles_without_statusword: int
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.state)


def decode(frames: np.ndarray, layout: Layout) -> Trace:
    """Frames in bus order -> one row per SYNC cycle (NaN where the cycle had no such PDO)."""
    sync_pos = np.flatnonzero(frames["cob_id"] == layout.sync_cob)
    n = len(sync_pos)
    cols: dict[str, np.ndarray] = {
        "t_s": (frames["t_us"][sync_pos].astype(np.float64) - float(frames["t_us"][sync_pos[0]])) / 1e6
        if n
        else np.zeros(0),
        "cycle": np.arange(n, dtype=np.float64),
    }
    values: dict[int, np.ndarray] = {}
    sw_seen = np.zeros(n, dtype=bool)
    for pdo in [layout.rpdo, *layout.tpdos]:
        last, _ = _per_cycle(frames, sync_pos, pdo.cob_id)
        has = last >= 0
        if pdo is layout.rpdo:  # the bench's RPDO of a cycle is sent before its SYNC: take the previous cycle's
            has_prev = np.r_[False, has[:-1]] if n else has
            last = np.r_[-1, last[:-1]] if n else last
            has = has_prev
        data = frames["data"][np.where(has, last, 0)] if n else np.zeros((0, 8), np.uint8)
        for index, (off, size) in pdo.fields().items():
            v = _field(data, off, size, index in SIGNED) if n else np.zeros(0)
            values[index] = np.where(has, v, np.nan)
        if any(index == 0x6041 for index, _ in pdo.entries):
            sw_seen = has
    nan = np.full(n, np.nan)
    i_rated, t_rated = layout.rated_current_mA / 1000.0, layout.rated_torque_mNm / 1000.0
    sw = values.get(0x6041, nan)
    cols["statusword"] = sw
    cols["mode_display"] = values.get(0x6061, nan)
    cols["torque_actual_permille"] = values.get(0x6077, nan)
    cols["torque_actual_Nm"] = cols["torque_actual_permille"] / 1000 * t_rated
    cols["current_actual_permille"] = values.get(0x6078, nan)
    cols["current_actual_A"] = cols["current_actual_permille"] / 1000 * i_rated
    cols["position_rad"] = values.get(0x6064, nan) * (2 * math.pi / INC_PER_REV)
    cols["velocity_rad_s"] = values.get(0x606C, nan) * (2 * math.pi / INC_PER_REV)
    cols["controlword"] = values.get(0x6040, nan)
    cols["target_torque_permille"] = values.get(0x6071, nan)
    states = ["" if math.isnan(v) else state_name(int(v)) for v in sw.tolist()]
    return Trace(cols, states, int(n - int(np.count_nonzero(sw_seen))))


def decode_log(path: Path, layout: Layout) -> Trace:
    chunks = list(read_frames(path))
    frames = np.concatenate(chunks) if chunks else empty()
    return decode(frames[np.argsort(frames["t_us"], kind="stable")], layout)


def states_passed(trace: Trace) -> list[str]:
    out: list[str] = []
    for s in trace.state:
        if s and (not out or out[-1] != s):
            out.append(s)
    return out


def tracking(trace: Trace) -> list[dict[str, Any]]:
    """Per run of one target (as sent): mean torque actual over the second half of the run, with the
    cycles in OPERATION ENABLED only."""
    tgt = trace.columns["target_torque_permille"]
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
    names = [name for name, _, _ in STATES]
    codes = np.array([names.index(s) if s in names else np.nan for s in trace.state], dtype=np.float64)
    ax2.step(c["t_s"], codes, where="post")
    ax2.set_yticks(range(len(names)), [n.title() for n in names], fontsize=6)
    ax2.set_xlabel("time from the first SYNC, s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
