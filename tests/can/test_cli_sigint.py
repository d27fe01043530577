"""Ctrl-C in the middle of a `bench run` over vcan leaves no process behind (on this machine, or in the CAN box,
whose slot the run gives back)."""

from __future__ import annotations

import signal
import time
from pathlib import Path

from bench_proc import NODES, pids, start_long_run
from can_site import Site


def test_sigint_mid_run_leaves_no_orphan(site: Site, tmp_path: Path) -> None:
    out = tmp_path / "long"
    proc = start_long_run(out, "--bus", site.iface)
    slot = site.run_slot(proc.pid)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not site.pids("build/bin/plant_node"):
        time.sleep(0.5)
    assert site.pids("build/bin/plant_node"), "the run never started its nodes"
    time.sleep(3.0)  # configured and running
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    time.sleep(0.5)
    for name in NODES:
        assert not site.pids(name), f"{name} still running after Ctrl-C"
        assert not pids(name), f"{name} still running here after Ctrl-C"
    assert not out.exists()
    if slot is not None:
        from bench.run.bus.box import life

        assert not life.slot_held(slot), "the run kept its slot of the CAN box"
