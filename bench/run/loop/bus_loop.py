"""The lockstep loop over a bus (a part of Session over SocketCAN or another python-can interface): the plant runs
the periods the master wrote to run_periods and holds; the master waits for its hold announcement (an
event-driven TPDO, no polling while the loop runs), confirmed by SDO, with an SDO poll as a fallback, and checks
the nodes' lives (Liveness) while it waits. No time limit: load may slow the loop as much as it likes; what ends
a wait early is a lost node or a stall with both nodes alive."""

from __future__ import annotations

import queue
import struct
import threading
import time
from collections.abc import Callable

import canopen
from can import CanError
from canopen.sdo.exceptions import SdoError

from bench.run.bus.liveness import Liveness, LoopStopped
from bench.run.options import RunOptions

POLL_ANSWER_S = 0.4  # SDO answer time of the progress poll during a segment (a fallback: a miss costs nothing)
# The master's own bus failing (the CAN box's SLCAN port closes when its VM ends: "Could not read from serial
# device") is, in a run whose box or node died, the watch's to name: it is given this long to see it.
BUS_ERROR_GRACE_S = 10.0


class BusLoop:
    def __init__(
        self, plant: canopen.RemoteNode, opts: RunOptions, liveness: Liveness | None, stall_s: float | None = None
    ) -> None:
        self.plant = plant
        self.opts = opts
        self.stall_s = opts.stall_s if stall_s is None else stall_s  # longer in the CAN box (options.BOX_STALL_S)
        self.liveness = liveness
        self._hold = threading.Event()
        self._hold_index = -1

    def arm(self) -> None:
        """Before a segment's run_periods write: a hold announced before it is not this segment's."""
        self._hold.clear()

    def on_hold(self, cob_id: int, data: bytearray, ts: float) -> None:
        if len(data) != 5:  # a foreign frame on the announcement's identifier (the decoder counts it)
            return
        index, state = struct.unpack_from("<IB", bytes(data))
        if state == 0:
            self._hold_index = index
            self._hold.set()

    def run(self, target_index: int, tick: Callable[[], None] | None) -> None:
        """Wait until the plant holds at or after `target_index` (the master has written run_periods)."""
        rc = self.plant.sdo["Run control"]
        # No time limit: load may slow the loop as much as it likes. What ends a wait early is a lost
        # node (heartbeats, processes: bench/run/bus/liveness.py) or a stall with both nodes alive.
        index, moved = -1, time.monotonic()
        last_poll = 0.0
        while True:
            # the hold announcement (no bus load, no CPU while the loop runs), confirmed by SDO (a frame of
            # the same identifier and length from elsewhere must not end a segment early) ...
            if self._hold.wait(timeout=0.1) and self._hold_index >= target_index:
                self._hold.clear()
                if self._poll(rc, target_index) is True:
                    return
            self._hold.clear()
            self.check_alive(index)
            now = time.monotonic()
            if now - last_poll < 0.5:
                continue
            last_poll = now
            if tick:
                tick()
            # ... and, should it be missed, the same information by SDO
            got = self._poll(rc, target_index)
            if got is True:
                return
            was, index = index, (got if got is not None else index)
            if index != was:
                moved = time.monotonic()
            elif time.monotonic() - moved > self.stall_s:  # also when the plant stops answering SDO
                self.check_alive(index)
                raise LoopStopped(
                    "frames_lost",
                    f"the loop stalled at period {index}: both nodes alive, no "
                    f"progress for {self.stall_s:g} s (a frame of the loop was lost on the "
                    "bus, or the plant no longer answers SDO)",
                    at_period=index,
                )

    def _poll(self, rc, target_index: int) -> bool | int | None:  # type: ignore[no-untyped-def]
        """The plant's period index by SDO: True when it holds at or after target_index, else the index
        (None: no answer). A short answer time, so that a dead plant does not hold up the liveness checks
        for the usual 5 s; after a miss, a late answer is let in and dropped before the next request."""
        sdo, wait = self.plant.sdo, self.plant.sdo.RESPONSE_TIMEOUT
        sdo.RESPONSE_TIMEOUT = POLL_ANSWER_S
        try:
            index = rc["period_index"].raw
            if index >= target_index and rc["state"].raw == 0:
                return True
            return int(index)
        except SdoError:
            self.check_alive(-1 if self._hold_index < 0 else self._hold_index)
            time.sleep(POLL_ANSWER_S)
            sdo.responses = queue.Queue()
            return None
        except CanError:
            self._bus_failed(-1 if self._hold_index < 0 else self._hold_index)
            raise
        finally:
            sdo.RESPONSE_TIMEOUT = wait

    def _bus_failed(self, index: int) -> None:
        """The master's bus failed under a request: when a node or the CAN box died (the box's SLCAN port closes
        with its VM), the watch names it within BUS_ERROR_GRACE_S, and that is the run's end (node_lost), not the
        bus's error; else the error is the run's (the caller re-raises it). Found under load: the bus's read error
        reached the run before the watch saw the box's VM end (test_box: exit 1 instead of 8)."""
        end = time.monotonic() + BUS_ERROR_GRACE_S
        while self.liveness is not None and time.monotonic() < end:
            self.check_alive(index)
            time.sleep(0.2)

    def check_alive(self, index: int) -> None:
        if self.liveness is None:
            return
        lost = self.liveness.verdict()
        if lost is not None:
            lost.at_period = index if index >= 0 else None
            raise lost
