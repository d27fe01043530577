"""What `bench run` (and `bench replay`) write and show, built once from the run's chunks and
result: traces.npy, bus.log (+ .asc/.blf on request), summary.json, PNG plots, run.rrd and the
live viewer; progress on every phase that takes time (bench/run/progress.py); the result printed for a person."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bench.run.bus.buses import bus_of_args
from bench.run.progress import Progress, ProgressSink
from bench.run.sinks import TRACES_FILE, TraceFileSink
from bench.scenario import Scenario


class Outputs:
    def __init__(self, folder: Path, sc: Scenario, args: argparse.Namespace) -> None:
        self.folder = folder
        self.sc = sc
        self.args = args
        self.log_formats = [f for f in (getattr(args, "log_format", None) or []) if f != "log"]
        self.traces = TraceFileSink(folder / TRACES_FILE)
        self.view = self._view_worker()
        self._progress_sink = ProgressSink()
        self.sinks: list[Any] = [self.traces, self.view, self._progress_sink]
        self.frame_sinks: list[Any] = []
        self.log_path = folder / "bus.log"
        self.interrupted = False  # a Ctrl-C while the results were written: no serving after them
        if bus_of_args(args).log_from_frames:  # over a kernel's CAN, candump's own log is the log
            from bench.run.record.canlog import CandumpWriter

            self.frame_sinks.append(CandumpWriter(self.log_path, args.bus))

    def _view_worker(self) -> Any:
        from bench.view.deferred import KEEP_PERIODS, DeferredView
        from bench.view.worker import ViewWorker
        from bench.view.worker_procs import live_of

        live = live_of(self.args.serve, self.args.no_viewer)
        kwargs: dict[str, Any] = {
            "live_decimate": self.args.live_decimate,
            "rrd": not getattr(self.args, "no_rrd", False),
            "plots": not getattr(self.args, "no_plots", False),
        }
        later = getattr(self.args, "view_later", None)  # the plugin's in-process runs (bench/cli_in_process.py)
        if later is not None and live == "none" and self.sc.periods <= KEEP_PERIODS:
            view = DeferredView(self.sc.name, self.folder, **kwargs)
            later.append(view)
            return view
        worker = ViewWorker(
            self.sc.name,
            self.folder,
            live=live,
            web_port=getattr(self.args, "web_port", 9090),
            grpc_port=getattr(self.args, "grpc_port", 9876),
            serve_for=getattr(self.args, "serve_for", None),
            bind=getattr(self.args, "serve_bind", "127.0.0.1"),
            **kwargs,
        )
        if live == "serve":  # fail before the run if the ports are taken; the address, once, now
            worker.wait_ready()
        return worker

    @contextmanager
    def progress(self, total: int, desc: str) -> Iterator[Progress]:
        bar = Progress(total, desc)
        self._progress_sink.bar = bar
        try:
            yield bar
        finally:
            self._progress_sink.bar = None
            bar.close()

    def finish(self, result: Any) -> None:
        """Everything after the last frame: the viewer process draws the plots and closes the recording
        while this one closes the log (or renames candump's), exports and writes the summary."""
        self.view.finish(result, self.sc.name)
        for fs in self.frame_sinks:
            fs.close()
        cand = self.folder / "candump.log"
        if cand.exists():
            cand.rename(self.log_path)
        for fmt in self.log_formats:
            from bench.run.record.canlog import export

            dst = self.log_path.with_suffix("." + fmt)
            print(f"  writing {dst.name} with python-can's writer ...", file=sys.stderr, flush=True)
            export(self.log_path, dst)
        if result.summary["periods"] > 200_000:  # long runs: say what the wait is for
            print("  writing run.rrd and the plots ...", file=sys.stderr, flush=True)
        try:
            shown = self.view.finish_wait()
        except RuntimeError as exc:  # the run and its data are fine: a view that failed is a warning
            print(f"bench run: warning: the recording or the plots were not written: {exc}", file=sys.stderr)
            shown = []
        live = getattr(self.view, "live_stats", None)
        if live:  # what the live viewer got: a viewer that fell behind lost rows of its view, never of the files
            result.summary["live_view"] = live
            if live["periods_dropped"]:
                print(
                    f"bench run: the live viewer fell behind: {live['periods_dropped']} of {live['periods']} periods "
                    "were not sent to it (run.rrd has every one)",
                    file=sys.stderr,
                )
        self.write_summary(result, [f for f in shown if f.endswith(".svg")])

    def write_summary(self, result: Any, plots: list[str] | None = None, complete: bool = True) -> None:
        """summary.json; `complete` False: the writing was cut, only the files the run's data is in are listed."""
        cand = self.folder / "candump.log"
        if cand.exists() and not self.log_path.exists():
            cand.rename(self.log_path)
        summary = result.summary
        summary["files"] = {
            "log": self.log_path.name,
            "traces": TRACES_FILE,
            "exports": [f"bus.{f}" for f in self.log_formats] if complete else [],
            "recording": "run.rrd" if complete and (self.folder / "run.rrd").exists() else None,
            "plots": plots or [],
        }
        (self.folder / "summary.json").write_text(json.dumps(summary, indent=2, default=json_default))

    def abort(self) -> None:
        self.view.abort()
        for fs in self.frame_sinks:
            try:
                fs.close()
            except Exception:  # noqa: BLE001 - already failing
                pass
        if self.traces is not None:
            try:
                self.traces.end({})
            except Exception:  # noqa: BLE001
                pass

    def serve(self, args: argparse.Namespace) -> None:
        """With --serve the viewer process keeps serving after the run: wait for it (Ctrl-C ends it)."""
        self.view.serve(args.serve_for)


def json_default(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serializable: {type(o)}")
