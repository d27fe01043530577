"""You 2019 claims over real vcan (C plant and drive processes in lockstep)."""

from __future__ import annotations

from bench.claims import you2019 as y


def _check(results) -> None:  # type: ignore[no-untyped-def]
    for r in results if isinstance(results, list) else [results]:
        print(f"{r.claim_id}: {r.verdict}: bench {r.bench_value}")
        assert r.ok, f"{r.claim_id}: {r.tolerance}; bench: {r.bench_value}"


def test_matched_step_over_vcan(vcan0: str) -> None:
    _check(y.claim_matched_step(vcan0))


def test_saturated_step_over_vcan(vcan0: str) -> None:
    _check(y.claim_saturated_step(vcan0))


def test_inductance_mismatch_over_vcan(vcan0: str) -> None:
    _check(y.claim_inductance_mismatch(vcan0))


def test_tuning_over_vcan(vcan0: str) -> None:
    _check(y.claim_tuning(vcan0))


def test_identification_accuracy_over_vcan(vcan0: str) -> None:
    _check(y.claim_identification_accuracy(vcan0))


def test_frequency_response_over_vcan(vcan0: str) -> None:
    """A sine reference written every period (lockstep events), through the real loop."""
    _check(y.claim_frequency_response(vcan0, freqs_Hz=(1000.0, 4545.45), periods_per_freq=100))
