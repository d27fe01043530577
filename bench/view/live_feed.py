"""The live viewer's stream of a run (`--serve`, or a spawned viewer): what a person can see, sent by a thread of
its own, never holding up the run or its recording.

- **What is sent.** By default (`--live-decimate` not given) a min/max envelope: each signal's rows in buckets, the
  smallest and the largest value of each bucket kept at their own period, and the bucket sized from the rate the
  rows come at so that about LIVE_BUCKETS_PER_S buckets a second of wall time go out (a real-time run at 100 us
  brings 10,000 rows a second: buckets of 10; a direct lockstep run at 400,000: buckets of 400). A spike of one
  period stays in view, where every Nth period would miss it. `--live-decimate N` sends every Nth period, as before.
- **What is drawn.** The live viewer's views show the last LIVE_WINDOW_S simulated seconds before the time cursor,
  which follows the run: what a frame draws stays the same as the run grows (the whole run is in run.rrd).
- **Never blocking.** The rows go through a bounded queue to the sending thread: when the viewer (or the network) is
  slower than the run, rerun's channel fills, the thread waits, the queue fills, and the rows of the chunks that
  find it full are dropped from the live view, counted (`stats`). The recording (run.rrd) gets every row anyway:
  it is written by the caller, not here. rerun-sdk releases the GIL while it waits for its channel (checked with
  rerun-sdk 0.41: a thread kept running while another was blocked in `send_columns` for 8 s).
"""

from __future__ import annotations

import math
import queue
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import rerun as rr

LIVE_BUCKETS_PER_S = 1000  # envelope buckets a second of wall time: two points each, per signal
LIVE_WINDOW_S = 10.0  # the live viewer's views show the last this many simulated seconds (bench/view/rerun_blueprint)
QUEUE_CHUNKS = 4  # chunks waiting for the sending thread before new ones are dropped
END_BUCKETS = 2000  # envelope buckets of a column of the whole run sent at its end (the SYNC lateness)
LIVE_SEND_S = 0.5  # the live stream's rows go out gathered, this often
END_WAIT_S = 10.0  # at the run's end, how long what is queued may take to reach the viewer

Columns = list[tuple[str, np.ndarray]]
Item = list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]  # (entity path, values, period, sim_time) per signal


def envelope_index(values: np.ndarray, bucket: int) -> np.ndarray:
    """The rows kept of one signal: per bucket of `bucket` rows (the last one shorter), the row of its smallest and of
    its largest value, in row order (one row when they are the same): a bucket with a NaN keeps its first NaN row
    alone (a gap stays a gap in the viewer)."""
    n = len(values)
    if bucket <= 1 or n <= 2:
        return np.arange(n)
    full = n // bucket * bucket
    parts = [values[:full].reshape(-1, bucket)] if full else []
    starts = [np.arange(0, full, bucket)] if full else []
    if full < n:  # the tail: one bucket of its own
        parts.append(values[full:].reshape(1, -1))
        starts.append(np.array([full]))
    lo, hi = [], []
    for block, base in zip(parts, starts, strict=True):
        imin, imax = block.argmin(axis=1), block.argmax(axis=1)  # numpy: both the first NaN, if any
        lo.append(base + np.minimum(imin, imax))
        hi.append(base + np.maximum(imin, imax))
    first, second = np.concatenate(lo), np.concatenate(hi)
    idx = np.stack([first, second], axis=1).ravel()
    keep = np.ones(len(idx), dtype=bool)
    keep[1::2] = second != first
    return idx[keep]


def _gather(pending: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]], item: Item) -> None:
    for path, values, period, t_s in item:
        pending.setdefault(path, []).append((values, period, t_s))


class LiveFeed:
    """The live stream `rec`: `put` thins a chunk's columns and queues them (or drops them when the queue is full),
    a thread sends them; `call` queues other work for the stream (a blueprint, the end's events); `close` waits up to
    END_WAIT_S for what is queued. `decimate`: every Nth period, or None for the min/max envelope."""

    def __init__(self, rec: rr.RecordingStream, decimate: int | None) -> None:
        self.rec = rec
        self.decimate = decimate
        self._queue: queue.Queue[Item | Callable[[], None] | None] = queue.Queue(maxsize=QUEUE_CHUNKS)
        self._clock = time.monotonic  # the rows' arrival times (a test sets its own)
        self._last = self._clock()
        self.periods = self.periods_dropped = self.points = 0
        self.buckets: list[int] = []  # the envelope's bucket sizes, min and max (stats)
        self._thread = threading.Thread(target=self._send_loop, daemon=True, name="bench-live-view")
        self._thread.start()

    def put(self, columns: Columns, period: np.ndarray, t_s: np.ndarray, seen: int, whole: bool = False) -> None:
        """One chunk of rows (`seen`: the rows before it, for every Nth period across chunks). `whole`: not a chunk of
        the run as it goes but a column of the whole run made at its end (the SYNC lateness): its envelope has
        END_BUCKETS buckets, and its rows are not counted as the run's periods."""
        n = len(period)
        item = self._thin(columns, period, t_s, seen, math.ceil(n / END_BUCKETS) if whole else None)
        if not whole:
            self.periods += n
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self.periods_dropped += 0 if whole else n
            return
        self.points += sum(len(v) for _, v, _, _ in item)

    def call(self, job: Callable[[], None]) -> None:
        """Other work for the stream, in order with the rows (waits for room up to END_WAIT_S, then drops it)."""
        try:
            self._queue.put(job, timeout=END_WAIT_S)
        except queue.Full:
            print("rerun: the live viewer fell behind; an update of its layout or events was not sent", file=sys.stderr)

    def _thin(self, columns: Columns, period: np.ndarray, t_s: np.ndarray, seen: int, bucket: int | None) -> Item:
        if self.decimate is not None:
            first = (-seen) % self.decimate
            rows = np.arange(first, len(period), self.decimate)
            return [(p, v[rows], period[rows], t_s[rows]) for p, v in columns]
        if bucket is None:
            now = self._clock()
            rate = len(period) / max(now - self._last, 1e-3)  # rows a second of wall time, as they come
            self._last = now
            bucket = max(1, math.ceil(rate / LIVE_BUCKETS_PER_S))
            was = self.buckets
            self.buckets = [min(was[0], bucket), max(was[1], bucket)] if was else [bucket, bucket]
        out: Item = []
        for path, values in columns:
            rows = envelope_index(values, bucket)
            out.append((path, values[rows], period[rows], t_s[rows]))
        return out

    def _send_loop(self) -> None:
        """Rows gathered per signal and sent every LIVE_SEND_S: a viewer takes few large chunks far better than many
        small ones (each chunk is a store insertion in the viewer)."""
        pending: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        last = time.monotonic()
        while True:
            try:
                item = self._queue.get(timeout=LIVE_SEND_S)
            except queue.Empty:
                item = ()  # nothing new: what is gathered goes out if due
            try:
                if item and not callable(item):
                    _gather(pending, item)
                if item is None or callable(item) or time.monotonic() - last >= LIVE_SEND_S:
                    self._send(pending)  # the rows before a job, the last ones, or those due
                    last = time.monotonic()
                if item is None:
                    return
                if callable(item):
                    item()
            except Exception as exc:  # noqa: BLE001 - a viewer that went away must not end the run
                print(f"rerun: live viewer: {exc}", file=sys.stderr, flush=True)

    def _send(self, pending: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]) -> None:
        for path, parts in pending.items():
            values, period, t_s = (np.concatenate(x) for x in zip(*parts, strict=True))
            if len(period):
                times = [rr.TimeColumn("period", sequence=period), rr.TimeColumn("sim_time", duration=t_s)]
                self.rec.send_columns(path, indexes=times, columns=rr.Scalars.columns(scalars=values))
        pending.clear()

    def close(self) -> None:
        """Send what is queued (up to END_WAIT_S), then stop the thread; the rest of the queue is dropped."""
        deadline = time.monotonic() + END_WAIT_S
        try:
            self._queue.put(None, timeout=END_WAIT_S)
        except queue.Full:
            pass
        self._thread.join(max(0.0, deadline - time.monotonic()))
        if self._thread.is_alive():
            print(f"rerun: the live viewer did not take the run's last rows within {END_WAIT_S:g} s", file=sys.stderr)

    def stats(self) -> dict[str, Any]:
        """What the live viewer got: summary.json's "live_view"."""
        mode = "envelope" if self.decimate is None else "every_nth"
        out: dict[str, Any] = {"mode": mode, "periods": self.periods, "periods_dropped": self.periods_dropped}
        out |= {"decimate": self.decimate} if self.decimate is not None else {"buckets": self.buckets}
        out["points_sent"] = self.points
        return out
