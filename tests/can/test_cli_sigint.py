"""Ctrl-C in the middle of a `bench run` over vcan leaves no process behind."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

from bench.paths import REPO


def _alive(pattern: str) -> list[str]:
    res = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True)
    return res.stdout.split()


def test_sigint_mid_run_leaves_no_orphan(vcan0: str, tmp_path: Path) -> None:
    out = tmp_path / "long"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "bench.cli",
            "run",
            str(REPO / "scenarios" / "you2019_step.toml"),
            "--bus",
            vcan0,
            "--out",
            str(out),
            "--no-viewer",
            "--set",
            "scenario.periods=5000000",
        ],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not _alive("build/bin/plant_node"):
        time.sleep(0.5)
    assert _alive("build/bin/plant_node"), "the run never started its nodes"
    time.sleep(3.0)  # configured and running
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    time.sleep(0.5)
    for name in ("build/bin/plant_node", "build/bin/drive_node", "candump -L"):
        assert not _alive(name), f"{name} still running after Ctrl-C"
    assert not out.exists()
