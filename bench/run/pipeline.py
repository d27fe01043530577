"""One run, data flowing one way, once: scenario -> SDO configuration -> PDO loop -> frames
(numpy chunks) -> decode once -> trace chunks -> sinks (files, viewers, the caller's memory).

    from bench.run import RunOptions, run_scenario
    result = run_scenario(load(Path("scenarios/you2019_step.toml")), RunOptions(bus="direct"), keep_trace=True)
    result.status, result.summary["steps"], result.trace["iq_A"]

`bench run`, the claims, sweeps, perf and the demo all call `run_scenario`; `bench replay`
feeds a log's frames through the same `Pipeline`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.emcy import emcy_codes
from bench.run.bus.liveness import LoopStopped
from bench.run.decode.decoder import Decoder
from bench.run.loop.reads import CONTROLLER_VALUES
from bench.run.loop.session import Session
from bench.run.options import RunOptions
from bench.run.sinks import Sink, TraceCollector
from bench.run.verdict.faults import StatusWatch
from bench.run.verdict.faults import build as fault_report
from bench.run.verdict.stats import STEP_SIGNALS, Envelope, StepTracker
from bench.run.verdict.summary import (
    SCHEMA_VERSION,
    bus_stats,
    divergence_bound_A,
    frame_bits,
    identified,
    plant_values,
    step_cost,
    verdict,
)
from bench.scenario import Scenario
from bench.signals import SignalInfo

FrameSink = Any  # has write(frames) and close()
# The drive's EMCYs of a safe state its current law caused (status law_fault): its command non-finite or
# beyond Vmax_V (0xFF06), a step longer than the period on a bare-metal target (0xFF07).
LAW_FAULT_EMCY = frozenset(emcy_codes("safe_law_output", "safe_overrun"))
Progress = Callable[[int, int], None]


def stopped_at(stopped: dict[str, Any], periods: int) -> dict[str, Any]:
    """The period an early stop happened at, from the record: the last period on the bus (the traces'
    last row). The master's own figure is only the last it heard of: over a bus, where a dead plant
    answers no SDO, that is the end of the previous lockstep segment (its hold announcement) or the
    last poll, periods before the loop really stopped. Without a period on the bus it stays as it was."""
    if periods <= 0:
        return stopped
    return {**stopped, "at_period": periods - 1}


@dataclass
class RunResult:
    scenario: str
    bus: str
    status: str  # ok | tripped | diverged | non_finite | frames_lost | node_lost | interference
    exit_code: int  # 0, or the status's code (bench/run/verdict/summary.py)
    expected: bool  # the status is what the scenario declared
    summary: dict[str, Any]
    signals: list[SignalInfo] = field(default_factory=list)
    trace: dict[str, np.ndarray] | None = None  # when asked for (keep_trace)
    envelopes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    step_windows: list[dict[str, np.ndarray]] = field(default_factory=list)

    # what the claims and tests read, by the names they had
    @property
    def identified(self) -> dict[str, Any]:
        return self.summary["identified"]

    @property
    def plant(self) -> dict[str, Any]:
        return self.summary["plant"]

    @property
    def controller(self) -> dict[str, Any]:
        return self.summary["controller"]

    @property
    def counters(self) -> dict[str, Any]:
        return self.summary["counters"]


class Pipeline:
    """Frames in (any chunk size, bus order), trace chunks out to the sinks, a summary at the end."""

    WINDOW = (4, 24)  # periods before and after a reference step kept for its plot
    MAX_WINDOWS = 64  # steps whose rows are kept (the plots show the first dozen)

    def __init__(
        self,
        plant_id: int | None,  # None: the EDS's NodeID
        drive_id: int | None,
        sinks: list[Sink] | None = None,
        frame_sinks: list[FrameSink] | None = None,
        expect: tuple[str, ...] = ("ok",),
    ) -> None:
        self.dec = Decoder(plant_id, drive_id)
        self.sinks = list(sinks or [])
        self.frame_sinks = list(frame_sinks or [])
        self.expect = expect
        self.steps = {sig: StepTracker(sig) for sig, _, _ in STEP_SIGNALS}
        self.envelopes: dict[str, Envelope] = {}
        self.bits = 0
        self.max_phase_A = 0.0
        self.bound_A: float | None = None
        self.first_trip_period: int | None = None
        self.first_beyond_bound_period: int | None = None
        self._begun = False
        self._tail: dict[str, np.ndarray] = {}  # the last rows, for step windows that start in a chunk
        self._windows: list[dict[str, Any]] = []
        self._open_windows: list[dict[str, Any]] = []
        self._seen: set[tuple[int, str]] = set()
        self.status = StatusWatch()  # the plant's status bits per period (held, missed, trip)

    @property
    def periods(self) -> int:
        return self.dec.stats.periods

    def feed(self, frames: np.ndarray) -> None:
        if len(frames) == 0:
            return
        for fs in self.frame_sinks:
            fs.write(frames)
        self.bits += frame_bits(frames)
        self._rows(self.dec.feed(frames))

    def _rows(self, chunk: dict[str, np.ndarray] | None) -> None:
        if chunk is None or len(chunk["period"]) == 0:
            return
        if not self._begun:
            self._begun = True
            for s in self.sinks:
                s.begin(self.dec.signals, self.dec)
            self.envelopes = {s.name: Envelope() for s in self.dec.signals if s.name in chunk}
            self.bound_A = divergence_bound_A(plant_values(self.dec))  # the plant as configured
        for sig, x, ref in STEP_SIGNALS:
            if x in chunk:
                self.steps[sig].add(chunk["period"], chunk[x], chunk[ref])
        for n, env in self.envelopes.items():
            env.add(chunk[n])
        phase = [
            np.abs(np.nan_to_num(chunk[c], nan=0.0, posinf=0.0, neginf=0.0)) for c in ("i_a_A", "i_b_A") if c in chunk
        ]
        if phase:
            a = np.maximum.reduce(phase)  # the larger phase current of each period
            self.max_phase_A = max(self.max_phase_A, float(a.max()))
            if self.bound_A is not None and self.first_beyond_bound_period is None and a.max() > self.bound_A:
                self.first_beyond_bound_period = int(chunk["period"][int(np.argmax(a > self.bound_A))])
        if "status" in chunk:
            self.status.add(chunk["period"], chunk["status"])
        if self.first_trip_period is None and "status" in chunk:
            st = chunk["status"]
            hit = np.nonzero(np.isfinite(st) & (np.nan_to_num(st).astype(np.int64) & 1 == 1))[0]
            if len(hit):
                self.first_trip_period = int(chunk["period"][hit[0]])
        self._step_windows(chunk)
        for s in self.sinks:
            s.write(chunk)

    def _step_windows(self, chunk: dict[str, np.ndarray]) -> None:
        """Keep the rows around each reference step (a few dozen per step, the first MAX_WINDOWS steps)
        for the step plots."""
        before, after = self.WINDOW
        names = [n for n in ("period", "iq_A", "iq_ref_A", "id_A", "id_ref_A", "vd_V", "vq_V") if n in chunk]
        joined = {n: np.concatenate([self._tail.get(n, chunk[n][:0]), chunk[n]]) for n in names}
        p = joined["period"]
        for w in self._open_windows:  # windows still filling
            m = (p >= w["lo"]) & (p < w["hi"]) & (p > w["have"])
            if m.any():
                for n in names:
                    w["rows"][n] = np.concatenate([w["rows"][n], joined[n][m]])
                w["have"] = int(p[m][-1])
        self._open_windows = [w for w in self._open_windows if w["have"] < w["hi"] - 1]
        for ref in ("iq_ref_A", "id_ref_A"):
            if ref not in joined or len(joined[ref]) < 2 or len(self._windows) >= self.MAX_WINDOWS:
                continue
            r = joined[ref]
            for j in np.nonzero(np.abs(np.diff(r)) > 1e-6)[0] + 1:
                at = int(p[j])
                if (at, ref) in self._seen or len(self._windows) >= self.MAX_WINDOWS:
                    continue
                self._seen.add((at, ref))
                lo, hi = at - before, at + after
                m = (p >= lo) & (p < hi)
                w = {
                    "at": at,
                    "ref": ref,
                    "lo": lo,
                    "hi": hi,
                    "have": int(p[m][-1]),
                    "rows": {n: joined[n][m].copy() for n in names},
                }
                self._windows.append(w)
                self._open_windows.append(w)
        self._tail = {n: joined[n][-before:] for n in names}

    def finish(
        self,
        scenario: str,
        bus: str,
        wall: dict[str, float] | None = None,
        stopped: dict[str, Any] | None = None,
        links: dict[str, dict[str, Any]] | None = None,
        faults: tuple[list[Any], list[tuple[Any, ...]], int] | None = None,
    ) -> RunResult:
        """`stopped`: the run ended before its last period (LoopStopped.to_dict(): a node lost, a stall);
        `links`: each SocketCAN interface's kernel report before and after the run (Session.links);
        `faults`: the scenario's faults, the injector's log and how many actions it could not log."""
        self._rows(self.dec.finish())
        dec = self.dec
        if stopped:
            stopped = stopped_at(stopped, dec.stats.periods)
        steps = [m.to_dict() for sig, _, _ in STEP_SIGNALS for m in self.steps[sig].finish()]
        tuning = dec.sdo.changes("Online tuning.enable")
        for s in steps:
            on = [v for p, v in tuning if p <= s["at_period"]]
            s["tuning_on"] = bool(on and on[-1])
        steps.sort(key=lambda s: (s["signal"] != "iq", s["at_period"]))
        plant = plant_values(dec)
        bound = self.bound_A
        bstats = bus_stats(dec, self.bits)
        trip_active = dec.sdo.plant.get("Run control", "trip_active")
        # A loop that never settles and still swings over half its step at the end of the window
        # oscillates (an unstable loop held by the voltage limit): diverged, though bounded.
        oscillating = [
            s["at_period"]
            for s in steps
            if s["periods_to_settle"] is None and (s["tail_peak_to_peak_A"] or 0.0) > 0.5 * abs(s["to_A"] - s["from_A"])
        ]
        # The periods the master ran (its run_periods writes, in the log): a log with fewer (cut short, a
        # recorder that lost the end) or more is not the run, unless the run stopped early.
        planned = sum(int(v) for _, v in dec.sdo.changes("Run control.run_periods", node="plant") if 0 < v < 0xFFFFFFFF)
        bstats["planned_periods"] = planned or None
        short = bool(planned) and dec.stats.periods != planned and not stopped
        # The drive refused its law (a non-finite or beyond-Vmax_V command; a step longer than the period on a
        # bare-metal target) and entered its safe state: its EMCY, the first one's period
        law_faults = [e["period"] for e in dec.emcy if e["node"] == "drive" and int(e["code"], 16) in LAW_FAULT_EMCY]
        flags = {
            "law_fault": bool(law_faults),
            "non_finite": bool(bstats["non_finite_values"]),
            "diverged": (bound is not None and self.max_phase_A > bound) or bool(oscillating),
            "tripped": self.first_trip_period is not None or bool(trip_active),
            "frames_lost": bstats["lost_frames"] > 0 or short or bool(stopped and stopped["status"] == "frames_lost"),
            "node_lost": bool(stopped and stopped["status"] == "node_lost"),
            "interference": bstats["interference"]["frames"] > 0,
        }
        first = {
            "law_fault": min(law_faults) if law_faults else None,
            "non_finite": dec.stats.first_non_finite_period,
            "tripped": self.first_trip_period,
            "diverged": self.first_beyond_bound_period
            if self.first_beyond_bound_period is not None
            else (oscillating[0] if oscillating else None),
            "interference": bstats["interference"]["first_period"],
            "frames_lost": dec.stats.first_lost_period,
        }
        if stopped:
            at = stopped.get("at_period")
            first[stopped["status"]] = at if at is not None else dec.stats.periods
        status, code, expected = verdict(flags, self.expect, first)
        timing = dict(wall or {})
        if timing.get("run_wall_s"):
            timing["periods_per_s"] = dec.stats.periods / timing["run_wall_s"]
        ctl = dec.sdo.drive
        summary: dict[str, Any] = {
            "schema_version": SCHEMA_VERSION,
            "scenario": scenario,
            "bus": bus,
            "status": status,
            "status_expected": expected,
            "expect": list(self.expect),
            "status_flags": flags,
            "stopped": stopped,
            "emcy": dec.emcy[:100],
            "first_trip_period": self.first_trip_period,
            "first_non_finite_period": dec.stats.first_non_finite_period,
            "oscillating_steps": oscillating,
            "max_phase_current_A": self.max_phase_A,
            "divergence_bound_A": bound,
            "periods": dec.stats.periods,
            "Ts_s": dec.ts_s,
            "steps": steps,
            "identified": identified(dec),
            "step_cost": step_cost(dec),
            "plant": plant,
            "controller": {n: ctl.get("Controller", n) for n in CONTROLLER_VALUES},
            "counters": {
                "plant_missed_commands": dec.sdo.plant.get("Run control", "missed_commands"),
                "plant_late_commands": dec.sdo.plant.get("Run control", "late_commands"),
                "plant_period_index": dec.sdo.plant.get("Run control", "period_index"),
                "drive_current_steps": ctl.get("Drive status", "current_steps"),
                "drive_lost_measurements": ctl.get("Drive status", "lost_measurements"),
                "drive_late_measurements": ctl.get("Drive status", "late_measurements"),
            },
            "settings": [
                {"period": w.period, "node": w.node, "name": w.name, "value": w.value}
                for w in dec.sdo.writes
                if w.period > 0
            ],
            "bus_stats": bstats,
            "timing": timing,
            # each SocketCAN interface (kind, state, bit rate, error counters) before and after the run
            "can_links": links or {},
        }
        if faults is not None:
            summary["faults"] = fault_report(faults[0], faults[1], faults[2], dec.emcy, self.status)
        for s in self.sinks:
            s.end(summary)
        windows = [{**w["rows"], "at_period": np.int64(w["at"])} for w in sorted(self._windows, key=lambda w: w["at"])]
        return RunResult(
            scenario,
            bus,
            status,
            code,
            expected,
            summary,
            list(dec.signals),
            envelopes={n: e.arrays() for n, e in self.envelopes.items()},
            step_windows=windows,
        )


DIRECT_IS_LOCKSTEP = (
    "scenario.timing = realtime needs a CAN bus (--bus vcan0, can0, ...): the direct bus calls both nodes in "
    "one process, period by period, so it runs lockstep only"
)


def run_scenario(
    sc: Scenario,
    opts: RunOptions | None = None,
    sinks: list[Sink] | None = None,
    frame_sinks: list[FrameSink] | None = None,
    keep_trace: bool = False,
    progress: Progress | None = None,
) -> RunResult:
    """Run a scenario on a bus ('direct' or a SocketCAN/python-can channel) and return its result.

    `sinks` take the trace chunks (files, viewers); `frame_sinks` the raw frames (a log writer);
    `keep_trace` also returns the whole trace in memory (O(periods): for short runs and tests).
    Over SocketCAN the frames come from candump's log in `opts.out` (which must be set)."""
    from bench.run.record.sources import CandumpSource, DirectSource, ListenerSource

    opts = opts or RunOptions()
    if opts.bus == "direct" and sc.timing == "realtime":
        raise ValueError(DIRECT_IS_LOCKSTEP)
    sinks = list(sinks or [])
    collector = TraceCollector() if keep_trace else None
    if collector is not None:
        sinks.append(collector)
    pipe = Pipeline(opts.plant_id, opts.drive_id, sinks, frame_sinks, sc.expect)
    t0 = time.monotonic()
    sess = Session(sc, opts)
    source: Any = None
    run_wall = 0.0
    stopped: dict[str, Any] | None = None
    try:
        if opts.out is not None:
            opts.out.mkdir(parents=True, exist_ok=True)
        if opts.bus != "direct" and opts.interface == "socketcan" and opts.record:
            if opts.out is None:
                raise ValueError("a run over SocketCAN needs opts.out for candump's log")
            sess.prepare_links()
            source = CandumpSource(opts.bus, opts.out / "candump.log")
        sess.open()
        if sess.hil is not None and sess.direct is not None and opts.record:
            source = DirectSource(sess.hil, opts.chunk_periods)
            sess.direct.on_chunk = source.collect
            sess.direct.on_stop = source.release
        elif source is None and opts.record:
            source = ListenerSource()
            sess.net.notifier.add_listener(source)

        def tick() -> None:
            if source is not None:
                pipe.feed(source.drain())

        sess.reset_nodes()
        sess.configure()
        t_run = time.monotonic()
        try:
            run_wall = sess.run(progress, tick)
            sess.statuses()
        except LoopStopped as exc:  # a verdict, not a failure: the frames so far are decoded and kept
            stopped = exc.to_dict()
            run_wall = time.monotonic() - t_run
            if exc.status == "node_lost":
                sess.linger()  # the other node's reaction (its heartbeat consumer) goes into the record
    finally:
        sess.close()
        if source is not None:
            source.stop()
    if source is not None:
        pipe.feed(source.drain(final=True))
        if hasattr(source, "cleanup"):
            source.cleanup()
    injected = (sc.faults, *sess.fault_log()) if sc.faults else None
    res = pipe.finish(
        sc.name, opts.bus, {"wall_s": time.monotonic() - t0, "run_wall_s": run_wall}, stopped, sess.links, injected
    )
    if collector is not None:
        res.trace = collector.trace
    return res


def capture_to_log(sc: Scenario, opts: RunOptions) -> tuple[float, dict[str, Any] | None, dict[str, dict[str, Any]]]:
    """The bus half of a run only: nodes, master and candump's log in `opts.out`; no decoding
    (inside the VM, where Python is slow, the host decodes the log). Returns the loop's wall time,
    when the loop ended early why (LoopStopped.to_dict()), and the interfaces' state (Session.links)."""
    from bench.run.record.sources import CandumpSource

    assert opts.out is not None
    sess = Session(sc, opts)
    sess.prepare_links()
    source = CandumpSource(opts.bus, opts.out / "candump.log", follow=False)
    stopped: dict[str, Any] | None = None
    try:
        sess.open()
        sess.reset_nodes()
        sess.configure()
        t_run = time.monotonic()
        try:
            run_wall = sess.run()
            sess.statuses()
        except LoopStopped as exc:
            stopped = exc.to_dict()
            run_wall = time.monotonic() - t_run
            if exc.status == "node_lost":
                sess.linger()
    finally:
        sess.close()
        source.stop()
        source.cleanup()
    return run_wall, stopped, sess.links


def replay_log(
    path: Path,
    plant_id: int | None = None,
    drive_id: int | None = None,
    sinks: list[Sink] | None = None,
    keep_trace: bool = False,
    expect: tuple[str, ...] = ("ok",),
    progress: Callable[[int], None] | None = None,
) -> RunResult:
    """A CAN log (candump .log, .asc, .blf, ...) through the same pipeline as a run: the same trace and
    summary, since the log carries the layout, the settings and the statuses (bench/run/decode/sdo_log.py)."""
    from bench.run.record.canlog import read_frames
    from bench.run.record.sources import sorted_chunks

    sinks = list(sinks or [])
    collector = TraceCollector() if keep_trace else None
    if collector is not None:
        sinks.append(collector)
    pipe = Pipeline(plant_id, drive_id, sinks, None, expect)
    t0 = time.monotonic()
    frames = read_frames(path)
    for chunk in sorted_chunks(frames):
        pipe.feed(chunk)
        if progress:
            progress(len(chunk))
    res = pipe.finish(path.name, f"log {path.name}", {"wall_s": time.monotonic() - t0})
    res.summary["log"] = {"path": str(path), **frames.report(), "sdo_transfers": pipe.dec.sdo.transfers}
    if collector is not None:
        res.trace = collector.trace
    return res
