"""Yao 2020 (seed 001): DPCC with a sliding-mode disturbance observer and R/L identification.

Each claim function runs the real loop (plant emulator + drive over the CANopen frames, presets
yao2020_low / yao2020_high, rotor driven at the rated electrical frequency) and judges one
claim of Section V-VI against values derived from the fully discretised model (Eq. 5-7):
x = exp(-R T/L), y = (1 - x)/R, G2 = (x - exp(j w T))/(R + j w L); the paper's numbers are
reported beside them.

    yao2020_common.py          the scenario (base), the traced entries and the derived model
    yao2020_low_frequency.py   Fig. 10: observer (Eq. 13-20), identification (Eq. 30-45), deadbeat after it
    yao2020_identification.py  Fig. 11 (high-frequency motor), Fig. 14 (gains, Eq. 44), Fig. 16-17 (RLS, Eq. 46-48)

`bench reproduce` runs ALL, in its order.
"""

from __future__ import annotations

from bench.claims.saturation import finding_yao2020_saturation
from bench.claims.yao2020_common import (
    GAIN_X,
    MOTORS,
    PAPER,
    base,
    dM_gain,
    first_sample_error,
    g2,
    rls_fixed_point,
    steady_state_no_observer,
    step_error,
    xy,
)
from bench.claims.yao2020_identification import claim_gain_speed, claim_high_frequency, claim_rls_flux
from bench.claims.yao2020_low_frequency import claim_low_frequency, claim_observer

ALL = [
    claim_observer,
    claim_low_frequency,
    claim_high_frequency,
    claim_gain_speed,
    claim_rls_flux,
    finding_yao2020_saturation,
]

__all__ = [
    "ALL",
    "finding_yao2020_saturation",
    "GAIN_X",
    "MOTORS",
    "PAPER",
    "base",
    "claim_gain_speed",
    "claim_high_frequency",
    "claim_low_frequency",
    "claim_observer",
    "claim_rls_flux",
    "dM_gain",
    "first_sample_error",
    "g2",
    "rls_fixed_point",
    "steady_state_no_observer",
    "step_error",
    "xy",
]
