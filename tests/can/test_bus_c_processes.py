"""Two separate C processes exchange frames over vcan0 and check every byte."""

from __future__ import annotations

from bench.tools.pingpong import run_pingpong


def test_c_pingpong_exchanges_verified_frames(vcan0: str) -> None:
    res = run_pingpong(vcan0, 500)
    print(res.ping_output)
    assert res.frames == 500
    assert res.verified == 500
    assert res.bad == 0
    assert "answered 500 pings" in res.echo_output
    assert res.rtt_median_us > 0
