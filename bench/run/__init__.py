"""A run, end to end: scenario -> SDO configuration -> PDO loop -> frames -> decode once ->
trace chunks -> sinks. `run_scenario` is the public entry point (bench/run/pipeline.py).

This module is the run's public face: what the tools (bench/tools: perf, doctor) and other packages use of a
run, whatever floor of bench/run/ holds it (tests/host/test_import_graph.py: bench/tools imports `bench.run`, never
a module inside it). Each name is imported on first use, so that `bench.signals` (what the view worker needs)
does not pull in canopen and the C library: _WHERE says where each lives."""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bench.run.bus.box.life import down as box_down
    from bench.run.bus.box.life import next_accel as box_next_accel
    from bench.run.bus.box.life import read_info as box_info
    from bench.run.bus.box.life import status as box_status
    from bench.run.bus.direct import DirectBus, Hil
    from bench.run.bus.vm import VmOptions, run_in_vm
    from bench.run.bus.vm import readiness as vm_readiness
    from bench.run.loop.configure import HOLD_TPDO, enable_cia402
    from bench.run.loop.session import Session
    from bench.run.options import RunOptions
    from bench.run.pipeline import Pipeline, RunResult, capture_to_log, replay_log, run_scenario
    from bench.run.record.canlog import read_frames
    from bench.run.record.sources import DirectSource, LogFollower
    from bench.run.sinks import TraceFileSink, TraceRows

# name -> (module, its name there); the imports above and __all__ say the same, for a type checker, a linter and the
# import-graph test (tests/host/test_import_graph.py keeps the three equal)
_WHERE: dict[str, tuple[str, str]] = {
    # a run, whole or its halves
    "run_scenario": ("bench.run.pipeline", "run_scenario"),
    "RunOptions": ("bench.run.options", "RunOptions"),
    "RunResult": ("bench.run.pipeline", "RunResult"),
    "Pipeline": ("bench.run.pipeline", "Pipeline"),
    "capture_to_log": ("bench.run.pipeline", "capture_to_log"),
    "replay_log": ("bench.run.pipeline", "replay_log"),
    # the loop step by step: open, reset_nodes, configure, run, statuses, close
    "Session": ("bench.run.loop.session", "Session"),
    "enable_cia402": ("bench.run.loop.configure", "enable_cia402"),
    "HOLD_TPDO": ("bench.run.loop.configure", "HOLD_TPDO"),
    # frames: where they come from, where they go
    "DirectSource": ("bench.run.record.sources", "DirectSource"),
    "LogFollower": ("bench.run.record.sources", "LogFollower"),
    "read_frames": ("bench.run.record.canlog", "read_frames"),
    "TraceFileSink": ("bench.run.sinks", "TraceFileSink"),
    "TraceRows": ("bench.run.sinks", "TraceRows"),
    # buses: the in-process one, the VM, the CAN box
    "DirectBus": ("bench.run.bus.direct", "DirectBus"),
    "Hil": ("bench.run.bus.direct", "Hil"),
    "VmOptions": ("bench.run.bus.vm", "VmOptions"),
    "run_in_vm": ("bench.run.bus.vm", "run_in_vm"),
    "vm_readiness": ("bench.run.bus.vm", "readiness"),
    "box_status": ("bench.run.bus.box.life", "status"),
    "box_info": ("bench.run.bus.box.life", "read_info"),
    "box_down": ("bench.run.bus.box.life", "down"),
    "box_next_accel": ("bench.run.bus.box.life", "next_accel"),
}

__all__ = [
    "DirectBus",
    "DirectSource",
    "HOLD_TPDO",
    "Hil",
    "LogFollower",
    "Pipeline",
    "RunOptions",
    "RunResult",
    "Session",
    "TraceFileSink",
    "TraceRows",
    "VmOptions",
    "box_down",
    "box_info",
    "box_next_accel",
    "box_status",
    "capture_to_log",
    "enable_cia402",
    "read_frames",
    "replay_log",
    "run_in_vm",
    "run_scenario",
    "vm_readiness",
]


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'bench.run' has no attribute {name!r}")
    return getattr(import_module(where[0]), where[1])
