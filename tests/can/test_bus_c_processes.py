"""Two separate C processes exchange frames over vcan0 and check every byte (on the host's vcan0, or in the
session's slot of the CAN box: tests/can/can_site.py)."""

from __future__ import annotations

from pathlib import Path

from can_site import Site

from bench.tools.pingpong import parse_ping

N = 500


def test_c_pingpong_exchanges_verified_frames(site: Site, tmp_path: Path) -> None:
    echo_log, ping_log = tmp_path / "echo.out", tmp_path / "ping.out"
    echo = site.popen(["can_pingpong", "echo", site.iface, str(N)], echo_log)
    try:
        # the first ping only once the echo process listens (its socket bound); a bound, not a timing
        assert site.wait_for_output(echo_log, "echo: ready", 60), site.read(echo_log)
        ping = site.popen(["can_pingpong", "ping", site.iface, str(N)], ping_log)
        assert ping.wait(timeout=600) == 0, site.read(ping_log)
        assert echo.wait(timeout=60) == 0, site.read(echo_log)
    finally:
        if echo.poll() is None:
            echo.kill()
    res = parse_ping(site.read(ping_log), site.read(echo_log))
    print(res.ping_output)
    assert res.frames == N
    assert res.verified == N
    assert res.bad == 0
    assert f"answered {N} pings" in res.echo_output
    assert res.rtt_median_us > 0
