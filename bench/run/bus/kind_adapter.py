"""A python-can interface other than SocketCAN (--interface pcan, kvaser, slcan, ...): the master's own bus through a
physical adapter; the recorder listens on the master's handle (an adapter's channel takes one client). The bench's
node processes, where it starts them, still use SocketCAN; the fault gateway, which joins two SocketCAN interfaces,
has nothing to act on."""

from __future__ import annotations

from typing import Any

import can

from bench.run.bus.kind import BusKind, FrameSource, Recorders, open_can_bus
from bench.run.options import RunOptions


class AdapterKind(BusKind):
    label = "a python-can interface"
    nodes_here = True

    def faults_refusal(self) -> str | None:
        return "[[faults]] need SocketCAN (the fault gateway joins two SocketCAN interfaces)"

    def recorder(self, rec: Recorders, opened: bool) -> FrameSource | None:
        return rec.listener() if opened else None

    def master_bus(self, opts: RunOptions, held: Any) -> can.BusABC:
        return open_can_bus(opts, opts.interface, None)
