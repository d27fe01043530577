"""Two C processes exchanging frames over a real vcan: the bus smoke test and floor benchmark."""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass

from bench.paths import binary


@dataclass
class PingPongResult:
    frames: int
    verified: int
    bad: int
    rtt_median_us: float
    rtt_p99_us: float
    round_trips_per_s: float
    echo_output: str
    ping_output: str


def run_pingpong(iface: str = "vcan0", count: int = 1000) -> PingPongResult:
    """Start an echo process and a ping process on `iface`; both must exit cleanly."""
    exe = str(binary("can_pingpong"))
    echo = subprocess.Popen(
        [exe, "echo", iface, str(count)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        # the first ping only once the echo process listens (its socket bound): a fixed sleep was too short
        # for a loaded VM, and the lost first ping failed the run
        assert echo.stdout is not None
        ready = echo.stdout.readline()
        if ready.strip() != "echo: ready":
            echo.wait(timeout=30)
            raise RuntimeError(f"ping-pong: the echo process did not start: {ready}{echo.stdout.read()}")
        ping = subprocess.run([exe, "ping", iface, str(count)], capture_output=True, text=True, timeout=600)
        echo_out, _ = echo.communicate(timeout=60)
        echo_out = ready + echo_out
    finally:
        if echo.poll() is None:
            echo.kill()
    if ping.returncode != 0 or echo.returncode != 0:
        raise RuntimeError(
            f"ping-pong failed: ping rc {ping.returncode}: {ping.stdout}{ping.stderr}; "
            f"echo rc {echo.returncode}: {echo_out}"
        )
    return parse_ping(ping.stdout, echo_out)


def parse_ping(ping_out: str, echo_out: str) -> PingPongResult:
    """The result of a ping-pong from the two processes' outputs (ValueError when the ping's is not one)."""
    m = re.search(r"(\d+) frames sent, (\d+) answers verified, (\d+) bad", ping_out)
    r = re.search(r"median (\d+) p99 (\d+) .*; (\d+) round trips/s", ping_out)
    if not m or not r:
        raise ValueError(f"unexpected ping output: {ping_out!r}")
    return PingPongResult(int(m[1]), int(m[2]), int(m[3]), float(r[1]), float(r[2]), float(r[3]), echo_out, ping_out)
