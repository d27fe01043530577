"""What `bench run` (and `bench replay`) write and show, built once from the run's chunks and
result: traces.npy, bus.log (+ .asc/.blf on request), summary.json, PNG plots, run.rrd and the
live viewer; progress on every phase that takes time; the result printed for a person."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..scenario import Scenario
from .sinks import TRACES_FILE, TraceFileSink


class Progress:
    """A tqdm bar on a terminal; otherwise a line every few seconds (CI logs), none for short phases."""

    def __init__(self, total: int, desc: str, every_s: float = 5.0, unit: str = "periods") -> None:
        self.total, self.desc, self.n, self.unit = total, desc, 0, unit
        self._bar: Any = None
        self._t0 = self._last = time.monotonic()
        self._every = every_s
        if sys.stderr.isatty():
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit=unit, desc=desc, unit_scale=True, leave=False)

    def update(self, k: int) -> None:
        if k <= 0:
            return
        if self.n == 0:
            self._t0 = time.monotonic()  # the rate counts from the first period (a VM boots first)
        self.n += k
        if self._bar is not None:
            self._bar.update(k)
            return
        now = time.monotonic()
        if now - self._last >= self._every:
            self._last = now
            rate = self.n / max(now - self._t0, 1e-9)
            eta = (self.total - self.n) / rate if rate > 0 else float("nan")
            print(
                f"  {self.desc}: {self.n}/{self.total} {self.unit} ({rate:,.0f}/s, ~{max(eta, 0):.0f} s left)",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


class Outputs:
    def __init__(self, folder: Path, sc: Scenario, args: argparse.Namespace) -> None:
        self.folder = folder
        self.sc = sc
        self.args = args
        self.log_formats = [f for f in (getattr(args, "log_format", None) or []) if f != "log"]
        self.traces = TraceFileSink(folder / TRACES_FILE)
        self.view = self._view_worker()
        self.sinks: list[Any] = [self.traces, self.view]
        self.frame_sinks: list[Any] = []
        self.log_path = folder / "bus.log"
        self.interrupted = False  # a Ctrl-C while the results were written: no serving after them
        if args.bus == "direct":  # over a bus, candump's own log is the log
            from .canlog import CandumpWriter

            self.frame_sinks.append(CandumpWriter(self.log_path, "direct", int(time.time() * 1e6)))

    def _view_worker(self) -> Any:
        from ..view.worker import ViewWorker

        live = "none"
        if self.args.serve:
            live = "serve"
        elif not self.args.no_viewer and (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            live = "spawn"
        worker = ViewWorker(
            self.sc.name,
            self.folder,
            live=live,
            live_decimate=self.args.live_decimate,
            web_port=getattr(self.args, "web_port", 9090),
            grpc_port=getattr(self.args, "grpc_port", 9876),
            serve_for=getattr(self.args, "serve_for", None),
            bind=getattr(self.args, "serve_bind", "127.0.0.1"),
        )
        if live == "serve":  # fail before the run if the ports are taken; the address, once, now
            worker.wait_ready()
        return worker

    @contextmanager
    def progress(self, total: int, desc: str) -> Iterator[Progress]:
        bar = Progress(total, desc)
        try:
            yield bar
        finally:
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
            from .canlog import export

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
        (self.folder / "summary.json").write_text(json.dumps(summary, indent=2, default=_json_default))

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


def _json_default(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serializable: {type(o)}")


def _ids(by_id: dict[str, int]) -> str:
    return ", ".join(f"{k} x{v}" for k, v in list(by_id.items())[:6]) or "none"


def print_result(out: Path, result: Any) -> None:
    from .summary import format_identified, format_table

    s = result.summary
    print(format_table(s))
    print(format_identified(s["identified"]))
    bs = s["bus_stats"]
    nf = bs["non_finite_values"]
    print(
        f"bus: {bs['frames']} frames, {bs['lost_frames']} lost (SYNC gaps {bs['sync_counter_gaps']}, "
        f"missing measurements {bs['missing_measurements']}, missing commands {bs['missing_commands']}), "
        f"plant missed {bs['plant_missed_commands']}, late {bs['plant_late_commands']}"
        + (f"; non-finite values: {', '.join(f'{k} x{v}' for k, v in nf.items())}" if nf else "")
    )
    ff, itf = bs.get("foreign_frames", {}), bs.get("interference", {})
    if ff.get("frames") or itf.get("frames") or bs.get("after_loop_frames"):
        print(
            f"bus: foreign frames {ff.get('frames', 0)} ({_ids(ff.get('by_cob_id', {}))}); interference "
            f"{itf.get('frames', 0)} ({_ids(itf.get('by_cob_id', {}))}); after the loop "
            f"{bs.get('after_loop_frames', 0)}"
        )
    emcy = s.get("emcy") or []
    if emcy:
        shown = ", ".join(f"{e['node']} {e['code']} at period {e['period']}" for e in emcy[:6])
        print(f"EMCY: {len(emcy)}{'+' if len(emcy) >= 100 else ''}: {shown}{' ...' if len(emcy) > 6 else ''}")
    if s.get("faults"):
        from ..faults.report import format_faults

        print(format_faults(s["faults"]))
    cost = s.get("step_cost")
    if cost:
        print(
            f"drive step cost ({cost['controller']}, {cost['steps_measured']} steps): mean "
            f"{cost['step_cycles_mean']:.0f}, max {cost['step_cycles_max']:.0f} ticks of its "
            f"{cost['cycle_clock_Hz']:,} Hz counter ({cost['step_mean_s'] * 1e6:.2f} / "
            f"{cost['step_max_s'] * 1e6:.2f} us; on the QEMU image, -icount shift=0: "
            f"{cost['step_mean_s'] * 1e9:.0f} / {cost['step_max_s'] * 1e9:.0f} instructions)"
        )
    t = s.get("timing", {})
    if t.get("periods_per_s"):
        print(
            f"run: {s['periods']} periods in {t['run_wall_s']:.3f} s ({t['periods_per_s']:,.0f} periods/s, "
            f"decoding included); with configuration {t['wall_s']:.2f} s"
        )
    status = s["status"]
    osc = s.get("oscillating_steps") or []
    why = {
        "tripped": f"the plant's over-current trip latched at period {s.get('first_trip_period')} "
        f"(I_trip_A = {s['plant'].get('I_trip_A')})",
        "diverged": (
            f"the step at period {osc[0]} never settles: its error still swings over half the step at "
            "the end of its window (an unstable loop held by the voltage limit)"
            if osc
            else f"a phase current of {s['max_phase_current_A']:.3g} A, beyond "
            f"{s['divergence_bound_A']:.3g} A that the inverter can drive through the winding"
        ),
        "non_finite": f"non-finite values arrived in PDOs: {', '.join(nf)}",
        "frames_lost": (s["stopped"]["message"] if s.get("stopped") else f"{bs['lost_frames']} frames lost"),
        "node_lost": (s.get("stopped") or {}).get("message", ""),
        "interference": f"{bs.get('interference', {}).get('frames')} frames on the loop's own identifiers that "
        f"the loop did not send ({_ids(bs.get('interference', {}).get('by_cob_id', {}))}), the "
        f"first in period {bs.get('interference', {}).get('first_period')}",
    }.get(status, "")
    if status == "ok":
        print("status: ok")
    elif result.expected:
        print(f"status: {status} (expected by the scenario): {why}")
    else:
        print(f"status: {status.upper()}: {why} (exit {result.exit_code})")
    if status == "ok" and not result.expected:
        print(f"status: the scenario expected {', '.join(s['expect'])} (exit {result.exit_code})")
    views = ", run.rrd, *.svg" if (out / "run.rrd").exists() else ""
    print(f"results in {out}/: summary.json, {TRACES_FILE}, bus.log{views}")
