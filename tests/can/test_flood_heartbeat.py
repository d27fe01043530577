"""A flood of received frames does not silence a node's heartbeat (CiA 301 error control).

cangen floods vcan0 with SYNCs as fast as it can while the drive node answers each of them with a
synchronous TPDO; the node's heartbeat (producer time 100 ms) must keep coming at about its period: a
node that drains its socket without bound before its timers run fell silent for the whole flood once
(11.5 s during 20,000 SYNCs), and the bench declared it lost. The heartbeats' times are the kernel's
receive timestamps (candump -L, filtered to the heartbeat: its queue holds nothing else).
"""

from __future__ import annotations

import time
from pathlib import Path

from can_site import Site
from canopen_helpers import node_target

DRIVE_ID = 0x20
HEARTBEAT_MS = 100
FLOOD_S = 6.0
# a bound, not a timing: the heartbeat may be late on a loaded machine, not silent for the flood
MAX_GAP_S = 30 * HEARTBEAT_MS / 1000  # a bound for a loaded VM (cangen takes a core); the defect was 11.5 s


def _heartbeat_times(text: str) -> list[float]:
    out = []
    for line in text.splitlines():  # "(1700000000.123456) vcan0 720#05"
        if line.startswith("(") and f" {0x700 + DRIVE_ID:03X}#" in line:
            out.append(float(line[1 : line.index(")")]))
    return out


def test_heartbeat_keeps_its_period_under_a_sync_flood(site: Site, tmp_path: Path) -> None:
    log = tmp_path / "heartbeat.log"
    with node_target("drive_node", [], "drive", DRIVE_ID, site) as t:
        t.node.sdo["Producer heartbeat time"].raw = HEARTBEAT_MS
        tpdo3 = t.node.sdo[0x1802]  # synchronous (every SYNC): each SYNC of the flood costs the node a send too
        cob = tpdo3[1].raw
        tpdo3[1].raw = cob | 0x80000000
        tpdo3[2].raw = 1
        tpdo3[1].raw = cob & 0x7FF
        t.node.nmt.send_command(0x01)
        dump = site.popen(["candump", "-L", f"{site.iface},{0x700 + DRIVE_ID:03X}:7FF"], log)
        try:
            # candump listens once it has logged a heartbeat (a bound)
            assert site.wait_for_output(log, f"{0x700 + DRIVE_ID:03X}#", 120), "candump logged no heartbeat"
            t_start = site.now()  # the clock of the kernel that stamps candump's frames
            gen = site.popen(
                ["cangen", site.iface, "-I", "080", "-L", "1", "-D", "i", "-g", "0", "-i"], tmp_path / "gen.out"
            )
            try:
                time.sleep(FLOOD_S)
            finally:
                gen.kill()
                gen.wait(timeout=30)
            t_stop = site.now()
            time.sleep(1.0)  # the heartbeats after the flood, and the backlog served
        finally:
            dump.terminate()
            dump.wait(timeout=30)
        text = site.read(log)
        assert t.proc.alive(), "the drive node died in the flood"
    times = [x for x in _heartbeat_times(text) if t_start <= x <= t_stop]
    gaps = [b - a for a, b in zip([t_start, *times], [*times, t_stop], strict=True)]
    print(f"{len(times)} heartbeats in {t_stop - t_start:.1f} s of flood, longest gap {max(gaps):.3f} s")
    assert max(gaps) <= MAX_GAP_S, f"heartbeat silent for {max(gaps):.1f} s during the flood ({len(times)} seen)"
