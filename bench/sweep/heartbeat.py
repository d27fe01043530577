"""A worker of the embedded cluster closes without cutting its own heartbeat off.

dask.distributed's `Worker.close` stops the heartbeat's periodic callback but leaves a beat already sent
running: it then closes its connection pool, which closes the comm that beat is waiting on, and the
beat logs `distributed.worker - ERROR - Failed to communicate with scheduler during heartbeat` with two
tracebacks (tornado `StreamClosedError`, `CommClosedError ... ConnectionPool.heartbeat_worker`). The
scheduler is still up then (`SpecCluster` closes the nannies, and so their workers, before it); it is
only slow to answer under CPU load, so that a beat is in flight when the worker closes, and the worker
process writes that error to the terminal the sweep shares with it (after Ctrl-C, or at a sweep's end).

`QuietClose`, given to the embedded cluster's workers at their start (before their first beat), runs each
beat as a task it knows; its teardown, which `Worker.close` runs before it closes its connections, stops
the beats and cancels the one in flight. A cancelled call is distributed's own case (`send_recv` drops
that comm, nothing logged), where a closed comm is its error case. Waiting for the beat's answer instead
would deadlock: a worker the scheduler has retired hears "missing" and its beat awaits the worker's close.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

NAME = "bench-quiet-close"
CANCEL_WAIT_S = 2.0  # a cancelled beat ends at its next await; bounded all the same (the nanny kills at 4 s)


class _Beats:
    """The heartbeat callback, each beat a task: the one in flight can be cancelled, and its
    cancellation ends there (the periodic callback sees a beat that returned)."""

    def __init__(self, beat: Callable[[], Awaitable[Any]]) -> None:
        self.beat = beat
        self.current: asyncio.Task[Any] | None = None
        self.stopping = False

    async def __call__(self) -> None:
        if self.stopping:
            return
        task = asyncio.ensure_future(self.beat())
        self.current = task
        try:
            await task
        except asyncio.CancelledError:
            if not self.stopping:  # not ours: the callback itself was cancelled
                raise
        finally:
            self.current = None

    async def stop(self) -> None:
        self.stopping = True
        task = self.current
        if task is not None and not task.done():
            task.cancel()
            await asyncio.wait({task}, timeout=CANCEL_WAIT_S)


class QuietClose(WorkerPlugin):
    """Each heartbeat a task; the teardown stops them and cancels the one in flight."""

    name = NAME

    def __init__(self) -> None:
        self._beats: _Beats | None = None
        self._pc: Any = None

    def setup(self, worker: Any) -> None:
        pc = getattr(worker, "periodic_callbacks", {}).get("heartbeat")
        if pc is None:  # a distributed without that callback: nothing to guard
            return
        self._beats, self._pc = _Beats(pc.callback), pc
        pc.callback = self._beats

    async def teardown(self, worker: Any) -> None:
        if self._pc is None or self._beats is None:
            return
        self._pc.stop()  # no new beat
        await self._beats.stop()
