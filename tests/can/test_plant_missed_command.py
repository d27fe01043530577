"""A command that never comes is counted by the plant (lockstep timeout), not silently absorbed."""

from __future__ import annotations

import time

from can_site import Site
from canopen_helpers import node_target


def test_missing_commands_are_counted(site: Site) -> None:
    with node_target("plant_node", [], "plant", 0x10, site) as t:
        rc = t.node.sdo["Run control"]
        rc["command_timeout_us"].raw = 20000
        t.node.nmt.send_command(0x01)
        t.capture.clear()
        rc["run_periods"].raw = 5
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not (rc["state"].raw == 0 and rc["period_index"].raw == 4):
            time.sleep(0.02)
        assert rc["period_index"].raw == 4
        syncs = t.capture.with_id(0x80)
        assert len(syncs) == 5
        # periods 0..3 ended without a command (the 5th is still open when the plant holds)
        assert rc["missed_commands"].raw == 4
        status = [f[5] for f in t.capture.with_id(0x290)]
        assert len(status) == 5 and all(s & 0x04 for s in status[1:])
