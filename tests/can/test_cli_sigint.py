"""Ctrl-C in the middle of a `bench run` over vcan leaves no process behind."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest
from bench_proc import NODES, pids, start_long_run

# the test looks for the run's node processes among this machine's
# (kernel_can: the kernel's CAN in this process, inside the VM on a host without CAN)
pytestmark = pytest.mark.kernel_can


def test_sigint_mid_run_leaves_no_orphan(vcan0: str, tmp_path: Path) -> None:
    out = tmp_path / "long"
    proc = start_long_run(out, "--bus", vcan0)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not pids("build/bin/plant_node"):
        time.sleep(0.5)
    assert pids("build/bin/plant_node"), "the run never started its nodes"
    time.sleep(3.0)  # configured and running
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    time.sleep(0.5)
    for name in NODES:
        assert not pids(name), f"{name} still running after Ctrl-C"
    assert not out.exists()
