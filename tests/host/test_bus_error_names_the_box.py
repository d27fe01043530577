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


class EndedBox:
    """A CAN box lease whose box ended (`why`), or is up (None)."""

    def __init__(self, why: str | None) -> None:
        self.why = why

    def gone(self) -> str | None:
        return self.why


def _kind_whose_recorder_fails(why: str | None) -> Any:
    """The direct bus, but leased from a box that `why` ended and whose candump fails to start, as when the box's
    QEMU is killed 0.2 s after the run took its slot."""
    from bench.run.bus.kind_direct import DirectKind

    class Kind(DirectKind):
        def lease(self, realtime: bool) -> Any:
            return EndedBox(why)

        def recorder(self, rec: Any, opened: bool) -> Any:
            if not opened:
                raise RuntimeError("candump on vcan0 in the CAN box failed: -9")
            return super().recorder(rec, opened)

    return Kind("direct", None)


@pytest.mark.parametrize("why", ["its QEMU process ended (killed by signal 9)", None])
def test_a_box_that_ends_while_the_run_starts_is_node_lost(why: str | None, monkeypatch: pytest.MonkeyPatch) -> None:
    """The run's processes starting in a box that ends: node_lost (cause box_lost, exit 8) with what failed, as in
    the loop; the same failure in a box that is up stays the failure (bench run's FAILED, exit 1)."""
    from bench.paths import REPO
    from bench.run import RunOptions, run_scenario
    from bench.run.bus import buses
    from bench.scenario import load

    monkeypatch.setattr(buses, "bus_of", lambda opts, faults=False, box=True: _kind_whose_recorder_fails(why))
    sc = load(REPO / "scenarios" / "you2019_step.toml", ["scenario.periods=50"])
    if why is None:
        with pytest.raises(RuntimeError, match="candump on vcan0 in the CAN box failed"):
            run_scenario(sc, RunOptions(bus="direct"))
        return
    res = run_scenario(sc, RunOptions(bus="direct"))
    stopped = res.summary["stopped"]
    assert (res.status, res.exit_code, res.summary["periods"]) == ("node_lost", 8, 0)
    assert stopped["cause"] == "box_lost" and why in stopped["message"]
    assert stopped["failed"] == "candump on vcan0 in the CAN box failed: -9"
