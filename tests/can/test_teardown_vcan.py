"""The end of a run raises no false alarm, and a real alarm still does (issue 52).

The race: at the end of a run the node processes are stopped one after the other; on a loaded host (or in the CAN
box under load) the one stopped last may outlive the other's last heartbeat by more than its heartbeat-consumer
time (1 s) and send EMCY 0x8130, which a run's verdict once stamped on its last period (`expect_no_emcy` failed a
green run). Here the race is provoked deterministically: the drive's stop is delayed beyond its consumer time.

- The bench ends a run with NMT Stop to both nodes before any process stops: a STOPPED node sends no EMCY
  (CiA 301), so the delayed drive stays silent.
- Whatever a node still sends after that command is the teardown's: with the NMT Stop kept from the drive, the
  drive's EMCYs are on the bus and in the log, listed in summary.json's "teardown", never in the run's "emcy".
- A heartbeat lost mid-run still ends the run (node_lost): tests/can/test_liveness.py, test_faults_vcan.py.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import Any

import pytest

from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.bus.buses import box_wanted
from bench.run.loop.session import Session
from bench.run.loop.session_bus import SessionBus
from bench.run.options import BOX_CONSUMER_MS
from bench.scenario import load

TUNE = REPO / "tests" / "scenarios" / "parity.toml"


@pytest.fixture
def slow_drive_stop(monkeypatch: pytest.MonkeyPatch) -> None:
    """The plant's process stopped first, the drive's only after the drive's heartbeat-consumer time (0x1016 as
    the run configured it: longer in the CAN box, options.py BOX_CONSUMER_MS) and half a second: the drive sees the
    plant's heartbeat end while it still runs."""
    stop_nodes = SessionBus._stop_nodes

    def stop_plant_then_wait(self: SessionBus) -> None:
        plant = self.node_procs.get("plant")
        if plant is not None:
            plant.stop()
            time.sleep(self.config.consumer_ms / 1000 + 0.5)  # type: ignore[attr-defined]  # a Session
        stop_nodes(self)

    monkeypatch.setattr(SessionBus, "_stop_nodes", stop_plant_then_wait)


def _drive_not_stopped(monkeypatch: pytest.MonkeyPatch) -> None:
    """The teardown's NMT Stop reaches the plant only: the drive stays OPERATIONAL and its heartbeat
    consumer fires, as on a bus where the command did not reach it in time."""
    close = Session.close

    def close_without_the_drives_stop(self: Session) -> None:
        send = self.drive.nmt.send_command

        def no_stop(code: int) -> None:
            if code != 0x02:
                send(code)

        self.drive.nmt.send_command = no_stop  # type: ignore[method-assign]
        close(self)

    monkeypatch.setattr(Session, "close", close_without_the_drives_stop)


def _run(vcan0: str, out: Path) -> Any:
    return run_scenario(load(TUNE, ["scenario.periods=600"]), RunOptions(bus=vcan0, out=out))


def test_a_drive_that_outlives_the_plant_raises_no_alarm(vcan0: str, tmp_path: Path, slow_drive_stop: None) -> None:
    res = _run(vcan0, tmp_path / "run")
    assert res.status == "ok", res.summary["stopped"]
    assert res.summary["emcy"] == [], res.summary["emcy"]
    # the drive was STOPPED when the plant's heartbeat ended: it sent nothing at all
    assert res.summary["teardown"]["emcy"] == [], res.summary["teardown"]
    # each node consumes the other's heartbeat with the run's consumer time: 5 s in the CAN box, whose emulation
    # may starve one node for seconds (options.py BOX_CONSUMER_MS), the bench's 1 s elsewhere
    want = BOX_CONSUMER_MS if box_wanted(vcan0) is not None else RunOptions().heartbeat_timeout_ms
    log = "\n".join(p.read_text() for p in (tmp_path / "run").glob("*.log"))
    for node, other in ((0x10, 0x20), (0x20, 0x10)):
        write = struct.pack("<BHBI", 0x23, 0x1016, 1, (other << 16) | want).hex().upper()
        assert f"{0x600 + node:03X}#{write}" in log, (node, want)


def test_an_alarm_after_the_runs_end_is_the_teardowns(
    vcan0: str, tmp_path: Path, slow_drive_stop: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    _drive_not_stopped(monkeypatch)
    res = _run(vcan0, tmp_path / "run")
    assert res.status == "ok", res.summary["stopped"]
    assert res.summary["emcy"] == [], res.summary["emcy"]
    late = res.summary["teardown"]["emcy"]
    # the race happened (the drive's heartbeat consumer fired on the bus) and it is in the log, marked
    assert ("drive", "0x8130") in [(e["node"], e["code"]) for e in late], late
    assert all(e["period"] is None and e["after_stop_s"] > 0 for e in late), late
    logs = list((tmp_path / "run").glob("*.log"))
    assert any("0A0#3081" in p.read_text() for p in logs), [p.name for p in logs]  # drive 0x20's EMCY 0x8130
