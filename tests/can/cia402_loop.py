"""The project's drive node as a CiA 402 device with its "motor" behind it, for the tests over a real bus:
drive_node and plant_node started on one interface, the plant a SYNC consumer (0x1005 bit 30 clear: it
produces no SYNC and samples at each SYNC it receives), the measurement and command PDOs wired as the
bench wires them, the drive's PI tuned for a slow cycle. Whoever produces SYNC (the test, or the bench's
CiA 402 master) paces the loop; no Python runs per period in the loop itself.

Slow cycles because the tests run in the VM, which stalls processes up to ~150 ms: the plant's model is
exact at any Ts (its discretisation), the drive's PI bandwidth is 1/(12 Ts)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import canopen
from can_site import Site

from bench.paths import EDS_DIR
from bench.run.bus.nodes import NodeProcess

PLANT_ID, DRIVE_ID = 0x10, 0x20
RUN_FOREVER = 0xFFFFFFFF


@dataclass
class Loop:
    net: canopen.Network
    plant: canopen.RemoteNode
    drive: canopen.RemoteNode
    procs: tuple[NodeProcess, NodeProcess]


class BootWatch:
    """The nodes' boot-up messages (0x700 + id, one byte 0), heard from before the processes start: a boot-up
    sent while the test was not yet listening (this process descheduled on a loaded machine between starting
    the nodes and subscribing) would be missed for good."""

    def __init__(self, net: canopen.Network, ids: tuple[int, ...]) -> None:
        self.net, self.ids = net, ids
        self.seen: set[int] = set()
        for i in ids:
            net.subscribe(0x700 + i, self._on_boot)

    def _on_boot(self, cob_id: int, data: bytearray, ts: float) -> None:
        if len(data) == 1 and data[0] == 0:
            self.seen.add(cob_id - 0x700)

    def wait(self, timeout_s: float = 15.0) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not set(self.ids) <= self.seen:
            time.sleep(0.02)
        for i in self.ids:
            self.net.unsubscribe(0x700 + i, self._on_boot)
        missing = set(self.ids) - self.seen
        assert not missing, f"no boot-up from node(s) {sorted(hex(i) for i in missing)}"


def configure_motor(
    plant: canopen.RemoteNode,
    drive: canopen.RemoteNode,
    cycle_s: float,
    law: Callable[[canopen.RemoteNode, float], int] | None = None,
) -> None:
    """The plant as the drive's motor (SYNC consumer, locked rotor, running without end) and the drive's
    current loop at the cycle (PI, bandwidth 1/(12 Ts), no estimator, measurement timeout 10 cycles); the
    PDOs wired. `law(drive, bandwidth_Hz)`: another current law instead of the PI, given the bandwidth before
    the cycle is written (every law checks its parameters against Ts); it returns the law's controller value."""
    sdo = plant.sdo
    sdo["Motor preset"].raw = "you2019"
    sdo["Motor model"]["mech_mode"].raw = 1  # locked (ValueNames free, locked, imposed_speed)
    sdo["Inverter"]["Ts_s"].raw = cycle_s
    # an ideal inverter: the preset's dead time (2 us at a 55 us PWM period: ~11 V against the current's
    # sign) drives a slow PI into a limit cycle of +-7 A (seen in direct mode at 50 ms)
    sdo["Inverter"]["t_dead_s"].raw = 0.0
    sdo["COB-ID SYNC message"].raw = 0x80  # bit 30 clear: no SYNC of its own, it samples at the master's
    sdo["Run control"]["mode"].raw = 0
    sdo["Run control"]["run_periods"].raw = RUN_FOREVER
    motor, ctl, outer = sdo["Motor model"], drive.sdo["Controller"], drive.sdo["Outer loops"]
    ctl["controller"].raw = 1  # pi (0x2200:01 ValueNames, the papers' law folders in order)
    you = drive.sdo["Online tuning"]  # the PI's and You 2019's record: You 2019's drive pipeline (its law.eds)
    # You 2019's current estimator predicts i(k+1) by forward Euler: unstable at Ts >> L/R (3 ms here)
    you["estimator_enable"].raw = 0
    bw = 1.0 / (12 * cycle_s)  # the bandwidths before Ts: each is checked against it (< 1/(6 Ts), 1/(2 Ts))
    you["pi_bandwidth_Hz"].raw = max(1.0, bw)
    if law is not None:
        ctl["controller"].raw = law(drive, max(1.0, bw))
    you["estimator_bandwidth_Hz"].raw = max(1.0, bw)
    ctl["speed_loop_divider"].raw = 1  # the speed loop's Nyquist (x the divider) and the cascade's order
    outer["position_bandwidth_Hz"].raw = max(0.01, bw / 8)
    outer["speed_bandwidth_Hz"].raw = max(0.1, bw / 2)
    ctl["Ts_s"].raw = cycle_s
    for hat, true in (("R_hat_ohm", "R_ohm"), ("Ld_hat_H", "Ld_H"), ("Lq_hat_H", "Lq_H"), ("psi_hat_Wb", "psi_Wb")):
        ctl[hat].raw = motor[true].raw
    drive.sdo["Safe state"]["meas_timeout_periods"].raw = 10
    # plant TPDO1/2 -> drive RPDO1/2, drive TPDO1 -> plant RPDO1 (bench/run/loop/configure.py wire_pdos)
    for n in (plant, drive):
        n.tpdo.read()
        n.rpdo.read()
    for num in (1, 2):
        drive.rpdo[num].cob_id = plant.tpdo[num].cob_id
        drive.rpdo[num].enabled = True
        drive.rpdo[num].save()
    plant.rpdo[1].cob_id = drive.tpdo[1].cob_id
    plant.rpdo[1].enabled = True
    plant.rpdo[1].save()


@contextmanager
def drive_with_motor(
    site: Site, cycle_s: float, drive: canopen.RemoteNode | None = None, drive_iface: str | None = None
) -> Iterator[Loop]:
    """Both nodes started on `iface` (the drive on `drive_iface` if given: another controller on the same
    bus), configured, the plant OPERATIONAL; the drive left in PRE-OPERATIONAL and SWITCH ON DISABLED for
    the master under test (`drive`: a BaseNode402 to use as the drive's node). `site`: the host's bus or the
    session's slot of the CAN box (tests/can/can_site.py)."""
    iface = site.iface
    net = canopen.Network()
    net.connect(**site.bus_kwargs())
    plant = canopen.RemoteNode(PLANT_ID, str(EDS_DIR / "plant.eds"))
    drive = drive or canopen.RemoteNode(DRIVE_ID, str(EDS_DIR / "drive.eds"))
    for n in (plant, drive):
        n.sdo.RESPONSE_TIMEOUT = 3.0
        net.add_node(n)
    procs = (
        site.node("plant_node", ["--iface", iface, "--node-id", str(PLANT_ID)]),
        site.node("drive_node", ["--iface", drive_iface or iface, "--node-id", str(DRIVE_ID)]),
    )
    try:
        boot = BootWatch(net, (PLANT_ID, DRIVE_ID))
        for p in procs:
            p.start()
        boot.wait()
        configure_motor(plant, drive, cycle_s)
        plant.nmt.send_command(0x01)
        yield Loop(net, plant, drive, procs)
    finally:
        for p in procs:
            p.stop()
        net.disconnect()
