"""The bench's frame record: one CAN frame as the C recorder (bench/direct/hil_direct.c,
`hil_frame_t`) and the log reader (bench/direct/hil_log.c) produce it, as a numpy
structured array so that a run's frames are never a Python object each.

A run whose PDOs travel in CAN FD frames (a scenario's frames.can = "fd": plant.eds / drive.eds 0x2105) records
88-byte `hil_frame_fd_t` (FRAME_FD_DTYPE): the same fields at the same offsets, 64 data bytes and the frame's
flags. A classic run keeps the 24-byte record, so its memory and speed do not change; code that reads frames
indexes `data` by column and works on either."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

# t_us: simulated time (direct mode, from 0) or absolute time since the epoch (read from a log);
# seq: bus order; sender: 0 plant, 1 drive, 255 master or unknown (a log).
FRAME_DTYPE = np.dtype(
    [("t_us", "<u8"), ("seq", "<u4"), ("cob_id", "<u2"), ("dlc", "u1"), ("sender", "u1"), ("data", "u1", (8,))]
)
FD_DATA = 64
# the padding is a field: a copy that packs the fields (numpy drops gaps) keeps the record's layout
FRAME_FD_DTYPE = np.dtype(
    [
        ("t_us", "<u8"),
        ("seq", "<u4"),
        ("cob_id", "<u2"),
        ("dlc", "u1"),
        ("sender", "u1"),
        ("data", "u1", (FD_DATA,)),
        ("flags", "u1"),
        ("pad", "u1", (7,)),
    ]
)
FDF = 0x01  # hil_frame.h HIL_FRAME_FDF: a CAN FD frame
BRS = 0x02  # HIL_FRAME_BRS: its data phase at the data bit rate


def frame_dtype(fd: bool) -> np.dtype:
    return FRAME_FD_DTYPE if fd else FRAME_DTYPE


def is_fd(frames: np.ndarray) -> bool:
    """Frames in the wide record (they may still all be classic frames: see `flags`)."""
    return frames.dtype == FRAME_FD_DTYPE


def empty(fd: bool = False) -> np.ndarray:
    return np.zeros(0, dtype=frame_dtype(fd))


def widen(frames: np.ndarray) -> np.ndarray:
    """Classic records as wide ones (flags 0), the data's first 8 bytes kept; wide ones unchanged."""
    if is_fd(frames):
        return frames
    out = np.zeros(len(frames), dtype=FRAME_FD_DTYPE)
    for name in ("t_us", "seq", "cob_id", "dlc", "sender"):
        out[name] = frames[name]
    out["data"][:, :8] = frames["data"]
    return out


def join(parts: Sequence[np.ndarray]) -> np.ndarray:
    """The parts one after the other; in the wide record when any part is (the others widened)."""
    parts = [p for p in parts if len(p)] or list(parts[:1])
    if not parts:
        return empty()
    if len(parts) == 1:
        return parts[0]
    if any(is_fd(p) for p in parts) and not all(is_fd(p) for p in parts):
        parts = [widen(p) for p in parts]
    return np.concatenate(parts)


# CAN FD payload lengths (ISO 11898-1: a DLC code each above 8 bytes)
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def fd_len(n: int) -> int:
    """The CAN FD payload that holds n bytes (protocols/canopen/co_frame.h co_frame_fd_len): n up to 8, then the
    next of 12 .. 64."""
    for length in FD_LENGTHS:
        if length >= n:
            return length
    raise ValueError(f"{n} bytes do not fit a CAN FD frame (64 at most)")
