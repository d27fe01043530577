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

from bench.run.sinks import TRACES_FILE, TraceFileSink
from bench.scenario import Scenario


class Progress:
    """A tqdm bar on a terminal; otherwise a line every few seconds (CI logs) and a final line with what
    was done and the rate. The rate counts from the first update and the amount it brought (a VM boots
    first; the first update may carry many periods at once): none is shown before time has passed."""

    MIN_RATE_SPAN_S = 0.5  # a rate over less time than this is not shown

    def __init__(self, total: int, desc: str, every_s: float = 5.0, unit: str = "periods") -> None:
        self.total, self.desc, self.n, self.unit = total, desc, 0, unit
        self._bar: Any = None
        self._start = self._last = time.monotonic()
        self._t0: float | None = None  # first update: its time and the count it brought
        self._n0 = 0
        self._every = every_s
        self._closed = False
        if sys.stderr.isatty():
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit=unit, desc=desc, unit_scale=True, leave=False)

    def rate(self, now: float) -> float | None:
        """Units a second since the first update; None while too little time has passed to tell."""
        if self._t0 is None or now - self._t0 < self.MIN_RATE_SPAN_S or self.n <= self._n0:
            return None
        return (self.n - self._n0) / (now - self._t0)

    def update(self, k: int) -> None:
        if k <= 0:
            return
        self.n += k
        now = time.monotonic()
        if self._t0 is None:
            self._t0, self._n0 = now, self.n
        if self._bar is not None:
            self._bar.update(k)
            return
        if now - self._last >= self._every:
            self._last = now
            rate = self.rate(now)
            pace = f" ({rate:,.0f}/s, ~{max(self.total - self.n, 0) / rate:.0f} s left)" if rate else ""
            print(f"  {self.desc}: {self.n}/{self.total} {self.unit}{pace}", file=sys.stderr, flush=True)

    def close(self) -> None:
        """The bar goes; without a terminal, a final line: done, time, rate (when progress was seen)."""
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
            return
        if self.n == 0:
            return
        now = time.monotonic()
        rate = self.rate(now)
        pace = f", {rate:,.0f} {self.unit}/s" if rate else ""
        print(
            f"  {self.desc}: {self.n}/{self.total} {self.unit} done in {now - self._start:.1f} s{pace}",
            file=sys.stderr,
            flush=True,
        )


class _ProgressSink:
    """A trace sink that moves the active progress bar with the periods decoded: every kind of run (direct,
    a bus, the VM) feeds its trace chunks through the sinks as they come, so the bar moves within a
    segment (the session's own progress calls come at its events only)."""

    def __init__(self) -> None:
        self.bar: Progress | None = None

    def begin(self, signals: Any, ctx: Any) -> None:
        pass

    def write(self, chunk: dict[str, Any]) -> None:
        bar, periods = self.bar, chunk.get("period")
        if bar is not None and periods is not None and len(periods):
            bar.update(int(periods[-1]) + 1 - bar.n)

    def end(self, summary: dict[str, Any]) -> None:
        pass


class Outputs:
    def __init__(self, folder: Path, sc: Scenario, args: argparse.Namespace) -> None:
        self.folder = folder
        self.sc = sc
        self.args = args
        self.log_formats = [f for f in (getattr(args, "log_format", None) or []) if f != "log"]
        self.traces = TraceFileSink(folder / TRACES_FILE)
        self.view = self._view_worker()
        self._progress_sink = _ProgressSink()
        self.sinks: list[Any] = [self.traces, self.view, self._progress_sink]
        self.frame_sinks: list[Any] = []
        self.log_path = folder / "bus.log"
        self.interrupted = False  # a Ctrl-C while the results were written: no serving after them
        if args.bus == "direct":  # over a bus, candump's own log is the log
            from bench.run.record.canlog import CandumpWriter

            self.frame_sinks.append(CandumpWriter(self.log_path, "direct"))

    def _view_worker(self) -> Any:
        from bench.view.worker import ViewWorker

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
    from bench.run.verdict.summary import format_identified, format_table

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
        from bench.run.verdict.faults import format_faults

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
    if s.get("realtime"):
        print(_realtime_line(s["realtime"]))
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
        "frames_lost": (s["stopped"]["message"] if s.get("stopped") else _frames_lost(s)),
        "node_lost": (s.get("stopped") or {}).get("message", ""),
        "interference": f"{bs.get('interference', {}).get('frames')} frames on the loop's own identifiers that "
        f"the loop did not send ({_ids(bs.get('interference', {}).get('by_cob_id', {}))}), the "
        f"first in period {bs.get('interference', {}).get('first_period')}",
        "law_fault": _law_fault(s),
        "realtime_overrun": _realtime_overrun(s),
        "plant_fault": _plant_fault(s),
    }.get(status, "")
    at, also = _first_events(s)
    if status == "ok":
        print("status: ok")
    elif result.expected:
        print(f"status: {status}{at} (expected by the scenario): {why}{also}")
    else:
        print(f"status: {status.upper()}{at}: {why} (exit {result.exit_code}){also}")
    if status == "ok" and not result.expected:
        print(f"status: the scenario expected {', '.join(s['expect'])} (exit {result.exit_code})")
    print(f"results in {out}/: {', '.join(_files_written(s, out))}")


def _files_written(s: dict[str, Any], out: Path) -> list[str]:
    """The files summary.json lists (what was written), summary.json first."""
    files = s.get("files")
    if not files:  # a run stopped early whose view helpers were still starting has no recording, no plots
        views = ["run.rrd", "*.svg"] if (out / "run.rrd").exists() else []
        return ["summary.json", TRACES_FILE, "bus.log", *views]
    names = [files.get("log"), files.get("traces"), *files.get("exports", []), files.get("recording")]
    plots = files.get("plots") or []
    shown = ["summary.json", *[n for n in names if n]]
    return shown + (plots if len(plots) <= 3 else [f"{len(plots)} plots (*.svg)"])


def _plant_fault(s: dict[str, Any]) -> str:
    from bench.emcy import emcy_names

    names = emcy_names()
    e = next(
        (e for e in s.get("emcy", []) if e["node"] == "plant" and names.get(int(e["code"], 16)) == "model_fault"), None
    )
    at = f" at period {e['period']}" if e else ""
    return (
        f"the plant's model failed{at} (its FMU's doStep returned an error, EMCY 0xFF20; the plant's log says which): "
        "the inverter was switched off and the model no longer stepped; the frames up to there are kept"
    )


def _law_fault(s: dict[str, Any]) -> str:
    from bench.emcy import emcy_names

    why = {
        "safe_law_output": "a non-finite command or one beyond Vmax_V",
        "safe_overrun": "a step longer than the period",
    }
    names = emcy_names()
    e = next((e for e in s.get("emcy", []) if e["node"] == "drive" and names.get(int(e["code"], 16)) in why), None)
    if e is None:
        return ""
    law = (s.get("identified") or {}).get("controller")
    return (
        f"the drive refused its current law {law} at period {e['period']}: {why[names[int(e['code'], 16)]]} "
        f"(EMCY {e['code']}); it commands 0 V in its safe state from then on"
    )


def _us(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def _realtime_line(rt: dict[str, Any]) -> str:
    """A real-time run's timing in one line: the plant's own figures, then the bus's (summary.json "realtime")."""
    p, bus = rt.get("plant") or {}, rt.get("bus")

    def plant(what: str) -> str:
        return f"p99 {_us(p.get(f'{what}_p99_us'))} max {_us(p.get(f'{what}_max_us'))} us"

    line = (
        f"real time at Ts = {_us(rt.get('period_us'))} us: plant SYNC lateness {plant('sync_lateness')}, "
        f"turnaround {plant('turnaround')}, overruns {p.get('overruns')}, SYNC overruns {p.get('sync_overruns')}"
    )
    floor = rt.get("floor")
    if floor:
        line += f" (the host's floor p99 {floor['p99_us']:g} us)"
    if not bus:
        return line + "; bus: no time stamps"
    lat, tr, iv = bus["sync_lateness_us"], bus["turnaround_us"], bus["sync_interval_us"]
    causes = _causes(rt)
    return (
        f"{line}; bus SYNC lateness p99 {_us(lat['p99'])} max {_us(lat['max'])} us, turnaround p99 {_us(tr['p99'])} "
        f"max {_us(tr['max'])} us, SYNC interval {_us(iv['min'])} .. {_us(iv['max'])} us"
        + (f"; overruns by cause: {causes}" if causes else "")
    )


def _realtime_overrun(s: dict[str, Any]) -> str:
    """'37 overruns in 1000 periods at Ts = 5.0 us: the command was not at the plant by its deadline (12 missed
    their SYNC); worst SYNC lateness 412.3 us at period 18' (the plant's figures, summary.json realtime.plant)."""
    rt = s.get("realtime") or {}
    p = rt.get("plant") or {}
    n, late = p.get("overruns") or 0, p.get("sync_overruns") or 0
    where = f"in {p.get('periods', s.get('periods'))} periods at Ts = {_us(rt.get('period_us'))} us"
    missed = p.get("missed_commands") or 0
    parts = [f"{n} overruns {where}: the command was not at the plant by its deadline ({missed} missed their SYNC)"]
    parts = parts if n else []
    if late:
        parts.append(f"{late} SYNCs more than one period late" + ("" if n else f" {where}"))
    parts.append(f"worst SYNC lateness {_us(p.get('sync_lateness_max_us'))} us at period {p.get('worst_period')}")
    causes = _causes(rt)
    if causes:
        parts.append(f"by cause: {causes}")
    floor = rt.get("floor")
    if floor:
        parts.append(f"the host's floor p99 {floor['p99_us']:g} p99.9 {floor['p99_9_us']:g} us")
    return "; ".join(parts)


def _causes(rt: dict[str, Any]) -> str:
    """'plant_late 3, drive_missing 12' (summary.json realtime.bus.overrun_causes, the non-zero ones)."""
    got = ((rt.get("bus") or {}).get("overrun_causes")) or {}
    return ", ".join(f"{k} {v}" for k, v in got.items() if v)


def _frames_lost(s: dict[str, Any]) -> str:
    """Why frames_lost without a stop: frames missing from periods, and/or fewer periods than the master ran."""
    bs, log = s["bus_stats"], s.get("log") or {}
    parts = [f"{bs['lost_frames']} frames lost"] if bs["lost_frames"] else []
    planned = bs.get("planned_periods")
    if planned and s["periods"] != planned:
        parts.append(f"{s['periods']} periods of the {planned} the master ran")
    if log.get("truncated_line"):
        parts.append(f"the log is truncated (it ends mid-line at line {log['truncated_line']})")
    return "; ".join(parts) or f"{bs['lost_frames']} frames lost"


def _first_events(s: dict[str, Any]) -> tuple[str, str]:
    """(" at period N" of the status's first event, "; later: ..." the other raised flags with theirs): the
    status names the event that came first (bench/run/verdict/summary.py verdict)."""
    first = s.get("status_first_period") or {}

    def at(flag: str) -> str:
        return "" if first.get(flag) is None else f" at period {first[flag]}"

    others = [f"{k}{at(k)}" for k in first if k != s["status"]]
    return at(s["status"]), (f"; also raised: {', '.join(others)}" if others else "")
