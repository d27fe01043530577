"""How a run is made (bus, node-IDs, which nodes the bench starts, heartbeats, chunking): RunOptions, the one
record every layer of a run reads (the master's session, its configuration and direct loop, the pipeline),
and its values from a `bench run` / `bench capture` command line."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.eds import default_node_id


@dataclass
class RunOptions:
    bus: str = "direct"  # "direct" or a CAN channel (vcan0, can0, ...)
    interface: str = "socketcan"  # python-can interface for non-direct buses
    bitrate: int | None = None
    fd: bool = False
    data_bitrate: int | None = None
    plant_id: int = field(default_factory=lambda: default_node_id("plant"))  # the EDS's NodeID (0x10)
    drive_id: int = field(default_factory=lambda: default_node_id("drive"))  # (0x20)
    # the drive's own interface when it sits on another adapter of the same bus (a lab bench with two USB
    # adapters: plant, master and recorder on can0, the drive on can1); None: the drive is on `bus`
    drive_bus: str | None = None
    # the drive: "node" (the Linux process build/bin/drive_node) or "mcu" (the Cortex-M4F image under QEMU,
    # reached over SLCAN on `drive_tty`, joined to the drive's bus by the kernel: bench/run/bus/slcan_bridge.py)
    drive: str = "node"
    drive_tty: str | None = None
    start_plant: bool = True  # start the C plant process (False: a physical plant/drive is on the bus)
    start_drive: bool = True  # start the C drive process (False: a physical drive implements drive.eds)
    out: Path | None = None  # where the node processes' output goes (None: nowhere)
    # record every frame (candump / in-process); off only to time the loop alone (then nothing is decoded: the
    # result has no periods)
    record: bool = True
    chunk_periods: int = 65_536  # periods per chunk of the pipeline (direct mode: per C call)
    heartbeat_ms: int = 100  # both nodes' heartbeat producer time (0x1017)
    # consumer time (0x1016 of each node, and the bench's): a node silent this long is named and the run stops
    # (10 heartbeats: load in a VM must not look like a dead node)
    heartbeat_timeout_ms: int = 1000
    stall_s: float = 10.0  # both nodes alive, the period index still for this long: a frame was lost
    # vcan buses in the CAN box (bench/run/bus/box) even where the host could carry them (--box, BENCH_BOX=1);
    # without it the box is used only where the host's kernel cannot (bench/run/bus/buses.py box_reason)
    box: bool = False
    # a current law prototyped in Python (bench/law_py.py: an object of a class with the C interface's face), in place
    # of the registered law its `law` names; direct bus only (its methods are called in this process)
    py_law: Any = None


# The Cortex-M4F image of `--drive mcu` runs under qemu-system-arm's emulation (TCG) behind a serial SLCAN
# link: neither is real time, and a loaded host stalls them for seconds. With the 1 s consumer time a healthy
# image then lost the plant's heartbeat and entered its safe state (EMCY 0xFF04) in the middle of a lockstep
# run (2 burners on this 2-core host). The consumer time of both nodes and the bench with --drive mcu:
MCU_HEARTBEAT_TIMEOUT_MS = 5000
# The nodes' own consumer time (0x1016) when they run in the CAN box: QEMU's software emulation under a loaded host
# starves one node process of the guest while the other runs (the soak of issue 52 saw a plant silent for 1.5 s
# during configuration, and the drive's 1 s consumer raised EMCY 0x8130: in the loop it would have entered its safe
# state). The bench's own watch keeps heartbeat_timeout_ms and, in lockstep, judges such a node by its process
# (liveness.py STARVED_S, the same 5 s); the nodes, which cannot tell a starved peer from a dead one, get the same
# allowance (in real time too: the box cannot hold a real-time period anyway, docs/VM.md).
BOX_CONSUMER_MS = 5000
# ... and under two burners plus a second VM the image answered an SDO read after 12 s (its emulation and the
# serial path starved): with --drive mcu the master waits this long for the image's SDO answers, and in
# lockstep the bench gives the silent image this long before naming it lost (a dead QEMU or slcand process
# is named at once, by its exit).
MCU_STALL_S = 30.0
# The same for the nodes in the CAN box: the second soak of issue 52 (the box beside a CI run with two burners of
# its own and the soak's two) saw an SDO answer of the plant take over 5 s and a lockstep segment's end over 10 s.
# The box's SDO answers and a stall with both nodes alive are given this long there (a node that dies is named at
# once by its process, one that falls silent by its heartbeat, as before).
BOX_STALL_S = 30.0


def run_options(args: Any, out: Path) -> RunOptions:
    """RunOptions from the command line of `bench run` or `bench capture` (which has fewer options)."""
    drive = getattr(args, "drive", "node")
    return RunOptions(
        bus=args.bus,
        drive_bus=getattr(args, "drive_bus", None),
        interface=getattr(args, "interface", "socketcan"),
        bitrate=getattr(args, "bitrate", None),
        fd=getattr(args, "fd", False),
        data_bitrate=getattr(args, "data_bitrate", None),
        plant_id=args.plant_id,
        drive_id=args.drive_id,
        start_plant=not getattr(args, "no_plant", False),
        start_drive=not getattr(args, "no_drive", False),
        out=out,
        drive=drive,
        drive_tty=getattr(args, "drive_tty", None),
        heartbeat_timeout_ms=MCU_HEARTBEAT_TIMEOUT_MS if drive == "mcu" else RunOptions.heartbeat_timeout_ms,
        box=getattr(args, "box", False),
        py_law=getattr(args, "py_law_obj", None),
    )
