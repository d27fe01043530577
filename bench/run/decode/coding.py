"""The compact measurement frame's codes (plant.eds 0x2100:07-09) as amperes and radians, with the plant's and the
drive's own expressions (protocols/coding/meas_coding.h): the REAL32 scale widened to double, the double product
rounded once to float32. So a decoded column equals what the drive computed from the same frame, bit for bit."""

from __future__ import annotations

import math

import numpy as np

# code column -> the column it decodes into, and whether it is a current (else the angle)
CODE_COLUMNS = {"i_a_code": ("i_a_A", True), "i_b_code": ("i_b_A", True), "theta_code": ("theta_m_rad", False)}


def decoded_names(columns: set[str]) -> list[str]:
    """The columns the codes among `columns` decode into."""
    return [CODE_COLUMNS[c][0] for c in CODE_COLUMNS if c in columns]


def decode_codes(out: dict[str, np.ndarray], current_lsb_A: float, angle_counts: int) -> None:
    """Add i_a_A, i_b_A, theta_m_rad to the rows `out` from their codes (NaN stays NaN: a missing frame), float32
    values in float64 columns as the PDO columns are (rows.py _columns)."""
    lsb = float(np.float32(current_lsb_A))  # the REAL32 the nodes hold, widened
    step = math.tau / float(angle_counts)
    for code, (name, current) in CODE_COLUMNS.items():
        if code in out and name not in out:
            c = out[code].astype(np.float64)
            out[name] = (lsb * c if current else c * step).astype(np.float32).astype(np.float64)
