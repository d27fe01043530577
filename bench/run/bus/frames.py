"""The bench's frame record: one CAN frame as the C recorder (bench/direct/hil_direct.c,
`hil_frame_t`) and the log reader (bench/direct/hil_log.c) produce it, as a numpy
structured array so that a run's frames are never a Python object each."""

from __future__ import annotations

import numpy as np

# t_us: simulated time (direct mode, from 0) or absolute time since the epoch (read from a log);
# seq: bus order; sender: 0 plant, 1 drive, 255 master or unknown (a log).
FRAME_DTYPE = np.dtype(
    [("t_us", "<u8"), ("seq", "<u4"), ("cob_id", "<u2"), ("dlc", "u1"), ("sender", "u1"), ("data", "u1", (8,))]
)


def empty() -> np.ndarray:
    return np.zeros(0, dtype=FRAME_DTYPE)
