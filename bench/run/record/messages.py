"""Frames <-> python-can's can.Message, for the formats python-can reads and writes (.asc, .blf, .trc, ...) and for
a python-can listener on the master's bus: one Message per frame (~10 µs), the slow but standard path (the .log
path stays in C: canlog.py). CAN FD frames keep their length and flags both ways (is_fd, bitrate_switch)."""

from __future__ import annotations

import can
import numpy as np

from bench.run.bus.frames import BRS, FD_DATA, FDF, frame_dtype, is_fd


def ours(m: can.Message) -> bool:
    """An 11-bit data frame: classic of <= 8 bytes, or CAN FD of <= 64."""
    return not (m.is_extended_id or m.is_error_frame or m.is_remote_frame) and len(m.data) <= (
        FD_DATA if m.is_fd else 8
    )


def to_frames(msgs: list[can.Message]) -> np.ndarray:
    """can.Messages (see `ours`) -> frame records, in their order, seq 0, sender 255, t_us = round(timestamp *
    1e6); the wide record (FRAME_FD_DTYPE) when any of them is a CAN FD frame."""
    fd = any(m.is_fd for m in msgs)
    width = FD_DATA if fd else 8
    arr = np.zeros(len(msgs), dtype=frame_dtype(fd))
    arr["t_us"] = [round(m.timestamp * 1e6) for m in msgs]
    arr["cob_id"] = [m.arbitration_id & 0x7FF for m in msgs]
    arr["dlc"] = [len(m.data) for m in msgs]
    arr["sender"] = 255
    raw = b"".join(bytes(m.data).ljust(width, b"\0") for m in msgs)
    arr["data"] = np.frombuffer(raw, dtype=np.uint8).reshape(-1, width)
    if fd:
        arr["flags"] = [(FDF if m.is_fd else 0) | (BRS if m.bitrate_switch else 0) for m in msgs]
    return arr


def to_messages(frames: np.ndarray) -> list[can.Message]:
    """Frame records -> can.Messages (timestamp = t_us / 1e6 s), for python-can's writers."""
    ts, ids, dlcs = frames["t_us"].tolist(), frames["cob_id"].tolist(), frames["dlc"].tolist()
    width = frames["data"].shape[1]
    raw = np.ascontiguousarray(frames["data"]).tobytes()
    flags = frames["flags"].tolist() if is_fd(frames) else [0] * len(frames)
    return [
        can.Message(
            timestamp=t / 1e6,
            arbitration_id=i,
            is_extended_id=False,
            dlc=d,
            data=raw[width * k : width * k + d],
            is_rx=True,
            is_fd=bool(f & FDF),
            bitrate_switch=bool(f & BRS),
        )
        for k, (t, i, d, f) in enumerate(zip(ts, ids, dlcs, flags, strict=True))
    ]
