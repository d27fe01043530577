"""The bench as a CiA 402 master for drives it did not build (`bench run --drive-profile cia402`).

No plant node, no lockstep: the bench paces SYNC in real time with CAN_BCM periodic tasks, walks
the drive to OPERATION ENABLED with `canopen.BaseNode402`, plays the scenario's iq reference
profile as cyclic synchronous torque (CST, mode 10) targets, records every frame and decodes the
log once into a per-SYNC trace.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bench.run.bus.kind import BusKind

NO_LOCKSTEP = "no lockstep: SYNC paced in real time by the bench"


def cia402_bus(args: Any) -> BusKind:
    """The kind of the bus the CiA 402 master joins: its --bus through its --interface, on this host (never the CAN
    box: the master and the drive share one bus, a SocketCAN interface here or a python-can adapter's)."""
    from bench.run.bus.buses import choose_bus

    return choose_bus(args.bus, args.interface, box=False)
