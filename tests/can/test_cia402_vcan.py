"""python `canopen`'s BaseNode402, an independent CiA 402 master, drives the project's drive node over real
vcan: every transition of the state machine, a torque command in cyclic synchronous torque mode (CST)
tracked by the drive with the plant as its motor, a fault (the measurement timeout) and its reset.
The same walk runs over two emulated CAN controllers in tests/can/test_can_controllers.py."""

from __future__ import annotations

import pytest
from can_site import Site
from cia402_loop import DRIVE_ID, drive_with_motor
from cia402_transitions import new_drive_402, walk

CYCLE_S = 0.05  # the VM stalls processes up to ~150 ms: a slow cycle, the loop's model is exact at any Ts


def test_base_node_402_drives_the_drive_node(site: Site) -> None:
    drive = new_drive_402(DRIVE_ID)
    with drive_with_motor(site, CYCLE_S, drive) as loop:
        report = walk(loop, site.iface, CYCLE_S)
    print(report.text())
    assert report.transitions_failed == [], report.text()
    assert report.transitions_done >= 16
    # command: CST target 250 per mille of 1.26 N m -> iq 1 A; the drive's own actual values say so
    assert report.torque_mean_per_mille == pytest.approx(250, rel=0.15), report.text()
    assert max(t for t, _ in report.samples) - min(t for t, _ in report.samples) < 50, report.text()  # settled
    # fault: the plant silenced (NMT stop) -> measurement timeout -> FAULT, 0x603F = 0xFF03, EMCY 0xFF03
    assert report.fault_error_code == 0xFF03 and 0xFF03 in report.emcy_codes, report.text()
    assert report.state_after_reset == "OPERATION ENABLED", report.text()
    assert report.final_state == "SWITCH ON DISABLED"
