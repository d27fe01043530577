"""You 2019 (seed 000) claims, run in-process (direct mode: the same C nodes and frames as over vcan).

Each claim's verdict is computed from the simulated loop against values derived from the
paper's discrete model (bench/claims/you2019.py); the paper's own numbers are reported.
"""

from __future__ import annotations

import pytest

from bench.claims import ClaimResult
from bench.claims import you2019 as y

CLAIMS = {
    "matched_step": y.claim_matched_step,
    "saturated_step": y.claim_saturated_step,
    "inductance_mismatch": y.claim_inductance_mismatch,
    "resistance_mismatch": y.claim_resistance_mismatch,
    "identification_accuracy": y.claim_identification_accuracy,
    "tuning": y.claim_tuning,
    "tuning_position_profile": y.claim_tuning_position_profile,
    "frequency_response": y.claim_frequency_response,
    "saturation_finding": y.finding_you2019_saturation,
}


@pytest.mark.parametrize("name", list(CLAIMS))
def test_you2019_claim_direct(name: str) -> None:
    res = CLAIMS[name]("direct")
    results: list[ClaimResult] = res if isinstance(res, list) else [res]
    for r in results:
        print(f"{r.claim_id}: {r.verdict}: paper {r.paper_value} / bench {r.bench_value}")
        assert r.ok, f"{r.claim_id} ({r.figure}): {r.tolerance}; bench: {r.bench_value}"


def test_analytic_model_detects_a_wrong_plant() -> None:
    """The analytic closed-loop response used by the mismatch claim is sensitive: with the plant's B
    off by 5 % it no longer matches the matched-gain response (so that comparison can fail)."""
    import numpy as np

    A, B = 0.983, 0.012
    exact = y.closed_loop_response(A, B, A, B, 20)
    assert np.allclose(exact[2:], 1.0)
    off = y.closed_loop_response(A, B * 1.05, A, B, 20)
    assert np.max(np.abs(off - exact)) > 0.04
