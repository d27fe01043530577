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

from bench.run.bus.liveness import LoopStopped
from bench.run.decode.decoder import Decoder
from bench.run.loop.session import Session
from bench.run.options import RunOptions
from bench.run.sinks import Sink, StepWindows, TraceCollector
from bench.run.verdict.faults import build as fault_report
from bench.run.verdict.stats import STEP_SIGNALS, Envelope, StepTracker
from bench.run.verdict.summary import build_summary, bus_stats, frame_bits
from bench.run.verdict.watch import LoopWatch
from bench.scenario import Scenario
from bench.signals import SignalInfo

FrameSink = Any  # has write(frames) and close()
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

    # shortcuts into the summary
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

    def __init__(
        self,
        plant_id: int | None,  # None: the EDS's NodeID
        drive_id: int | None,
        sinks: list[Sink] | None = None,
        frame_sinks: list[FrameSink] | None = None,
        expect: tuple[str, ...] = ("ok",),
        envelopes: bool = True,
    ) -> None:
        self.dec = Decoder(plant_id, drive_id)
        self.keep_envelopes = envelopes  # every signal's min/max per bucket: the overview plot's, nothing else
        self.windows = StepWindows()
        self.sinks: list[Sink] = [self.windows, *(sinks or [])]
        self.frame_sinks = list(frame_sinks or [])
        self.expect = expect
        self.steps = {sig: StepTracker(sig) for sig, _, _ in STEP_SIGNALS}
        self.envelopes: dict[str, Envelope] = {}
        self.watch = LoopWatch()
        self.bits = 0
        self._begun = False

    @property
    def periods(self) -> int:
        return self.dec.stats.periods

    def feed(self, frames: np.ndarray, last: bool = False) -> None:
        """`last`: only `finish` follows (Decoder.feed)."""
        if len(frames) == 0:
            return
        for fs in self.frame_sinks:
            fs.write(frames)
        self.bits += frame_bits(frames)
        self._rows(self.dec.feed(frames, last))

    def _rows(self, chunk: dict[str, np.ndarray] | None) -> None:
        if chunk is None or len(chunk["period"]) == 0:
            return
        if not self._begun:
            self._begun = True
            for s in self.sinks:
                s.begin(self.dec.signals, self.dec)
            if self.keep_envelopes:
                self.envelopes = {s.name: Envelope() for s in self.dec.signals if s.name in chunk}
            self.watch.begin(self.dec)
        for sig, x, ref in STEP_SIGNALS:
            if x in chunk:
                self.steps[sig].add(chunk["period"], chunk[x], chunk[ref])
        for n, env in self.envelopes.items():
            env.add(chunk[n])
        self.watch.add(chunk)
        for s in self.sinks:
            s.write(chunk)

    def finish(
        self,
        scenario: str,
        bus: str,
        wall: dict[str, float] | None = None,
        stopped: dict[str, Any] | None = None,
        links: dict[str, dict[str, Any]] | None = None,
        faults: tuple[list[Any], list[tuple[Any, ...]], int] | None = None,
        floor: dict[str, float] | None = None,
    ) -> RunResult:
        """`stopped`: the run ended before its last period (LoopStopped.to_dict(): a node lost, a stall);
        `links`: each SocketCAN interface's kernel report before and after the run (Session.links);
        `faults`: the scenario's faults, the injector's log and how many actions it could not log."""
        self._rows(self.dec.finish())
        dec, watch = self.dec, self.watch
        if stopped:
            stopped = stopped_at(stopped, dec.stats.periods)
        steps = [m.to_dict() for sig, _, _ in STEP_SIGNALS for m in self.steps[sig].finish()]
        tuning = dec.sdo.changes("Online tuning.enable")
        for s in steps:
            on = [v for p, v in tuning if p <= s["at_period"]]
            s["tuning_on"] = bool(on and on[-1])
        steps.sort(key=lambda s: (s["signal"] != "iq", s["at_period"]))
        bstats = bus_stats(dec, self.bits)
        status, code, expected, flags, oscillating = watch.judge(dec, steps, bstats, stopped, self.expect)
        timing = dict(wall or {})
        if timing.get("run_wall_s"):
            timing["periods_per_s"] = dec.stats.periods / timing["run_wall_s"]
        summary = build_summary(
            dec,
            scenario=scenario,
            bus=bus,
            status=status,
            expected=expected,
            expect=self.expect,
            flags=flags,
            stopped=stopped,
            first_trip_period=watch.first_trip_period,
            oscillating=oscillating,
            max_phase_A=watch.max_phase_A,
            bound_A=watch.bound_A,
            steps=steps,
            bstats=bstats,
            timing=timing,
            links=links or {},
        )
        summary["status_first_period"] = watch.first_periods
        if floor is not None and summary.get("realtime"):  # the host's floor probed before the run (direct)
            summary["realtime"]["floor"] = floor
        if faults is not None:
            summary["faults"] = fault_report(faults[0], faults[1], faults[2], dec.emcy, watch.status)
        for s in self.sinks:
            s.end(summary)
        return RunResult(
            scenario,
            bus,
            status,
            code,
            expected,
            summary,
            list(dec.signals),
            # the signals', and a real-time run's timing (bench/run/verdict/realtime.py: the overview's last panel)
            envelopes={**{n: e.arrays() for n, e in self.envelopes.items()}, **watch.timing_envelopes},
            step_windows=self.windows.windows(),
        )


def _configure_and_run(
    sess: Session, progress: Progress | None = None, tick: Callable[[], None] | None = None
) -> tuple[float, dict[str, Any] | None]:
    """NMT reset, SDO configuration, the periods, the end-of-run reads: (the loop's wall time, and when it
    stopped early why: LoopStopped.to_dict(), a verdict, not a failure: the frames so far are kept)."""
    t_run = time.monotonic()
    try:
        sess.reset_nodes()
        sess.configure()  # a CAN box that ends here stops the run as in its loop (Session._check_box)
        sess.hold_plant_cpu()
        t_run = time.monotonic()
        run_wall = sess.run(progress, tick)
        sess.statuses()
    except LoopStopped as exc:
        run_wall = time.monotonic() - t_run
        if exc.status == "node_lost":
            sess.linger()  # the other node's reaction (its heartbeat consumer) goes into the record
        return run_wall, exc.to_dict()
    return run_wall, None


def run_scenario(
    sc: Scenario,
    opts: RunOptions | None = None,
    sinks: list[Sink] | None = None,
    frame_sinks: list[FrameSink] | None = None,
    keep_trace: bool = False,
    progress: Progress | None = None,
    envelopes: bool = True,
) -> RunResult:
    """Run a scenario on a bus ('direct' or a SocketCAN/python-can channel) and return its result.

    `sinks` take the trace chunks (files, viewers); `frame_sinks` the raw frames (a log writer);
    `keep_trace` also returns the whole trace in memory (O(periods): for short runs and tests);
    `envelopes=False` leaves out the signals' envelopes (RunResult.envelopes, for an overview plot: a sweep's
    point draws none), the same summary for less work.
    Over SocketCAN the frames come from candump's log in `opts.out` (which must be set). The bus's kind is chosen
    once (bench/run/bus/buses.py bus_of): the session, the recorder and the CAN box's lease ask it. Runs on the direct
    bus take turns within a process (one plant and drive per process, in libhil's statics): a second thread's run
    waits for the first's end."""
    from bench.run.bus.buses import bus_of
    from bench.run.bus.direct import ONE_AT_A_TIME

    opts = opts or RunOptions()
    kind = bus_of(opts, bool(sc.faults))
    if not kind.in_process:
        return _run(sc, opts, kind, sinks, frame_sinks, keep_trace, progress, envelopes)
    with ONE_AT_A_TIME:
        return _run(sc, opts, kind, sinks, frame_sinks, keep_trace, progress, envelopes)


def _run(
    sc: Scenario,
    opts: RunOptions,
    kind: Any,
    sinks: list[Sink] | None,
    frame_sinks: list[FrameSink] | None,
    keep_trace: bool,
    progress: Progress | None,
    envelopes: bool,
) -> RunResult:
    """run_scenario on its chosen bus."""
    from bench.run.recorder import RunRecorders

    sinks = list(sinks or [])
    collector = TraceCollector() if keep_trace else None
    if collector is not None:
        sinks.append(collector)
    pipe = Pipeline(opts.plant_id, opts.drive_id, sinks, frame_sinks, sc.expect, envelopes)
    t0 = time.monotonic()
    sess = Session(sc, opts, kind)
    recorders = RunRecorders(sess) if opts.record else None
    source: Any = None
    ran = False
    try:
        if opts.out is not None:
            opts.out.mkdir(parents=True, exist_ok=True)
        sess.box = kind.lease(sc.timing == "realtime")  # the CAN box's slot, when the buses are there
        try:
            if recorders is not None:  # candump, before the nodes start
                source = kind.recorder(recorders, opened=False)
            sess.open()
            if hasattr(source, "await_ready"):  # candump in the CAN box, started with the nodes: listening before NMT
                source.await_ready()
            if recorders is not None and source is None:  # libhil's frames, or the master's bus
                source = kind.recorder(recorders, opened=True)
        except Exception as exc:  # the CAN box ended while the run's processes started: a verdict, as in the loop
            if (stopped := sess.box_ended(exc)) is None:
                raise
            run_wall = 0.0
        else:

            def tick() -> None:
                if source is not None:
                    pipe.feed(source.drain())

            run_wall, stopped = _configure_and_run(sess, progress, tick)
        ran = True
    finally:
        sess.close()
        if source is not None:
            source.stop()
        if not ran:
            _end_box(sess, opts.out)
    try:
        if source is not None:
            pipe.feed(source.drain(final=True), last=True)
            if hasattr(source, "cleanup"):
                source.cleanup()
        injected = (sc.faults, *sess.fault_log()) if sc.faults else None
    finally:
        _end_box(sess, opts.out)
    res = pipe.finish(
        sc.name,
        opts.bus,
        {"wall_s": time.monotonic() - t0, "run_wall_s": run_wall},
        stopped,
        sess.links,
        injected,
        floor=sess.direct.floor if sess.direct is not None else sess.floor,
    )
    if sess.py_law is not None:  # a current law in Python (bench/law_py.py): what it did, and how it failed
        sess.py_law.report(res.summary)
    if sc.trip_note:  # a free rotor whose trip reaction may leave its flux map (bench/motor/trip.py): never silent
        res.summary.setdefault("notes", []).append(sc.trip_note)
    outside = (res.summary.get("counters") or {}).get("plant_outside_map_periods")
    if outside:  # the flux-map model counts the periods that ended off its grid (plant.eds Run control)
        res.summary.setdefault("notes", []).append(
            f"the currents left the flux map's grid in {outside} periods: the plant extrapolated the map there "
            "(extend the map, or lower drive.I_trip_A: docs/YOUR_MOTOR.md)"
        )
    if collector is not None:
        res.trace = collector.trace
    return res


def _end_box(sess: Session, keep: Path | None) -> None:
    """The run's share of the box given back (what is left of its processes killed, its namespace removed),
    what it wrote in the box (the processes' output, candump's log) moved into the run's folder. Once."""
    lease, sess.box = sess.box, None
    if lease is not None:
        sess.kind.release(lease, keep)


def capture_to_log(sc: Scenario, opts: RunOptions) -> tuple[float, dict[str, Any] | None, dict[str, dict[str, Any]]]:
    """The bus half of a run only: nodes, master and candump's log in `opts.out`; no decoding
    (inside the VM, where Python is slow, the host decodes the log). Returns the loop's wall time,
    when the loop ended early why (LoopStopped.to_dict()), and the interfaces' state (Session.links)."""
    from bench.run.record.sources import CandumpSource

    assert opts.out is not None
    sess = Session(sc, opts)
    sess.prepare_links()
    source = CandumpSource(opts.bus, opts.out / "candump.log", follow=False)
    try:
        sess.open()
        run_wall, stopped = _configure_and_run(sess)
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
