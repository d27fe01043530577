"""One bus interface: what a run asks of its bus, answered once per kind of bus (BusKind). The kinds: the direct bus
in this process (kind_direct.py), a SocketCAN interface of this host (kind_socketcan.py), vcan buses in the CAN box
(kind_box.py), a python-can interface for a physical adapter (kind_adapter.py). Which one a run uses is chosen in one
place, from the run's options (bench/run/bus/buses.py choose_bus): nothing else compares bus names, every other
module asks the chosen kind (tests/host/test_bus_kinds.py reads the sources for it)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, ClassVar, Protocol

import can
import numpy as np

from bench.run.options import RunOptions


class SettingRefused(RuntimeError):
    """A setting the run cannot have (the scenario's, a node's refusal, or its bus's), said before or while it is
    configured; `bench run` exits 2 naming it (also bench.run.loop.configure.SettingRefused)."""


class FrameSource(Protocol):
    """Where the recorder takes a run's frames from (bench/run/record/sources.py), numpy chunks in bus order."""

    def drain(self, final: bool = False) -> np.ndarray: ...

    def stop(self) -> None: ...


class Recorders(Protocol):
    """The recorder's sources, made by the run (bench/run/recorder.py) for the kind that names one."""

    def candump(self, bus: str) -> FrameSource:
        """candump on this host's interface `bus`, started before the nodes."""
        ...

    def box_candump(self, bus: str) -> FrameSource:
        """candump on `bus` in the run's namespace of the CAN box, started before the nodes."""
        ...

    def in_process(self) -> FrameSource:
        """libhil's frames, a chunk at a time, once the direct bus is open."""
        ...

    def listener(self) -> FrameSource:
        """What the master's own bus handle receives and sends, once it is open."""
        ...


class BusKind(ABC):
    """A kind of bus a run can use. `bus` is the run's channel (the plant's, the master's and the recorder's);
    `drive_bus` the drive's (the same bus, --drive-bus, or with [[faults]] over SocketCAN a bus of its own joined to
    the plant's by the fault gateway). A run asks its kind, never the names."""

    label: ClassVar[str]  # how a message names the kind
    # libhil's bus in this process: no interface, no node processes, simulated time; the canopen master is kept
    # between runs, the nodes' PDO maps are read from the EDS, the fault injector is libhil's
    in_process: ClassVar[bool] = False
    # SocketCAN interfaces of a Linux kernel (the host's, or the CAN box's): candump records them, the kernel filters
    # the master's socket, the fault gateway joins two of them, the links' state is noted before and after the run
    kernel_can: ClassVar[bool] = False
    # the node processes run on this host's CPUs (a real-time run keeps the plant's CPU for it)
    nodes_here: ClassVar[bool] = False
    # the run writes bus.log from the frames it recorded (else candump's own log is the log)
    log_from_frames: ClassVar[bool] = False
    # a virtual bus (vcan: made by `ip link add ... type vcan`, supplied by the VM and the CAN box), not a controller
    virtual: bool = False

    def __init__(self, bus: str, drive_bus: str | None = None) -> None:
        self.bus = bus
        self.drive_bus = drive_bus or bus

    @property
    def names(self) -> tuple[str, ...]:
        """The run's interfaces, each once: the plant's bus, then the drive's when it has its own."""
        return tuple(dict.fromkeys((self.bus, self.drive_bus)))

    def box_why(self) -> str | None:
        """Why the run's buses are in the CAN box, or None."""
        return None

    def needs_own_vm(self) -> bool:
        """True when this host cannot carry the bus and a VM of the run's own must (bench/run/vm_run.py)."""
        return False

    def faults_refusal(self) -> str | None:
        """Why this kind cannot act the scenario's [[faults]] out, or None."""
        return None

    def lease(self, realtime: bool) -> Any:
        """The run's share of the CAN box (bench/run/bus/box/lease.py) when its buses are there, else None."""
        return None

    def release(self, held: Any, keep: Path | None) -> None:
        """The run's hold on its bus (what `lease` gave) given back at the run's very end; what it wrote there goes
        into `keep`. A kind that leases nothing has nothing to give back."""
        return None

    def prepare_links(self, held: Any, bitrate: int | None) -> dict[str, dict[str, Any] | None]:
        """The links up (at their bit rate), before anything listens on them; what the kernel reports of each."""
        return {}

    def link_infos(self, held: Any, names: list[str]) -> dict[str, dict[str, Any] | None]:
        """What the kernel reports of the run's links now (after the run)."""
        return {}

    def end_processes(self, procs: list[Any], timeout_s: float) -> None:
        """The run's node processes ended together before each one's own stop (which then finds it ended): a kind
        whose every request costs (the CAN box) does it in one; others leave it to each process."""
        return None

    def consumer_ms(self, asked: int) -> int:
        """The nodes' heartbeat-consumer time (0x1016) for a run that asks for `asked`."""
        return asked

    def sdo_timeout_s(self) -> float:
        """How long the master waits for a node's SDO answer."""
        return 5.0

    def stall_s(self, asked: float) -> float:
        """How long the lockstep loop waits, both nodes alive, for a segment's end before a frame counts as lost."""
        return asked

    @abstractmethod
    def recorder(self, rec: Recorders, opened: bool) -> FrameSource | None:
        """The recorder's source of this kind's frames, made at its moment: before the bus is open (`opened` False:
        candump, which must hear the nodes' first frames) or once it is (the in-process bus, a listener)."""

    @abstractmethod
    def master_bus(self, opts: RunOptions, held: Any) -> can.BusABC:
        """The master's own bus handle; `held` is what the run holds of its bus: the CAN box's lease, libhil's
        in-process bus (bench/run/bus/direct.py Hil), or None."""

    def master_listeners(self) -> list[can.Listener]:
        """Listeners of this kind's own on the master's bus (next to canopen's)."""
        return []

    def hear_also(self, bus: can.BusABC, held: Any, cob_id: int) -> None:
        """The master's bus lets `cob_id` through too (the plant's hold announcement, once configured); a bus that
        filters nothing (in process, a python-can adapter's) has nothing to do."""
        return None


def master_ids(opts: RunOptions) -> list[dict[str, int]]:
    """What the master needs to hear of its nodes: their SDO answers and heartbeats (as python-can's filters)."""
    ids = (opts.plant_id, opts.drive_id)
    return [{"can_id": 0x580 + i, "can_mask": 0x7FF} for i in ids] + [
        {"can_id": 0x700 + i, "can_mask": 0x7FF} for i in ids
    ]


def open_can_bus(opts: RunOptions, interface: str, filters: list[dict[str, int]] | None) -> can.BusABC:
    """python-can's bus on the run's channel through `interface`, with the run's bit rates and frame format."""
    kwargs: dict[str, object] = {"interface": interface, "channel": opts.bus}
    if filters is not None:
        kwargs["can_filters"] = filters
    if opts.bitrate:
        kwargs["bitrate"] = opts.bitrate
    if opts.fd:
        kwargs["fd"] = True
        if opts.data_bitrate:
            kwargs["data_bitrate"] = opts.data_bitrate
    return can.Bus(**kwargs)  # type: ignore[arg-type]
