"""A CiA 402 drive the bench did not configure: the project's drive_node with the plant_node behind it as
its motor, alone on their own bus `vcan_motor`, joined to vcan0 by can-gw rules that pass only the drive's
CANopen frames (NMT, SYNC, its SDO, PDOs, heartbeat and EMCY, and the master's heartbeat).

The plant and the drive are configured as in tests/can/cia402_loop.py (the plant a SYNC consumer sampling
at each SYNC the bench sends; the drive's PI at the bench's cycle). The drive's 402 state is left to the
bench.
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

import canopen
from cia402_loop import DRIVE_ID, PLANT_ID, configure_motor

from bench.paths import EDS_DIR
from bench.run.bus.nodes import NodeProcess

MOTOR_BUS = "vcan_motor"
TO_DRIVE = (0x000, 0x080, 0x600 + DRIVE_ID, 0x77F) + tuple(0x200 + 0x100 * n + DRIVE_ID for n in range(4))
FROM_DRIVE = (0x580 + DRIVE_ID, 0x700 + DRIVE_ID, 0x80 + DRIVE_ID) + tuple(
    0x180 + 0x100 * n + DRIVE_ID for n in range(4)
)


def _sh(*cmd: str, check: bool = True) -> None:
    res = subprocess.run(list(cmd), capture_output=True, text=True)
    if check and res.returncode != 0:
        raise RuntimeError(f"`{' '.join(cmd)}` failed: {res.stderr.strip()}")


class StandIn:
    def __init__(
        self,
        cycle_s: float,
        bus: str = "vcan0",
        eds_dir: Path = EDS_DIR,
        law: Callable[[canopen.RemoteNode, float], int] | None = None,
    ) -> None:
        """eds_dir: the EDS files of the node binaries (a user law's build: its merged drive.eds); law: see
        cia402_loop.configure_motor."""
        self.cycle_s, self.bus, self.eds_dir, self.law = cycle_s, bus, eds_dir, law
        self.procs: list[NodeProcess] = []
        self.rules: list[list[str]] = []
        self.net: canopen.Network | None = None

    def __enter__(self) -> StandIn:
        try:
            self.start()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.stop()

    def start(self) -> None:
        _sh("modprobe", "-a", "vcan", "can-gw", check=False)
        _sh("ip", "link", "add", MOTOR_BUS, "type", "vcan", check=False)
        _sh("ip", "link", "set", MOTOR_BUS, "up")
        self.net = net = canopen.Network()
        net.connect(interface="socketcan", channel=MOTOR_BUS)
        plant = canopen.RemoteNode(PLANT_ID, str(self.eds_dir / "plant.eds"))
        drive = canopen.RemoteNode(DRIVE_ID, str(self.eds_dir / "drive.eds"))
        for node in (plant, drive):
            node.sdo.RESPONSE_TIMEOUT = 5.0
            net.add_node(node)
        for name, nid in (("plant_node", PLANT_ID), ("drive_node", DRIVE_ID)):
            self.procs.append(NodeProcess(name, ["--iface", MOTOR_BUS, "--node-id", str(nid)]).start())
        time.sleep(1.0)
        configure_motor(plant, drive, self.cycle_s, self.law)
        plant.nmt.state = "OPERATIONAL"
        drive.nmt.state = "OPERATIONAL"
        for src, dst, ids in ((self.bus, MOTOR_BUS, TO_DRIVE), (MOTOR_BUS, self.bus, FROM_DRIVE)):
            for cob in ids:
                rule = ["-s", src, "-d", dst, "-e", "-f", f"{cob:03X}:7FF"]
                _sh("cangw", "-A", *rule)
                self.rules.append(rule)

    def alive(self) -> bool:
        return all(p.alive() for p in self.procs)

    def stop(self) -> None:
        for rule in self.rules:
            _sh("cangw", "-D", *rule, check=False)
        self.rules = []
        for p in self.procs:
            p.stop()
        self.procs = []
        if self.net is not None:
            self.net.disconnect()
            self.net = None
        _sh("ip", "link", "del", MOTOR_BUS, check=False)
