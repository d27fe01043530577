"""SocketCAN on this host's kernel (vcan0, can0, ...; inside the VM too): candump records the bus, the kernel filters
the master's socket, the fault gateway joins the plant's bus and the drive's, the links are brought up at their bit
rate and their state noted before and after the run."""

from __future__ import annotations

from typing import Any

import can

from bench.canbus import ensure_vcan, host_has_vcan, link_info, prepare_can_link
from bench.run.bus.kind import BusKind, FrameSource, Recorders, master_ids, open_can_bus
from bench.run.options import RunOptions


class HostSocketCanKind(BusKind):
    label = "SocketCAN on this host"
    kernel_can = True
    nodes_here = True

    def __init__(
        self, bus: str, drive_bus: str | None = None, make: tuple[str, ...] = (), virtual: bool = False
    ) -> None:
        super().__init__(bus, drive_bus)
        self.make = make  # the virtual links made when missing (the fault gateway's second bus)
        self.virtual = virtual
        self.filters: list[dict[str, int]] = []

    def needs_own_vm(self) -> bool:
        return not host_has_vcan(self.bus)

    def prepare_links(self, held: Any, bitrate: int | None) -> dict[str, dict[str, Any] | None]:
        out: dict[str, dict[str, Any] | None] = {}
        for name in self.names:
            if name in self.make:
                ensure_vcan(name)
            prepare_can_link(name, bitrate)
            out[name] = link_info(name)
        return out

    def link_infos(self, held: Any, names: list[str]) -> dict[str, dict[str, Any] | None]:
        return {name: link_info(name) for name in names}

    def recorder(self, rec: Recorders, opened: bool) -> FrameSource | None:
        return None if opened else rec.candump(self.bus)

    def master_bus(self, opts: RunOptions, held: Any) -> can.BusABC:
        # The master only needs its nodes' SDO answers and heartbeats: filtering in the kernel keeps the PDO stream
        # (thousands of frames per second) out of this process's socket, which a slow Python (the VM) could not
        # drain, and which the recorder records anyway. EMCYs stay out too: a node may send hundreds a second (one
        # per foreign SYNC), which left the master's notifier seconds behind in the VM (heartbeats and SDO answers
        # queued behind them: a live node taken for lost); the decoder lists every EMCY from the record, and the
        # heartbeats judge liveness.
        self.filters = master_ids(opts)
        return open_can_bus(opts, opts.interface, self.filters)

    def hear_also(self, bus: can.BusABC, held: Any, cob_id: int) -> None:
        bus.set_filters([*self.filters, {"can_id": cob_id, "can_mask": 0x7FF}])
