"""A CiA 402 drive the bench did not configure: the project's drive_node with the plant_node behind it as
its motor, alone on their own bus `vcan_motor`, joined to vcan0 by can-gw rules that pass only the drive's
CANopen frames (NMT, SYNC, its SDO, PDOs, heartbeat and EMCY, and the master's heartbeat).

In the CAN box (a host without kernel CAN) the stand-in lives in the session's slot (tests/can/can_site.py)
and is joined the same way to the slot's tap, which the bench's master then uses as its bus (`--interface
slcan --bus <the tap's channel>`, as a user's python-can script does): can-gw routes a frame once (the
module's max_hops), so the drive's bus is joined to the tap itself, not to vcan0 behind it.

The plant and the drive are configured as in tests/can/cia402_loop.py (the plant a SYNC consumer sampling
at each SYNC the bench sends; the drive's PI at the bench's cycle). The drive's 402 state is left to the
bench.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

import canopen
from can_site import Site
from cia402_loop import DRIVE_ID, PLANT_ID, BootWatch, configure_motor

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
        site: Site,
        eds_dir: Path = EDS_DIR,
        law: Callable[[canopen.RemoteNode, float], int] | None = None,
    ) -> None:
        """site: where the master's bus is (the host's vcan0, or the session's slot of the CAN box); eds_dir: the
        EDS files of the node binaries (a user law's build: its merged drive.eds); law: see
        cia402_loop.configure_motor."""
        self.cycle_s, self.site, self.eds_dir, self.law = cycle_s, site, eds_dir, law
        self.bus = site.iface if site.lease is None else site.lease.tap_link
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

    def master_args(self) -> list[str]:
        """`bench run` options that put the master on the stand-in's bus."""
        if self.site.lease is None:
            return ["--bus", self.site.iface]
        return ["--interface", "slcan", "--bus", self.site.lease.tap_channel]

    def _sh(self, *cmd: str, check: bool = True) -> None:
        """A command where the stand-in lives: this machine, or the slot's namespace in the box."""
        lease = self.site.lease
        if lease is None:
            _sh(*cmd, check=check)
            return
        rc, out = lease.ctl.sh(lease.in_ns(list(cmd)) + " 2>&1")
        if check and rc != 0:
            raise RuntimeError(f"`{' '.join(cmd)}` failed in the box: {out.strip()}")

    def start(self) -> None:
        if self.site.lease is None:
            _sh("modprobe", "-a", "vcan", "can-gw", check=False)
        self._sh("ip", "link", "del", MOTOR_BUS, check=False)  # one a killed session left, with its routes
        self._sh("ip", "link", "add", MOTOR_BUS, "type", "vcan")
        self._sh("ip", "link", "set", MOTOR_BUS, "up")
        if self.site.lease is not None:  # the test reaches vcan_motor through the tap while it configures
            for src, dst in ((self.bus, MOTOR_BUS), (MOTOR_BUS, self.bus)):
                self._route(["-s", src, "-d", dst, "-e"])
        self.net = net = canopen.Network()
        if self.site.lease is None:
            net.connect(interface="socketcan", channel=MOTOR_BUS)
        else:
            net.connect(**self.site.bus_kwargs())
            Site.drain(net.bus.recv)  # what the guest kept for the tap before
        plant = canopen.RemoteNode(PLANT_ID, str(self.eds_dir / "plant.eds"))
        drive = canopen.RemoteNode(DRIVE_ID, str(self.eds_dir / "drive.eds"))
        for node in (plant, drive):
            node.sdo.RESPONSE_TIMEOUT = 5.0
            net.add_node(node)
        boot = BootWatch(net, (PLANT_ID, DRIVE_ID))
        for name, nid in (("plant_node", PLANT_ID), ("drive_node", DRIVE_ID)):
            self.procs.append(self.site.node(name, ["--iface", MOTOR_BUS, "--node-id", str(nid)]).start())
        boot.wait(30.0)
        configure_motor(plant, drive, self.cycle_s, self.law)
        plant.nmt.state = "OPERATIONAL"
        drive.nmt.state = "OPERATIONAL"
        if self.site.lease is not None:  # the tap is the master's now: one client at a time
            net.disconnect()
            self.net = None
            for rule in self.rules:
                self._sh("cangw", "-D", *rule)
            self.rules = []
        for src, dst, ids in ((self.bus, MOTOR_BUS, TO_DRIVE), (MOTOR_BUS, self.bus, FROM_DRIVE)):
            for cob in ids:
                self._route(["-s", src, "-d", dst, "-e", "-f", f"{cob:03X}:7FF"])

    def _route(self, rule: list[str]) -> None:
        self._sh("cangw", "-A", *rule)
        self.rules.append(rule)

    def alive(self) -> bool:
        return all(p.alive() for p in self.procs)

    def stop(self) -> None:
        for rule in self.rules:
            self._sh("cangw", "-D", *rule, check=False)
        self.rules = []
        for p in self.procs:
            p.stop()
        self.procs = []
        if self.net is not None:
            self.net.disconnect()
            self.net = None
        self._sh("ip", "link", "del", MOTOR_BUS, check=False)
