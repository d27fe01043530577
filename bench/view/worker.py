"""What only shows a run - the Rerun recording (and live viewer) and the PNG plots - in two
helper processes, so that it runs on the other core beside the loop, the decoding and the
files, and their imports (rerun ~0.5 s, matplotlib ~0.6 s) overlap with the run.

`prestart()` starts them first thing in `bench run` (before the bench's own imports); the
`ViewWorker` sink then sends the "rerun" process, over a pipe, its settings, the signal list
and every trace chunk as it is decoded; at the end the "plots" process gets what the plots
need (the summary, the step windows, the envelopes). Messages are pickled tuples; replies
come back as JSON lines on a pipe of their own (the processes' stdout and stderr stay the
user's).

This module owns the `ViewWorker` sink and is the processes' entry point; starting and piping to
them is bench/view/worker_procs.py, what runs inside them bench/view/worker_roles.py.

    python -m bench.view.worker ROLE REPLY_FD     (started by prestart(); not a user command)
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from bench.view.worker_procs import (
    _STARTED,
    ROLES,
    _Proc,
    _take,
    discard,
    give_back,
    prestart,
    reuse,
    reusing,
    roles_for,
)
from bench.view.worker_roles import main

__all__ = ["ROLES", "ViewWorker", "_STARTED", "_Proc", "discard", "main", "prestart", "reuse"]


class ViewWorker:
    """The bench's side: a Sink whose chunks go to the rerun process; `finish` hands the plots over."""

    def __init__(
        self,
        name: str,
        folder: Path,
        live: str = "none",
        live_decimate: int | None = None,
        web_port: int = 9090,
        grpc_port: int = 9876,
        rrd: bool = True,
        serve_for: float | None = None,
        bind: str = "127.0.0.1",
        plots: bool = True,
    ) -> None:
        self.spec = {
            "name": name,
            "folder": str(Path(folder).absolute()),  # a kept process keeps the cwd it started in
            "live": live,
            "live_decimate": live_decimate,
            "web_port": web_port,
            "grpc_port": grpc_port,
            "rrd": rrd,
            "serve_for": serve_for,
            "bind": bind,
            "keep": reusing() and live == "none",  # the processes serve the next run too (worker_procs.reuse)
        }
        # each process only when the run needs it (--no-rrd, --no-plots: bench/view/worker_procs.roles_for)
        roles = roles_for(rrd, plots, live)
        self.rerun = _take("rerun") if "rerun" in roles else None
        self.plots = _take("plots") if "plots" in roles else None
        self.procs = [p for p in (self.rerun, self.plots) if p is not None]
        for proc in self.procs:
            proc.send("spec", self.spec)
        self.live = live
        self.url: str | None = None
        self.skipped: str | None = None  # why the recording and the plots were not made
        self.live_stats: dict[str, Any] | None = None  # what the live viewer was sent (bench/view/live_feed.py)

    def wait_ready(self) -> None:
        """Block until the rerun process has its viewer up (serving: the ports are taken, or the error is known)."""
        if self.rerun is not None:
            self.url = self.rerun.first().get("url")

    def begin(self, signals: list[Any], ctx: Any = None) -> None:
        if self.rerun is not None:
            self.rerun.send("begin", signals)

    def write(self, chunk: dict[str, Any]) -> None:
        if self.rerun is not None:
            self.rerun.send("chunk", chunk)

    def end(self, summary: dict[str, Any]) -> None:
        pass  # the plots need the step windows too: see finish()

    def finish(self, result: Any, title: str) -> None:
        """Hand over what the plots need; both processes finish while the caller writes its own files.

        A run that stopped early (a node lost, a stall) does not wait for processes still starting (their
        imports take minutes in the VM): they are stopped, and the run has no recording and no plots
        (`bench replay` of its bus.log makes them). When they are up, it gets them as any run."""
        if result.summary.get("stopped") and self.live != "serve":
            if not all(p.ready_now() for p in self.procs):
                self.abort()
                Path(self.spec["folder"], "run.rrd").unlink(missing_ok=True)
                self.skipped = "the run stopped early and the viewer processes were still starting"
                print(
                    f"bench run: no run.rrd and no plots: {self.skipped} (bench replay of its bus.log makes them)",
                    file=sys.stderr,
                    flush=True,
                )
                return
        if self.rerun is not None:
            self.rerun.send("finish", {"summary": result.summary})
        if self.plots is not None:
            plots = {"summary": result.summary, "windows": result.step_windows, "envelopes": result.envelopes}
            self.plots.send("finish", {**plots, "title": title})
        if not self.spec["keep"]:
            for proc in self.procs:
                proc.close_input()

    def finish_wait(self) -> list[str]:
        """The files written (run.rrd and the PNGs), once both processes are done with them."""
        if self.skipped:
            return []
        try:
            files: list[str] = []
            for proc in self.procs:
                proc.first()  # ready
                reply = proc.recv()
                files += list(reply.get("files", []))
                self.live_stats = reply.get("live") or self.live_stats
        except BaseException:
            self.abort()  # a process that failed its run (or a kept one in the middle of it) serves no other
            raise
        if self.spec["keep"]:
            for proc in self.procs:
                give_back(proc)
        return files

    def serve(self, seconds: float | None) -> None:
        """With a live viewer: the rerun process keeps serving until `seconds`, Ctrl-C or SIGTERM (to the
        terminal's process group, or to the bench alone: then the bench stops it); wait for it."""
        from bench.stop import deferred

        if self.spec["keep"] or self.rerun is None:
            return  # no viewer; the processes went back for the next run (finish_wait)
        sys.stdout.flush()  # the results are said before the wait (a pipe buffers them otherwise)
        try:
            self.rerun.proc.wait()
        except KeyboardInterrupt:
            with deferred():  # a second signal must not leave the server behind
                self.rerun.kill()
        with deferred():
            if self.plots is not None:
                self.plots.kill()

    def abort(self) -> None:
        from bench.stop import deferred

        with deferred():
            for proc in self.procs:
                proc.kill()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
