"""A run's recording and plots drawn later, or never: the pytest plugin's direct runs in the test's process
(`--hil-view=failed`, its default) keep what the viewer processes would have been sent, and draw run.rrd and the
plots only when the test fails (`draw`). A passing test's run costs no recording and no plots (~80 ms of a 200-period
run's ~100 ms: pygal's SVG, rerun's file); a failing one gets the same files as a run that drew them at once, since
the viewer processes get the same messages (bench/view/worker.py).

What is kept is the run's decoded chunks (references: the pipeline hands each chunk over once and never changes it),
the step windows and envelopes: a run longer than KEEP_PERIODS draws at once instead (its chunks would be large), and
so does a run that finds the process keeping KEEP_BYTES already (a test of many runs), from then on."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

KEEP_PERIODS = 200_000  # longer runs draw their view at once: their chunks are not kept in memory
KEEP_BYTES = 256 << 20  # what a process keeps of runs not drawn; beyond it a run draws as it goes, as without this
_HELD = [0]  # bytes kept now by this process's DeferredViews


class DeferredView:
    """A ViewWorker's place in Outputs (the same sink and finish face) that only keeps what it is given."""

    def __init__(self, name: str, folder: Path, **worker: Any) -> None:
        self.name = name
        self.folder = Path(folder)
        self.worker = worker  # ViewWorker's keyword arguments (rrd, plots, live_decimate, ...)
        self.signals: list[Any] | None = None
        self.chunks: list[dict[str, Any]] = []
        self.result: Any = None
        self.title = name
        self.held = 0  # bytes of the kept chunks (counted in _HELD)
        self.now: Any = None  # a ViewWorker drawing as the run goes, once the process keeps KEEP_BYTES

    # the sink's face (bench/run/sinks.py)
    def begin(self, signals: list[Any], ctx: Any = None) -> None:
        self.signals = signals

    def write(self, chunk: dict[str, Any]) -> None:
        if self.now is not None:
            self.now.write(chunk)
            return
        self.chunks.append(chunk)
        size = sum(getattr(v, "nbytes", 0) for v in chunk.values())
        self.held += size
        _HELD[0] += size
        if _HELD[0] > KEEP_BYTES:  # this process keeps enough: this run's view is drawn as it goes, as without us
            self.now = self._worker(self.folder)
            self.release()

    def end(self, summary: dict[str, Any]) -> None:
        pass

    # ViewWorker's face to Outputs
    def wait_ready(self) -> None:
        pass

    def finish(self, result: Any, title: str) -> None:
        if self.now is not None:
            self.now.finish(result, title)
            return
        self.result, self.title = result, title

    def finish_wait(self) -> list[str]:
        return self.now.finish_wait() if self.now is not None else []  # nothing drawn yet

    def serve(self, seconds: float | None) -> None:
        pass

    def abort(self) -> None:
        if self.now is not None:
            self.now.abort()
        self.release()

    def pending(self) -> bool:
        """Whether `draw` has something to draw: a run that reached its end (finish) and was not drawn."""
        return self.result is not None and self.signals is not None

    def draw(self, folder: Path | None = None) -> list[str]:
        """Write run.rrd and the plots now into `folder` (the run's folder as it ended: the one it was written in
        is renamed when the run is complete; default that one), through the viewer processes (reused:
        bench/view/worker_procs.py), and name them in summary.json's "files"; the files written. Drawn once: the
        kept chunks are let go."""
        if self.now is not None:  # drawn as it went (over the budget): its files are the run's already
            return []
        if not self.pending():
            return []
        folder = Path(folder) if folder is not None else self.folder
        worker = self._worker(folder)
        for proc in worker.procs:  # ready: a run that stopped early is drawn too (ViewWorker.finish skips it else)
            proc.first()
        worker.finish(self.result, self.title)
        if worker.skipped:
            raise RuntimeError(worker.skipped)
        files = worker.finish_wait()
        self.release()
        _name_in_summary(folder / "summary.json", files)
        return files

    def _worker(self, folder: Path) -> Any:
        """A ViewWorker given what was kept (the run's signals and chunks so far)."""
        from bench.view.worker import ViewWorker

        worker = ViewWorker(self.name, folder, **self.worker)
        worker.begin(self.signals or [])
        for chunk in self.chunks:
            worker.write(chunk)
        return worker

    def release(self) -> None:
        """Let the kept chunks go (drawn, or a passing test's run: never drawn)."""
        _HELD[0] -= self.held
        self.held = 0
        self.chunks, self.result = [], None


def _name_in_summary(path: Path, files: list[str]) -> None:
    """summary.json's "files": the recording and the plots drawn after the run."""
    try:
        summary = json.loads(path.read_text())
    except (OSError, ValueError):
        return  # a run folder the test moved or removed: the files are there, unnamed
    named = summary.setdefault("files", {})
    named["recording"] = "run.rrd" if "run.rrd" in files else named.get("recording")
    named["plots"] = [f for f in files if f.endswith(".svg")] or named.get("plots", [])
    path.write_text(json.dumps(summary, indent=2))
