"""You 2019 (seed 000): z-domain deadbeat current control with online gain identification.

Each claim function runs the loop and judges one claim of the paper (Section 5 and 7). The
expected values are derived from the discrete model of Eq. 2 with the plant's own
parameters (A = exp(-Ts R / L), B = (1 - A) / R, K1 = 1/B, K2 = A/B), never copied
from the paper's sentences; the paper's numbers are reported beside them.

    you2019_common.py  the scenario of the paper's simulations (base) and the discrete model
    you2019_steps.py   Section 5: steps (Fig. 8-9, 18-19), mismatches (Fig. 11-14, 20-21),
                       frequency response (Fig. 10, 26)
    you2019_tuning.py  Sections 6-7: identification (Eq. 22-27, Fig. 20-21), online tuning (Fig. 22-25)
    saturation.py      a finding (issue 42): Eq. 32's L_hat on a saturating machine (examples/motors/)

`bench reproduce` runs ALL, in its order.
"""

from __future__ import annotations

from bench.claims.saturation import finding_you2019_saturation
from bench.claims.you2019_common import PAPER, STEP_AT, base, closed_loop_response, model_gains
from bench.claims.you2019_steps import (
    claim_frequency_response,
    claim_inductance_mismatch,
    claim_matched_step,
    claim_resistance_mismatch,
    claim_saturated_step,
)
from bench.claims.you2019_tuning import (
    claim_identification_accuracy,
    claim_tuning,
    claim_tuning_position_profile,
    identification_errors,
    step_fraction,
)

ALL = [
    claim_matched_step,
    claim_saturated_step,
    claim_inductance_mismatch,
    claim_resistance_mismatch,
    claim_identification_accuracy,
    claim_tuning,
    claim_tuning_position_profile,
    claim_frequency_response,
    finding_you2019_saturation,
]

__all__ = [
    "ALL",
    "finding_you2019_saturation",
    "PAPER",
    "STEP_AT",
    "base",
    "claim_frequency_response",
    "claim_identification_accuracy",
    "claim_inductance_mismatch",
    "claim_matched_step",
    "claim_resistance_mismatch",
    "claim_saturated_step",
    "claim_tuning",
    "claim_tuning_position_profile",
    "closed_loop_response",
    "identification_errors",
    "model_gains",
    "step_fraction",
]
