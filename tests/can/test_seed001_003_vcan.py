"""Yao 2020 and Zhao 2022 claims over real vcan (C plant and drive processes in lockstep):
one short claim of each paper (the full sets run in direct mode in tests/host)."""

from __future__ import annotations

from bench.claims import yao2020 as y
from bench.claims import zhao2022 as z


def test_yao2020_observer_steady_state_over_vcan(vcan0: str) -> None:
    r = y.claim_observer(vcan0)
    print(f"{r.claim_id}: {r.verdict}: bench {r.bench_value}")
    assert r.verdict == "reproduced", f"{r.claim_id}: {r.tolerance}; bench: {r.bench_value}"


def test_zhao2022_flux_independence_over_vcan(vcan0: str) -> None:
    r = z.claim_flux_independence(vcan0, wrong=(0.8,))
    print(f"{r.claim_id}: {r.verdict}: bench {r.bench_value}")
    assert r.verdict == "reproduced", f"{r.claim_id}: {r.tolerance}; bench: {r.bench_value}"
