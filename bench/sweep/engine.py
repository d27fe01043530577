"""Where a study's points run: dask.distributed (an embedded LocalCluster, or an existing cluster by its
scheduler's address), or serially in this process (`--serial`: the reference a cluster's table must equal,
and a debugger's friend).

Points go out in batches (bench/sweep/point.py run_batch) and their rows come back as they complete
(`as_completed`): the caller writes them at once. Workers of an existing cluster need this package and
its built C library: see docs/SWEEPS.md.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from bench.sweep.point import run_batch

Rows = list[dict[str, Any]]
WAIT_WORKERS_S = 120  # an existing cluster without workers: how long to wait for one
DASHBOARD = "127.0.0.1:0"  # the embedded cluster's dashboard: this machine only, a free port


def batches(points: list[dict[str, str]], workers: int, max_batch: int = 16) -> list[list[dict[str, str]]]:
    """Batches small enough that every worker gets several (load balance, progress) and large enough that
    a task's scheduling cost stays small next to its points."""
    size = max(1, min(max_batch, len(points) // max(1, 8 * workers)))
    return [points[i : i + size] for i in range(0, len(points), size)]


class WorkerError(RuntimeError):
    """A worker that cannot run points at all (the sweep stops; its table keeps what is done)."""


class Engine:
    """Runs batches of points and yields their rows as they complete."""

    def __init__(
        self,
        scheduler: str | None,
        workers: int | None,
        serial: bool,
        dashboard: bool = True,
        dashboard_address: str = DASHBOARD,
    ) -> None:
        self.serial = serial
        self.py_law: str | None = None  # every point's Python law (FILE.py:Class, bench run --py-law)
        self.client: Any = None
        self.cluster: Any = None
        self.where = "this process (serial)"
        self.dashboard: str | None = None
        self.dashboard_listens = dashboard_address  # the embedded cluster's
        if serial:
            self.workers = 1
            return
        import dask
        from dask.distributed import Client, LocalCluster

        # a point is one C loop in one thread: one thread per worker process, no nested parallelism. No statistical
        # profiler in the workers: it calls sys._current_frames() every 10 ms, which on CPython 3.11 can run the
        # garbage collector while holding the interpreter's thread-list lock and drop the GIL there, while the
        # point's thread holds the GIL and starts a thread (it needs that lock): the worker hangs for good (seen
        # here in a 10^4-point study: py-spy and gdb showed exactly these two threads). docs/SWEEPS.md: clusters.
        dask.config.set({"distributed.worker.daemon": False, "distributed.worker.profile.enabled": False})
        if scheduler:
            self.client = _connect(Client, scheduler)
            if not self.client.scheduler_info(n_workers=-1)["workers"]:
                print(f"bench sweep: the cluster at {scheduler} has no worker yet; waiting up to {WAIT_WORKERS_S} s")
                try:
                    self.client.wait_for_workers(1, timeout=WAIT_WORKERS_S)
                except TimeoutError as exc:
                    self.client.close()
                    raise OSError(f"no worker joined in {WAIT_WORKERS_S} s (docs/SWEEPS.md: starting workers)") from exc
            info = self.client.scheduler_info(n_workers=-1)
            self.workers = max(1, sum(w.get("nthreads", 1) for w in info["workers"].values()))
            self.where = f"the Dask cluster at {self.client.scheduler.address} ({len(info['workers'])} workers)"
        else:
            from bench.stop import spawn_ignoring_sigint
            from bench.sweep.heartbeat import QuietClose

            n = workers or os.cpu_count() or 1
            with contextlib.redirect_stderr(open(os.devnull, "w")):  # noqa: SIM115 - distributed's start-up chatter
                # The workers ignore Ctrl-C (inherited): this process stops them, keeping the rows done.
                self.cluster = spawn_ignoring_sigint(
                    lambda: LocalCluster(
                        n_workers=n,
                        threads_per_worker=1,
                        processes=True,
                        host="127.0.0.1",
                        silence_logs=logging.ERROR,  # no warnings of the tasks a stop cancels
                        dashboard_address=dashboard_address if dashboard else None,
                        # each worker cancels its heartbeat in flight before it closes its comms (no error
                        # on the terminal at a stop); set up before its first beat: bench/sweep/heartbeat.py
                        plugins=(QuietClose(),),
                    )
                )
            self.client = Client(self.cluster)
            self.workers = n
            self.where = f"a local Dask cluster of {n} worker processes"
        with contextlib.suppress(Exception):
            link = self.client.dashboard_link
            self.dashboard = link if dashboard and link else None
        if self.cluster is not None and self.dashboard:
            host = dashboard_address.rpartition(":")[0] or "every interface"
            port = self.dashboard.split("://", 1)[-1].split("/", 1)[0].rpartition(":")[2]
            self.dashboard_listens = f"{host}, port {port}"

    def run(self, scenario_text: str, where: str, fixed: list[str], todo: list[list[dict[str, str]]]) -> Iterator[Rows]:
        if self.serial:
            for batch in todo:
                yield run_batch(scenario_text, where, fixed, batch, self.py_law)
            return
        from dask.distributed import as_completed

        # the scenario's text (a kilobyte) goes with each task: nothing to keep alive between calls
        futures = [self.client.submit(run_batch, scenario_text, where, fixed, b, self.py_law, pure=False) for b in todo]
        try:
            for fut in as_completed(futures):
                try:
                    rows = fut.result()
                except (ImportError, OSError) as exc:  # a worker without the project, or without its C build
                    raise WorkerError(
                        f"a worker of {self.where} cannot run a point: {exc!r}; every worker needs this project "
                        "installed and built (docs/SWEEPS.md)"
                    ) from exc
                yield rows
        finally:
            for f in futures:
                f.cancel()

    def close(self) -> None:
        with contextlib.suppress(Exception):
            if self.client is not None:
                self.client.close()
        with contextlib.suppress(Exception):
            if self.cluster is not None:
                self.cluster.close()


def _connect(client: Callable[..., Any], scheduler: str) -> Any:
    """tcp://HOST:PORT, or the JSON file `dask scheduler --scheduler-file` writes."""
    path = Path(scheduler)
    if path.suffix == ".json" and path.exists():
        address = json.loads(path.read_text())["address"]
    else:
        address = scheduler
    return client(address, timeout="10s")
