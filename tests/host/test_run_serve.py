"""`bench run --serve` as a user runs it: the address a browser opens is printed once, it
answers while the run goes and after it, for --serve-for seconds, then the command ends."""

from __future__ import annotations

import re
import socket
import subprocess
import time
import urllib.request
from pathlib import Path

from bench_cli import spawn_bench

from bench.paths import REPO


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_serve_prints_the_browser_address_and_keeps_serving(tmp_path: Path) -> None:
    web, grpc = free_port(), free_port()
    proc = spawn_bench(
        "run", REPO / "scenarios" / "you2019_step.toml", "--bus", "direct", "--out", tmp_path / "r",
        "--serve", "--serve-for", "6", "--web-port", str(web), "--grpc-port", str(grpc),
        stderr=subprocess.STDOUT,
    )  # fmt: skip
    assert proc.stdout is not None
    lines: list[str] = []
    url = None
    t0 = time.monotonic()
    while url is None and time.monotonic() - t0 < 60:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        m = re.search(r"web viewer at (http://\S+)", line)
        if m:
            url = m.group(1)
    assert url is not None, "".join(lines)
    assert url.startswith(f"http://localhost:{web}/") and f"{grpc}" in url
    # the run ends, the viewer keeps answering
    while time.monotonic() - t0 < 60:
        line = proc.stdout.readline()
        lines.append(line)
        if "results in" in line:
            break
    with urllib.request.urlopen(url, timeout=10) as resp:
        assert resp.status == 200 and b"<html" in resp.read(2000).lower()
    assert proc.poll() is None, "the command ended before --serve-for"
    rest, _ = proc.communicate(timeout=60)
    out = "".join(lines) + rest
    assert proc.returncode == 0, out
    assert out.count("rerun: web viewer at") == 1, out  # the address once (then "serving ... for 6 s")
    assert time.monotonic() - t0 >= 6
    assert (tmp_path / "r" / "run.rrd").stat().st_size > 0
