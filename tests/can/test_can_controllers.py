"""The loop over CAN controllers, as on a lab bench with two USB adapters on one bus: the plant, the master
and the recorder on can0, the drive on can1 (links of type `can`, brought up by the bench at their bit rate).
On this project's machines the controllers are QEMU's emulated Kvaser PCIcan cards (SJA1000, Linux driver
kvaser_pci) on one emulated CAN bus: scripts/run_tests.sh boots the VM with two (`bench vm
--can-controllers 2`).

- traces over can0/can1 equal, bit for bit, those of the direct and the vcan runs;
- summary.json reports each controller's state and error counters, before and after;
- a link taken down mid-run (`ip link set can1 down`) is reported (the drive is lost, the run stops
  node_lost), the missed periods are counted, no process is left behind;
- the bench brings a link up at its bit rate, and says what it needs when it cannot use one.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from bench_proc import NODES, pids, start_long_run
from can_site import Site
from cia402_loop import DRIVE_ID, drive_with_motor
from cia402_transitions import new_drive_402, walk

from bench.canbus import LinkError, link_info, prepare_can_link
from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.verdict.summary import EXIT_CODES
from bench.scenario import load

# the emulated CAN controllers (can0, can1) are the VM's
# (kernel_can: the kernel's CAN in this process, inside the VM on a host without CAN)
pytestmark = pytest.mark.kernel_can

PARITY = REPO / "tests" / "scenarios" / "parity.toml"
CIA402_CYCLE_S = 0.05  # as tests/can/test_cia402_vcan.py


@pytest.fixture(scope="module")
def can_pair() -> tuple[str, str]:
    """can0 and can1, two CAN controllers on one bus; fails (never skips) without them."""
    for name in ("can0", "can1"):
        info = link_info(name)
        if info is None or info["kind"] != "can":
            pytest.fail(
                f"{name}: no CAN controller ({info and info['kind']}); these tests need two on one bus: run them "
                "through scripts/run_tests.sh, or `bench vm --can-controllers 2 -- pytest tests/can/"
                "test_can_controllers.py` (emulated Kvaser PCIcan cards)"
            )
    return "can0", "can1"


def _ip(*args: str) -> None:
    subprocess.run(["ip", "link", "set", *args], check=True)


def test_traces_over_can_controllers_equal_vcan_and_direct(
    can_pair: tuple[str, str], vcan0: str, tmp_path: Path
) -> None:
    plant_bus, drive_bus = can_pair
    sc = load(PARITY)
    direct = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    vcan = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "vcan"), keep_trace=True)
    can = run_scenario(sc, RunOptions(bus=plant_bus, drive_bus=drive_bus, out=tmp_path / "can"), keep_trace=True)
    for res in (vcan, can):
        assert res.status == "ok", (res.summary["stopped"], res.summary["bus_stats"])
        assert res.summary["bus_stats"]["lost_frames"] == 0
    assert direct.trace is not None and vcan.trace is not None and can.trace is not None
    assert can.trace.keys() == direct.trace.keys() == vcan.trace.keys()
    for k in direct.trace:
        if k != "t_s":
            np.testing.assert_array_equal(can.trace[k], direct.trace[k], err_msg=k)
            np.testing.assert_array_equal(can.trace[k], vcan.trace[k], err_msg=k)
    print(f"{len(can.trace['period'])} periods, {len(can.trace)} signals: can0/can1 = vcan0 = direct, bit for bit")
    # each controller's state and counters, from the kernel, before and after
    links = can.summary["can_links"]
    assert set(links) == {plant_bus, drive_bus}
    frames = can.summary["bus_stats"]["frames"]
    for name, rec in links.items():
        before, after = rec["before"], rec["after"]
        assert before["kind"] == after["kind"] == "can"
        assert after["state"] == "ERROR-ACTIVE" and after["bitrate"] == 1_000_000
        assert after["bus_off"] == before["bus_off"] and after["berr_tx"] == 0
        moved = (after["rx_frames"] - before["rx_frames"]) + (after["tx_frames"] - before["tx_frames"])
        assert moved >= frames, (name, moved, frames)  # every frame of the log crossed each controller
    print(json.dumps({n: r["after"] for n, r in links.items()}, indent=1))


def test_a_link_taken_down_mid_run_is_reported(can_pair: tuple[str, str], tmp_path: Path) -> None:
    plant_bus, drive_bus = can_pair
    out = tmp_path / "down"
    proc = start_long_run(out, "--bus", plant_bus, "--drive-bus", drive_bus)
    try:
        log = out.with_name(out.name + ".partial") / "candump.log"
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and not (log.exists() and log.stat().st_size > 200_000):
            time.sleep(0.2)
        assert proc.poll() is None, proc.communicate()
        _ip(drive_bus, "down")
        t_down = time.time()
        stdout, stderr = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
        subprocess.run(["ip", "link", "set", drive_bus, "up"], check=False)
    assert proc.returncode == EXIT_CODES["node_lost"], stdout + stderr
    summary = json.loads((out / "summary.json").read_text())
    stopped = summary["stopped"]
    assert summary["status"] == "node_lost" and stopped["node"] == "drive", stopped
    # named by its heartbeat's silence, well before the 10 s stall detector (a bound for a loaded VM, whose
    # own stalls the watcher does not count against the drive, so a bound, not the consumer time)
    assert stopped["detected_at_unix"] - t_down < RunOptions().stall_s, stopped
    assert 0 < summary["periods"] < 5_000_000
    # the drive's adapter went down: the kernel says so in the summary
    assert summary["can_links"][drive_bus]["after"]["up"] is False
    counters = summary["bus_stats"]
    print(
        f"stopped after {summary['periods']} periods: {stopped['message']}; plant missed "
        f"{counters['plant_missed_commands']}, lost frames {counters['lost_frames']}"
    )
    assert counters["plant_missed_commands"] is not None
    time.sleep(0.5)
    for name in NODES:
        assert not pids(name), f"{name} still running"


def test_the_bench_brings_a_link_up_at_its_bit_rate(can_pair: tuple[str, str]) -> None:
    name = can_pair[1]
    _ip(name, "down")
    assert "brought up at 500000 bit/s" in prepare_can_link(name, 500_000)
    info = link_info(name)
    assert info is not None and info["up"] and info["bitrate"] == 500_000 and info["restart_ms"] == 100
    # up at another rate than asked: refused, with the commands that would change it
    with pytest.raises(LinkError, match=r"up at 500000 bit/s, not the --bitrate 1000000"):
        prepare_can_link(name, 1_000_000)
    _ip(name, "down")
    prepare_can_link(name, None)  # a rate given once stays the link's (the kernel keeps it)
    info = link_info(name)
    assert info is not None and info["bitrate"] == 500_000
    _ip(name, "down")
    _ip(name, "type", "can", "bitrate", "1000000")
    prepare_can_link(name, None)
    with pytest.raises(LinkError, match="no such network interface"):
        prepare_can_link("can9", None)


def test_a_user_without_rights_is_told_the_commands(can_pair: tuple[str, str]) -> None:
    name = can_pair[1]
    _ip(name, "down")
    try:
        # as an unprivileged user (nobody): the bench cannot configure the link and says what it needs
        code = (
            "import sys; from bench.canbus import LinkError, prepare_can_link\n"
            f"try:\n    prepare_can_link({name!r}, None)\nexcept LinkError as e:\n    print(e); sys.exit(3)"
        )
        res = subprocess.run(
            ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", sys.executable, "-c", code],
            capture_output=True,
            text=True,
            cwd=REPO,
            env={**os.environ, "HOME": "/tmp"},
        )
        assert res.returncode == 3, res.stdout + res.stderr
        assert f"sudo ip link set {name} type can bitrate" in res.stdout and "CAP_NET_ADMIN" in res.stdout, res.stdout
    finally:
        prepare_can_link(name, None)


def test_base_node_402_walks_the_drive_over_can_controllers(can_pair: tuple[str, str]) -> None:
    """The CiA 402 walk of tests/can/test_cia402_vcan.py with the master and the plant on can0, the drive on
    can1: every frame of the state machine and the CST loop crosses the bus between two controllers."""
    master_bus, drive_bus = can_pair
    for name in can_pair:
        prepare_can_link(name, None)
    with drive_with_motor(Site(master_bus), CIA402_CYCLE_S, new_drive_402(DRIVE_ID), drive_iface=drive_bus) as loop:
        report = walk(loop, master_bus, CIA402_CYCLE_S)
    print(report.text())
    assert report.transitions_failed == [] and report.transitions_done >= 16, report.text()
    assert report.torque_mean_per_mille == pytest.approx(250, rel=0.15), report.text()
    assert max(t for t, _ in report.samples) - min(t for t, _ in report.samples) < 50, report.text()
    assert report.fault_error_code == 0xFF03 and report.state_after_reset == "OPERATION ENABLED", report.text()
    for name in can_pair:
        info = link_info(name)
        assert info is not None and info["state"] == "ERROR-ACTIVE", info
