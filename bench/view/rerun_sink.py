"""Rerun sink of a run: traces decoded chunk by chunk go to an .rrd file (full rate) and,
when asked, to a live viewer (every Nth period): a spawned native viewer, or a web viewer
served from this process.

Entities are grouped by SI unit, `/{unit_slug}/{column}`, under a blueprint of one time-series view
per unit (bench/view/rerun_blueprint.py). Timelines: `period` (sequence, the control-period index)
and `sim_time` (duration, simulated seconds). Each chunk is logged with one `send_columns` call per
signal. A real-time run's chunks carry each period's SYNC and command time stamps
(bench/run/verdict/realtime.py): its turnaround goes to `/timing/turnaround_us` as the chunks come, its
SYNC lateness to `/timing/sync_lateness_us` at the end (the grid of a segment is anchored on the segment's
earliest SYNC, known when the run is over: the summary's realtime block names the segments), in a timing view.

Serving happens once per process (bench/view/serve.py): the first serve-mode sink starts the
server (gRPC and the web viewer, on 127.0.0.1 unless `bind` says otherwise), and it stays up until
the process exits or `serve.stop()` (`serve_until` keeps the process alive after a run); later
serve-mode sinks in the same process stream to the same server when they ask for the same ports,
and are refused with a clear error when they ask for others.
"""

from __future__ import annotations

import ipaddress
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
import rerun as rr

from bench.run.verdict.realtime import COMMAND_T, SYNC_T, TIMING_COLUMNS, BusTiming, summary_segments
from bench.signals import SignalInfo
from bench.view.live_feed import LIVE_WINDOW_S, LiveFeed
from bench.view.rerun_blueprint import RERUN_0_23, TIMING, blueprint_for, entity_path, events_blueprint
from bench.view.serve import DEFAULT_BIND, PORT_OPTIONS, ServeError, listening
from bench.view.serve import serve as _serve

__all__ = ["PORT_OPTIONS", "RerunSink", "ServeError"]

APPLICATION_ID = "pmsm-hil-bench"
TIMELINES = ("period", "t_s")  # chunk columns that are timelines, not signals
LATENESS_PATH, TURNAROUND_PATH = f"/{TIMING}/sync_lateness_us", f"/{TIMING}/turnaround_us"


# --- serving: bench/view/serve.py; spawning a native viewer -------------------------------------

_SAID_NO_DISPLAY = False


def _viewer_executable() -> str | None:
    """The `rerun` viewer: on PATH, else the one the rerun-sdk wheel installed next to this
    interpreter (a venv's bin/, not on PATH when .venv/bin/python is run directly)."""
    if shutil.which("rerun"):
        return None  # rerun finds it itself
    beside = Path(sys.executable).with_name("rerun.exe" if sys.platform == "win32" else "rerun")
    return str(beside) if beside.exists() else None


def _display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform in ("darwin", "win32")


def _spawn_viewer(name: str, grpc_port: int, memory_limit: str, rrd: Path | None) -> rr.RecordingStream | None:
    """A native viewer spawned on `grpc_port` and a stream connected to it; None, said on stdout, when there is
    no display (said once per process), the spawn failed, or the viewer does not listen."""
    global _SAID_NO_DISPLAY
    if not _display():
        if not _SAID_NO_DISPLAY:
            print(
                "rerun: no display (DISPLAY/WAYLAND_DISPLAY unset): no viewer spawned"
                + (f"; the recording is saved to {rrd}" if rrd else ""),
                flush=True,
            )
            _SAID_NO_DISPLAY = True
        return None
    saved = f"; the recording is saved to {rrd}" if rrd else ""
    live_rec = rr.RecordingStream(APPLICATION_ID, recording_id=name)
    try:
        # Not connect=True: a viewer that died at start (no usable display) would leave the
        # stream buffering the whole run for a connection that never comes.
        newer: dict[str, Any] = {"server_memory_limit": memory_limit, "executable_path": _viewer_executable()}
        rr.spawn(
            port=grpc_port,
            connect=False,
            memory_limit=memory_limit,
            hide_welcome_screen=True,
            recording=live_rec,
            **({} if RERUN_0_23 else newer),
        )
    except Exception as exc:  # noqa: BLE001 - the .rrd still gets everything
        first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"rerun: no viewer spawned ({first_line}){saved}", flush=True)
        return None
    if listening(grpc_port, within_s=1.0):
        live_rec.connect_grpc(f"rerun+http://127.0.0.1:{grpc_port}/proxy")
        return live_rec
    print(
        f"rerun: the spawned viewer is not listening on port {grpc_port} (it failed to start, see above){saved}",
        flush=True,
    )
    return None


# --- the sink ------------------------------------------------------------------------------------


class RerunSink:
    """Chunks of a run to an .rrd file (full rate) and optionally a live viewer (every
    `live_decimate`-th period): `live="spawn"` a native viewer (when a display exists),
    `live="serve"` the web viewer served from this process at `url`."""

    def __init__(
        self,
        name: str,
        rrd: Path | None,
        live: Literal["none", "spawn", "serve"] = "none",
        live_decimate: int | None = None,
        web_port: int = 9090,
        grpc_port: int = 9876,
        memory_limit: str = "1GiB",
        bind: str = DEFAULT_BIND,
    ) -> None:
        if live not in ("none", "spawn", "serve"):
            raise ValueError(f"live must be 'none', 'spawn' or 'serve', not {live!r}")
        self.name = name
        self.rrd = Path(rrd) if rrd is not None else None
        self.live_decimate = None if live_decimate is None else max(1, int(live_decimate))
        self.feed: LiveFeed | None = None  # the live stream's sending thread (bench/view/live_feed.py)
        self._url: str | None = None
        self._signals: list[SignalInfo] = []
        self._paths: dict[str, str] = {}
        self._warned: set[str] = set()
        self._rows_seen = 0
        self._begun = self._ended = self._closed = False
        self._timing = BusTiming()  # a real-time run's time stamps, for its SYNC lateness at the end
        self._owns_server = False

        self.live: rr.RecordingStream | None = None
        if live == "serve":
            self.live, server = _serve(name, web_port, grpc_port, memory_limit, bind)
            self._url = server.url
            self._owns_server = server.owner is self.live
            wide = "" if ipaddress.ip_address(server.bind).is_loopback else "; other machines can watch"
            print(f"rerun: web viewer at {self._url} (listening on {server.where}{wide})", flush=True)
        elif live == "spawn":
            self.live = _spawn_viewer(name, grpc_port, memory_limit, self.rrd)

        # The file last: a refused serve leaves no empty .rrd behind.
        self.file: rr.RecordingStream | None = None
        if self.rrd is not None:
            self.rrd.parent.mkdir(parents=True, exist_ok=True)
            self.file = rr.RecordingStream(APPLICATION_ID, recording_id=name)
            self.file.save(str(self.rrd))

    def live_stats(self) -> dict[str, Any] | None:
        """What the live viewer was sent (bench/view/live_feed.py, LiveFeed.stats), or None without one."""
        return self.feed.stats() if self.feed is not None else None

    @property
    def url(self) -> str | None:
        """The address a browser opens (serve mode), else None."""
        return self._url

    def begin(self, signals: list[SignalInfo], ctx: Any = None) -> None:
        """Declare the signals (before the first chunk): builds and sends the blueprint. `ctx`
        (the decoder, as bench.run.sinks.Sink passes it) is not used."""
        seen: set[str] = set()
        self._signals = [s for s in signals if s.name not in TIMELINES and not (s.name in seen or seen.add(s.name))]
        self._paths = {s.name: entity_path(s) for s in self._signals}
        bp = blueprint_for(self._signals)
        if self.file is not None:
            self.file.send_blueprint(bp, make_active=False, make_default=True)
        if self.live is not None:  # the last LIVE_WINDOW_S of the run, scrolling with it
            live_bp = blueprint_for(self._signals, window_s=LIVE_WINDOW_S)
            self.live.send_blueprint(live_bp, make_active=True, make_default=True)
            self.feed = LiveFeed(self.live, self.live_decimate)
        self._begun = True

    def _warn_once(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            print(f"rerun: {message}", file=sys.stderr, flush=True)

    @staticmethod
    def _send(
        rec: rr.RecordingStream, columns: list[tuple[str, np.ndarray]], period: np.ndarray, t_s: np.ndarray
    ) -> None:
        times = [rr.TimeColumn("period", sequence=period), rr.TimeColumn("sim_time", duration=t_s)]
        for path, values in columns:
            rec.send_columns(path, indexes=times, columns=rr.Scalars.columns(scalars=values))

    def write(self, chunk: dict[str, np.ndarray]) -> None:
        """Log the periods of one chunk: all of them to the file, every Nth to the live viewer."""
        if self._ended:
            raise RuntimeError("RerunSink.write() after end()")
        if not self._begun:
            raise RuntimeError("RerunSink.write() before begin()")
        period = np.asarray(chunk["period"], dtype=np.int64)
        n = len(period)
        if n == 0:
            return
        t_s = np.asarray(chunk["t_s"], dtype=np.float64)
        columns: list[tuple[str, np.ndarray]] = []
        for sig in self._signals:
            col = chunk.get(sig.name)
            if col is None:
                self._warn_once("missing:" + sig.name, f"signal {sig.name} is missing from a chunk; not logged there")
                continue
            col = np.asarray(col)
            if col.shape != (n,) or not (np.issubdtype(col.dtype, np.number) or col.dtype == np.bool_):
                self._warn_once(
                    "shape:" + sig.name,
                    f"signal {sig.name} ({col.dtype}, shape {col.shape}) is not {n} numbers; not logged",
                )
                continue
            columns.append((self._paths[sig.name], col.astype(np.float64, copy=False)))
        if SYNC_T in chunk:
            columns.append((TURNAROUND_PATH, self._timed(chunk)))
        for name in chunk.keys() - self._paths.keys() - set(TIMELINES) - set(TIMING_COLUMNS):
            self._warn_once("undeclared:" + name, f"column {name} was not declared in begin(); not logged")

        self._log(columns, period, t_s, self._rows_seen)
        self._rows_seen += n

    def _log(
        self, columns: list[tuple[str, np.ndarray]], period: np.ndarray, t_s: np.ndarray, seen: int, whole: bool = False
    ) -> None:
        """Rows to the file (all) and the live viewer (every live_decimate-th; `seen`: rows before these)."""
        if self.file is not None:
            self._send(self.file, columns, period, t_s)
            # Block until this chunk is encoded to the file: the stream's queue would otherwise
            # grow with the run when logging outpaces the file writer.
            self.file.flush()
        if self.feed is not None:
            self.feed.put(columns, period, t_s, seen, whole)  # thinned, by its own thread, dropped if the viewer lags

    def _timed(self, chunk: dict[str, np.ndarray]) -> np.ndarray:
        """A real-time chunk's time stamps kept (the blueprint gets its timing view with the first); its turnaround."""
        if not self._timing:
            bp = blueprint_for(self._signals, timing=True)
            if self.file is not None:
                self.file.send_blueprint(bp, make_active=False, make_default=True)
            if self.live is not None and self.feed is not None:
                live, live_bp = self.live, blueprint_for(self._signals, timing=True, window_s=LIVE_WINDOW_S)
                self.feed.call(lambda: live.send_blueprint(live_bp, make_active=True, make_default=True))
        self._timing.add(chunk)
        sync = np.asarray(chunk[SYNC_T], dtype=np.float64)
        cmd = np.asarray(chunk[COMMAND_T], dtype=np.float64) if COMMAND_T in chunk else np.full(len(sync), np.nan)
        return cmd - sync

    def _lateness(self, summary: dict[str, Any]) -> None:
        """The SYNC lateness of every period, on the grid of its segment (the summary's realtime block)."""
        segs = summary_segments(summary)
        if not self._timing or segs is None:
            return
        pp = self._timing.per_period(segs)
        if len(pp.period):
            ts_s = float(summary.get("Ts_s") or 0.0)
            self._log([(LATENESS_PATH, pp.lateness)], pp.period, pp.period * ts_s, int(pp.period[0]), whole=True)

    def end(self, summary: dict[str, Any] | None = None) -> None:
        """Flush everything; the .rrd is complete and readable afterwards. Serving goes on. From `summary` (as
        bench.run.sinks.Sink passes it): a real-time run's segments (the SYNC lateness), the faults (events)."""
        if self._ended:
            return
        self._ended = True
        if summary:
            try:
                self._lateness(summary)
            except Exception as exc:  # noqa: BLE001 - the recording must still be closed
                self._warn_once("timing", f"the SYNC lateness was not logged ({exc})")
        if summary and summary.get("faults"):
            try:
                self._fault_events(summary["faults"])
            except Exception as exc:  # noqa: BLE001 - the recording must still be closed
                self._warn_once("faults", f"the fault events were not logged ({exc})")
        if self.file is not None:
            self.file.flush()
            self.file.disconnect()  # writes the footer and closes the file
        if self.feed is not None:
            self.feed.close()  # what is queued, up to its bound
        if self.live is not None:
            try:
                self.live.flush() if RERUN_0_23 else self.live.flush(timeout_sec=10.0)  # 0.23: 2 s without progress
            except Exception as exc:  # noqa: BLE001 - a slow viewer must not fail the run
                print(f"rerun: live viewer did not take all data ({exc})", file=sys.stderr, flush=True)

    def _fault_events(self, rep: dict[str, Any]) -> None:
        """The faults injected and the nodes' reactions as text logs on the period timeline, in an events
        panel added under the plots (the blueprint is sent again with it)."""
        rows: list[tuple[int, str, str, str]] = []
        for f in rep["injected"]:
            for p in f["action_periods"]:
                rows.append((p, "events/faults", f"fault {f['fault']}: {f['description']}", "WARN"))
        for r in rep["reactions"]:
            rows.append((r["period"], f"events/reactions/{r['node']}", f"{r['node']}: {r['what']}", "INFO"))

        def write(rec: rr.RecordingStream) -> None:
            for period, path, text, level in sorted(rows):
                rec.set_time("period", sequence=period)
                rec.log(path, rr.TextLog(text, level=level))
            window = LIVE_WINDOW_S if rec is self.live else None
            bp = events_blueprint(self._signals, timing=bool(self._timing), window_s=window)
            rec.send_blueprint(bp, make_active=rec is self.live, make_default=True)

        if self.file is not None:
            write(self.file)
        if self.live is not None and self.feed is not None:
            live = self.live
            self.feed.call(lambda: write(live))  # in order with the rows, by the live stream's thread

    def serve_until(self, seconds: float | None) -> None:
        """Keep the web viewer up after the run: until Ctrl-C (None) or for `seconds`."""
        if self._url is None:
            print("rerun: no web viewer is served (live mode is not 'serve')", flush=True)
            return
        if seconds is None:
            print(f"rerun: serving the web viewer at {self._url} until Ctrl-C", flush=True)
        else:
            print(f"rerun: serving the web viewer at {self._url} for {seconds:g} s (Ctrl-C stops)", flush=True)
        try:
            if seconds is None:
                while True:
                    time.sleep(3600)
            else:
                deadline = time.monotonic() + seconds
                while (left := deadline - time.monotonic()) > 0:
                    time.sleep(min(left, 1.0))
        except KeyboardInterrupt:
            print("rerun: stopped serving", flush=True)

    def close(self) -> None:
        """end(), then release the streams. The web viewer and gRPC server of this process stay up
        until it exits (the stream hosting the server is kept)."""
        if self._closed:
            return
        self.end()
        self._closed = True
        self.file = None
        if self.live is not None and not self._owns_server:
            self.live.disconnect()
        self.live = None

    def __enter__(self) -> RerunSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
