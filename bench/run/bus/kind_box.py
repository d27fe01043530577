"""vcan buses in the CAN box (bench/run/bus/box): one VM booted once carries them where this host's kernel cannot (or
when asked: --box, BENCH_BOX=1). The run leases a slot: its node processes, the fault gateway and candump run in the
slot's namespace, the master here over the slot's SLCAN port. QEMU's emulation may starve a node for seconds: its
consumer time, the master's SDO wait and the loop's stall bound are the box's (options.py BOX_CONSUMER_MS,
BOX_STALL_S)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import can

from bench.run.bus.kind import BusKind, FrameSource, Recorders
from bench.run.options import BOX_CONSUMER_MS, BOX_STALL_S, RunOptions


class CanBoxKind(BusKind):
    label = "the CAN box"
    kernel_can = True
    virtual = True

    def __init__(self, bus: str, drive_bus: str | None, why: str) -> None:
        super().__init__(bus, drive_bus)
        self.why = why

    def box_why(self) -> str | None:
        return self.why

    def lease(self, realtime: bool) -> Any:
        """The run's share of the box (the first run of a box says why it is used)."""
        from bench.run.bus.box.lease import acquire

        if realtime:
            print(
                "bench: warning: a real-time run in the CAN box - its nodes run under QEMU's software emulation, "
                "which cannot hold periods below a few ms; the plant's own timing record in the box judges it "
                "(realtime_overrun when it overran), not this host's clock (docs/VM.md, docs/REALTIME.md)",
                file=sys.stderr,
                flush=True,
            )
        return acquire(self.names, say=lambda text: print(f"{text} [{self.why}]", file=sys.stderr, flush=True))

    def release(self, held: Any, keep: Path | None) -> None:
        """What is left of the slot's processes killed, its namespace removed, what they wrote in the box (their
        output, candump's log) moved into `keep`."""
        held.close(keep=keep)

    def prepare_links(self, held: Any, bitrate: int | None) -> dict[str, dict[str, Any] | None]:
        return dict(held.link_infos(list(self.names)))  # in the run's namespace of the box

    def link_infos(self, held: Any, names: list[str]) -> dict[str, dict[str, Any] | None]:
        return dict(held.link_infos(names))

    def end_processes(self, procs: list[Any], timeout_s: float) -> None:
        from bench.run.bus.box.boxproc import BoxPopen, end_all

        end_all([p for p in procs if isinstance(p, BoxPopen)], timeout_s, wake=True)

    def consumer_ms(self, asked: int) -> int:
        return max(asked, BOX_CONSUMER_MS)

    def sdo_timeout_s(self) -> float:
        return BOX_STALL_S

    def stall_s(self, asked: float) -> float:
        return max(asked, BOX_STALL_S)

    def recorder(self, rec: Recorders, opened: bool) -> FrameSource | None:
        return None if opened else rec.box_candump(self.bus)

    def master_bus(self, opts: RunOptions, held: Any) -> can.BusABC:
        # the slot's SLCAN port (python-can's slcan interface): the box passes it SDO answers and heartbeats only
        # (box/life.py MASTER_IDS), and the hold announcement once configured (hear_also)
        # (box/protocol_boxsocket.py: pyserial's socket:// port without its 0.3 s nap at close)
        from bench.run.bus.box.protocol_boxsocket import use

        return can.Bus(interface="slcan", channel=use(held.master_channel), sleep_after_open=0)

    def master_listeners(self) -> list[can.Listener]:
        return [BridgeErrors()]  # a box that ends breaks the port: judged by the session (Session._check_box)

    def hear_also(self, bus: can.BusABC, held: Any, cob_id: int) -> None:
        held.add_master_ids([(cob_id, 0x7FF)])


class BridgeErrors(can.Listener):
    """Takes the errors of the master's SLCAN bridge port (python-can's notifier thread would print a traceback
    for each): a port that breaks ends the run through Session._check_box."""

    def __init__(self) -> None:
        self.errors: list[Exception] = []

    def on_message_received(self, msg: can.Message) -> None:
        pass

    def on_error(self, exc: Exception) -> None:
        self.errors.append(exc)
