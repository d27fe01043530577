"""The direct bus: the nodes and the master on libhil's in-process bus (bench/run/bus/direct.py), on simulated
time; its frames from libhil, its faults acted by libhil's injector."""

from __future__ import annotations

from typing import Any

import can

from bench.run.bus.direct import DirectBus
from bench.run.bus.kind import BusKind, FrameSource, Recorders
from bench.run.options import RunOptions


class DirectKind(BusKind):
    label = "the direct bus (in process)"
    in_process = True
    log_from_frames = True

    def recorder(self, rec: Recorders, opened: bool) -> FrameSource | None:
        return rec.in_process() if opened else None

    def master_bus(self, opts: RunOptions, held: Any) -> can.BusABC:
        return DirectBus(held)
