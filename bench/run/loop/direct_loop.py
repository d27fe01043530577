"""The in-process loop of direct mode (a part of Session in direct mode): the C loop on a thread of its own in
chunks, and why it stopped early, named as the liveness monitor names it on a bus."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from bench.run.bus.cpus import PlantCpu, plant_cpu
from bench.run.bus.liveness import NMT_STATES, LoopStopped

if TYPE_CHECKING:
    from bench.run.bus.direct import Hil
    from bench.run.options import RunOptions


def floor_line(floor: dict[str, float]) -> str:
    """The host's floor in one line, and a warning when it makes the period impossible: a plain timer loop late by
    a period in 1 % of its wake-ups (p99 >= Ts) would overrun that often before the bench did any work."""
    ts = floor["period_us"]
    line = (
        f"bench run: the host's floor at Ts = {ts:g} us (a plain timer loop at the plant's priority, "
        f"{floor['periods']} wake-ups): lateness p50 {floor['p50_us']:g} p99 {floor['p99_us']:g} "
        f"p99.9 {floor['p99_9_us']:g} max {floor['max_us']:g} us"
    )
    if floor["p99_us"] >= ts:
        line += (
            f"\nbench run: WARNING: this host cannot hold Ts = {ts:g} us: its own p99 wake-up lateness "
            f"({floor['p99_us']:g} us) is a whole period, so 1 % of the periods or more overrun whatever the "
            "bench does (a longer Ts, or a tuned host: docs/REALTIME.md)"
        )
    elif floor["p99_9_us"] >= ts:
        line += (
            f"\nbench run: WARNING: at Ts = {ts:g} us this host's own p99.9 wake-up lateness "
            f"({floor['p99_9_us']:g} us) is a whole period: expect about 0.1 % of the periods to overrun"
        )
    return line


class DirectLoop:
    """Runs libhil's loop (Session owns one in direct mode). `on_chunk` (the frame source takes the recorded
    frames) is called on the loop's thread after each chunk; `on_stop` when a segment ends or is interrupted,
    so that a waiting loop thread is released."""

    def __init__(self, hil: Hil, opts: RunOptions, realtime: bool = False) -> None:
        self.hil = hil
        self.opts = opts
        self.realtime = realtime
        self._told = False
        self._overflows = 0
        self._isolated = ""  # what left the plant's CPU for the run (PlantCpu.summary)
        self.floor: dict[str, float] | None = None  # the host's floor, probed before the first real-time segment
        self.on_chunk: Callable[[], None] | None = None
        self.on_stop: Callable[[], None] | None = None

    def run(self, n: int, tick: Callable[[], None] | None) -> None:
        """The C loop in chunks on a thread of its own (ctypes releases the GIL), so that this thread
        decodes chunk k (`tick`) while the loop runs chunk k+1: the two cores work at once. After each
        chunk `on_chunk` (the frame source) takes the recorded frames; it blocks while two chunks
        wait, so memory stays bounded when decoding is the slower side."""
        if not self.realtime and n <= self.opts.chunk_periods:
            self._run_here(n, tick)
            return
        ready = threading.Event()
        done = threading.Event()
        stop = threading.Event()
        errors: list[BaseException] = []
        ran = [0]

        def produce() -> None:
            try:
                if self.realtime:
                    ran[0] = self._run_realtime(n, ready)
                while ran[0] < n and not stop.is_set() and not self.realtime:  # in chunks: bounded memory
                    got = self.hil.run(min(self.opts.chunk_periods, n - ran[0]))
                    if got == 0:
                        break
                    ran[0] += got
                    if self.on_chunk is not None:
                        self.on_chunk()
                    ready.set()
            except BaseException as exc:  # noqa: BLE001 - re-raised in the caller's thread
                errors.append(exc)
            finally:
                done.set()
                ready.set()

        th = threading.Thread(target=produce, daemon=True, name="bench-direct-loop")
        th.start()
        try:
            while not done.is_set():
                ready.wait(0.5)
                ready.clear()
                if tick:
                    tick()
        except BaseException:
            if self.realtime:
                self.hil.stop()  # the C threads return at their next deadline
            raise
        finally:
            stop.set()
            if self.on_stop is not None:
                self.on_stop()
            th.join()
        if errors:
            raise errors[0]
        if tick:
            tick()
        if ran[0] != n:
            self._direct_stopped(ran[0], n)

    def _run_here(self, n: int, tick: Callable[[], None] | None) -> None:
        """A segment of one chunk (a sweep's point, most scenarios): on this thread, then decoded. Nothing to overlap,
        so no thread to start and no hand-over of the interpreter's lock between two threads per chunk."""
        ran = 0
        try:
            while ran < n:  # hil_run may return early (its own bound on a call), as in the threaded path
                got = self.hil.run(n - ran)
                if got == 0:
                    break
                ran += got
            if self.on_chunk is not None:
                self.on_chunk()
        finally:
            if self.on_stop is not None:
                self.on_stop()
        if tick:
            tick()
        if ran != n:
            self._direct_stopped(ran, n)

    def _run_realtime(self, n: int, ready: threading.Event) -> int:
        """The segment in real time: one C call (its threads pace the periods), while this thread takes what the
        recorder holds every 0.2 s (`on_chunk`), so that the decoding goes on meanwhile and memory stays bounded."""
        got: list[int] = [0]
        errors: list[BaseException] = []
        if self.floor is None:
            self.floor = self.hil.probe_floor()
            if self.floor is not None:
                print(floor_line(self.floor), flush=True)

        def loop() -> None:
            try:
                got[0] = self.hil.run_realtime(n)
            except BaseException as exc:  # noqa: BLE001 - re-raised below
                errors.append(exc)

        # the plant's CPU kept for the run: the C side moves this process's threads; what else may be moved here
        # (the bench's child processes, the kernel's unbound threads) leaves it too (bench/run/bus/cpus.py)
        cpu = plant_cpu()
        keep = PlantCpu(cpu) if cpu is not None else None
        if keep is not None:
            keep.isolate()
        th = threading.Thread(target=loop, daemon=True, name="bench-direct-realtime")
        th.start()
        try:
            while th.is_alive():
                th.join(0.2)
                if self.on_chunk is not None:
                    self.on_chunk()
                ready.set()
        finally:
            if th.is_alive():  # taking the frames failed: the C threads must not outlive the loop
                self.hil.stop()
                th.join()
            if keep is not None:
                self._isolated = keep.summary()
                keep.release()
        if errors:
            raise errors[0]
        if not self._told:
            isolated = f"; {self._isolated}" if self._isolated else ""
            print(f"bench run: real time: {self.hil.realtime_note()}{isolated}", flush=True)
            self._told = True
        lost = self.hil.receive_overflows()
        if lost > self._overflows:
            print(
                f"bench run: real time: {lost - self._overflows} frames overflowed a node's receive FIFO "
                "(the node was not scheduled for that long): lost to it, as on a CAN controller",
                flush=True,
            )
            self._overflows = lost
        return got[0]

    def _direct_stopped(self, ran: int, n: int) -> None:
        """Why the in-process loop stopped early, named as the liveness monitor names it on a bus: a node
        killed or out of OPERATIONAL (a fault), or a stall (simulated time ran on without a period)."""
        at = self.hil.period()
        down = self.hil.nodes_down()
        for name, state in down.items():
            nid = self.opts.plant_id if name == "plant" else self.opts.drive_id
            how = "was killed" if state == 0xFF else f"left OPERATIONAL: it is {NMT_STATES.get(state, hex(state))}"
            raise LoopStopped(
                "node_lost",
                f"the {name} (node 0x{nid:02X}) {how} at period {at}",
                node=name,
                node_id=nid,
                at_period=at,
                detected_after_s=0.0,
                details={"cause": "killed" if state == 0xFF else "left_operational"},
            )
        raise LoopStopped(
            "frames_lost",
            f"the loop stalled at period {at} after {ran} of {n} periods: 10 s of simulated time without a "
            "period (a frame of the loop was lost and nothing timed out: 0x2003:04 command_timeout_us is 0)",
            at_period=at,
        )
