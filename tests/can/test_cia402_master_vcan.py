"""`bench run --drive-profile cia402` over vcan0 against a CiA 402 drive it did not build (the stand-in of
tests/can/cia402_standin.py: the drive node with the plant behind it on a bus of its own). On a host without
kernel CAN the stand-in is in the CAN box and the master on the host, on the slot's tap through python-can's
slcan interface (`--interface slcan --bus socket://...`, as `bench box status` prints it).
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import canopen
import pytest
from bench_cli import bench_cli, spawn_bench
from bench_proc import pids
from can_site import Site
from cia402_standin import DRIVE_ID, StandIn

from bench.paths import EDS_DIR, REPO
from bench.run.options import BOX_STALL_S

CYCLE_MS = 50  # the box's guest (QEMU's software emulation) stalls processes up to ~150 ms
# Bounds on waits, not timings: in the CI's VM a bench's start-up (imports) takes ~25 s and its way out
# (disable, decode, plot) up to a minute; a CI run once took longer than 60 s after Ctrl-C.
STEP = REPO / "scenarios" / "you2019_step.toml"


@pytest.fixture
def standin(site: Site) -> Iterator[StandIn]:
    with StandIn(CYCLE_MS / 1000, site) as s:
        yield s


def run_args(standin: StandIn, out: Path, *extra: str) -> list[str]:
    """`bench run`'s arguments against the stand-in drive."""
    opts = [*standin.master_args(), *f"--drive-profile cia402 --cycle-ms {CYCLE_MS}".split()]
    return ["run", str(STEP), *opts, "--out", str(out), *extra]


def wait_playing(proc: subprocess.Popen[bytes]) -> bytes:
    """The bench's output up to its "playing" line (the drive is OPERATION ENABLED)."""
    assert proc.stdout is not None
    seen, deadline = b"", time.monotonic() + 300
    while b"playing" not in seen and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line and proc.poll() is not None:
            break
        seen += line
    assert b"playing" in seen, seen + (proc.stderr.read() if proc.stderr else b"")
    return seen


def read_drive(site: Site, *indices: int) -> list[int]:
    """The drive's objects read by SDO from a master of the test's own."""
    net = canopen.Network()
    net.connect(**site.bus_kwargs())
    try:
        node = canopen.RemoteNode(DRIVE_ID, str(EDS_DIR / "drive.eds"))
        node.sdo.RESPONSE_TIMEOUT = BOX_STALL_S if site.in_box else 5.0  # the bench's bound in the box
        net.add_node(node)
        return [int(node.sdo[i].raw) for i in indices]
    finally:
        net.disconnect()


def sdo_statusword(site: Site) -> int:
    return read_drive(site, 0x6041)[0]


def test_cst_step_tracks_and_ends_disabled(standin: StandIn, tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = bench_cli(*run_args(standin, out, "--set", "scenario.periods=80"), expect=0)
    assert "no lockstep" in res.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["lockstep"] is False and summary["final_state"] == "SWITCH ON DISABLED"
    assert "OPERATION ENABLED" in summary["states_passed"]
    step = [t for t in summary["tracking"] if t["target_permille"] == 250]
    assert step and step[0]["mean_actual_permille"] is not None, summary["tracking"]
    assert abs(step[0]["relative_error"]) <= 0.25, step
    assert (out / "trace.csv").exists() and (out / "overview.png").exists() and (out / "bus.log").exists()
    assert sdo_statusword(standin.site) & 0x4F == 0x40
    assert standin.alive()


def test_sigint_disables_the_drive(standin: StandIn, tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = spawn_bench(*run_args(standin, out, "--set", "scenario.periods=100000"), text=False)
    try:
        wait_playing(proc)
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        time.sleep(0.05)
        proc.send_signal(signal.SIGINT)  # a second Ctrl-C must not cut the cleanup short
        stdout, stderr = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, (stdout, stderr)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["final_state"] == "SWITCH ON DISABLED"
    from bench.cia402.layout import default_layout
    from bench.cia402.record import decode_log

    trace = decode_log(out / "bus.log", default_layout(DRIVE_ID, CYCLE_MS / 1000))
    last = [s for s in trace.state if s]
    assert last and last[-1] == "SWITCH ON DISABLED", last[-5:]
    assert sdo_statusword(standin.site) & 0x4F == 0x40


def test_sigkill_of_the_bench_faults_the_drive(standin: StandIn, tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = spawn_bench(*run_args(standin, out, "--set", "scenario.periods=100000"), text=False)
    try:
        watches = b"does NOT watch" not in wait_playing(proc)
        proc.kill()
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid in pids(f"candump -L -r {8 << 20} vcan0"):  # the killed bench's recorder (on a kernel bus)
            subprocess.run(["kill", str(pid)], check=False)
    assert watches, "the project's drive has a free 0x1016 entry: it must watch the bench's heartbeat"
    time.sleep(2.0)  # 500 ms consumer time, SYNC and heartbeat stopped with the bench's socket
    sw, code = read_drive(standin.site, 0x6041, 0x603F)
    assert sw & 0x4F == 0x08 and code == 0xFF04, (hex(sw), hex(code))
