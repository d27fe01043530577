"""The master's bus failing mid-run is the run's end as the liveness watch names it (issue 52: under load, the CAN
box's SLCAN port raised "Could not read from serial device" before the watch saw the box's VM end, and the run
exited 1 instead of 8, node_lost: tests/host/test_box.py's killed box). bench/run/loop/bus_loop.py gives the watch
BUS_ERROR_GRACE_S to name it; a bus error with every node alive stays the bus's error."""

from __future__ import annotations

import time
from types import SimpleNamespace
from typing import Any

import pytest
from can import CanOperationError

from bench.run.bus.liveness import LoopStopped
from bench.run.loop import bus_loop
from bench.run.loop.bus_loop import BusLoop


class FailingEntry:
    @property
    def raw(self) -> int:
        raise CanOperationError("Could not read from serial device")


class Watch:
    """Names the box lost `after_s` after the bus failed (None: never)."""

    def __init__(self, after_s: float | None) -> None:
        self.after_s, self.t0 = after_s, time.monotonic()

    def verdict(self) -> LoopStopped | None:
        if self.after_s is not None and time.monotonic() - self.t0 >= self.after_s:
            return LoopStopped("node_lost", "the plant: the CAN box it ran in ended", node="plant",
                               details={"cause": "box_lost"})  # fmt: skip
        return None


def loop(watch: Watch) -> BusLoop:
    sdo = SimpleNamespace(RESPONSE_TIMEOUT=1.0, responses=None)
    plant: Any = SimpleNamespace(sdo=sdo)
    return BusLoop(plant, SimpleNamespace(stall_s=30.0), watch)  # type: ignore[arg-type]


def test_a_bus_error_while_the_box_dies_is_node_lost() -> None:
    bl = loop(Watch(after_s=0.5))  # the watch sees the VM end half a second after the bus failed
    with pytest.raises(LoopStopped) as info:
        bl._poll({"period_index": FailingEntry(), "state": FailingEntry()}, 10)
    assert info.value.status == "node_lost" and info.value.details["cause"] == "box_lost"
    assert isinstance(info.value.__context__, CanOperationError)


def test_a_bus_error_with_every_node_alive_is_the_bus_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bus_loop, "BUS_ERROR_GRACE_S", 0.5)
    bl = loop(Watch(after_s=None))
    with pytest.raises(CanOperationError):
        bl._poll({"period_index": FailingEntry(), "state": FailingEntry()}, 10)
