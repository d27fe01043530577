"""Consumers of a run's trace chunks. Each takes every chunk once, in memory; files are
written once, as the chunks come (nothing is read back).

A sink has `begin(signals, ctx)`, `write(chunk)` and `end(summary)`; `ctx` is the Decoder
(layout, Ts, pole pairs, the nodes' state as the bus showed it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from bench.run.bus.frames import FRAME_DTYPE, join
from bench.signals import SignalInfo

TRACES_FILE = "traces.npy"


class Sink(Protocol):
    def begin(self, signals: list[SignalInfo], ctx: Any) -> None: ...
    def write(self, chunk: dict[str, np.ndarray]) -> None: ...
    def end(self, summary: dict[str, Any]) -> None: ...


def columns(signals: list[SignalInfo]) -> list[str]:
    return ["period", "t_s", *[s.name for s in signals]]


def trace_dtype(signals: list[SignalInfo]) -> np.dtype:
    """A trace row: the period, its time, each signal in its storage type (traces.npy's, TraceRows')."""
    return np.dtype([("period", "<i8"), ("t_s", "<f8"), *[(s.name, s.storage) for s in signals]])


def rows_of(dtype: np.dtype, chunk: dict[str, np.ndarray]) -> np.ndarray:
    """A chunk's columns as rows of `dtype` (NaN where no frame carried a signal)."""
    rows = np.empty(len(chunk["period"]), dtype=dtype)
    for name in dtype.names or ():
        rows[name] = chunk[name] if name in chunk else np.nan
    return rows


class TraceFileSink:
    """traces.npy: one numpy structured array, a row per period and a field per signal (NaN where
    no frame carried it), appended chunk by chunk. Its header is written first with room for any
    row count and rewritten at the end, so the file is a standard .npy that np.load reads
    (mmap_mode="r" reads one column of a long run without loading the rest)."""

    HEADER_BYTES = 64 * 64  # room for a few hundred field names; checked

    def __init__(self, path: Path) -> None:
        self.path = path
        self.rows = 0
        self._fh: Any = None
        self.dtype: np.dtype | None = None

    def begin(self, signals: list[SignalInfo], ctx: Any) -> None:
        self.dtype = trace_dtype(signals)
        self._fh = open(self.path, "wb")  # noqa: SIM115 - closed in end()
        self._fh.write(self._header(0))

    def _header(self, rows: int) -> bytes:
        assert self.dtype is not None
        d = {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False, "shape": (rows,)}
        text = repr(d).encode("latin1")
        room = self.HEADER_BYTES - 12 - 1
        if len(text) > room:
            raise ValueError(f"too many trace signals for the .npy header ({len(text)} > {room} bytes)")
        # magic, version 2.0, 4-byte header length, header padded with spaces, newline
        return b"\x93NUMPY\x02\x00" + (room + 1).to_bytes(4, "little") + text.ljust(room) + b"\n"

    def write(self, chunk: dict[str, np.ndarray]) -> None:
        assert self.dtype is not None
        rows = rows_of(self.dtype, chunk)
        self._fh.write(rows.tobytes())
        self.rows += len(rows)

    def end(self, summary: dict[str, Any]) -> None:
        if self._fh is None:
            return
        self._fh.seek(0)
        self._fh.write(self._header(self.rows))
        self._fh.close()
        self._fh = None


class TraceRows:
    """The whole trace in memory as the rows traces.npy holds (bench.api.run without files): `rows` after the end."""

    def __init__(self) -> None:
        self._parts: list[np.ndarray] = []
        self.dtype: np.dtype | None = None
        self.rows: np.ndarray | None = None

    def begin(self, signals: list[SignalInfo], ctx: Any) -> None:
        self.dtype = trace_dtype(signals)

    def write(self, chunk: dict[str, np.ndarray]) -> None:
        assert self.dtype is not None
        self._parts.append(rows_of(self.dtype, chunk))

    def end(self, summary: dict[str, Any]) -> None:
        if self.dtype is not None:
            self.rows = np.concatenate(self._parts) if self._parts else np.empty(0, dtype=self.dtype)
        self._parts = []


class TraceCollector:
    """The whole trace in memory, as columns (what the claims and the API's callers take)."""

    def __init__(self) -> None:
        self._parts: list[dict[str, np.ndarray]] = []
        self.trace: dict[str, np.ndarray] = {}

    def begin(self, signals: list[SignalInfo], ctx: Any) -> None:
        self._names = columns(signals)

    def write(self, chunk: dict[str, np.ndarray]) -> None:
        self._parts.append(chunk)

    def end(self, summary: dict[str, Any]) -> None:
        if self._parts:
            self.trace = {k: np.concatenate([p[k] for p in self._parts]) for k in self._parts[0]}
        self._parts = []


class FrameCollector:
    """Every frame in memory (a frame sink: for tests and short runs)."""

    def __init__(self) -> None:
        self._parts: list[np.ndarray] = []
        self.frames = np.zeros(0, dtype=FRAME_DTYPE)

    def write(self, frames: np.ndarray) -> None:
        self._parts.append(frames)

    def close(self) -> None:
        if self._parts:
            self.frames = join([self.frames, *self._parts])
            self._parts = []


class StepWindows:
    """The rows around each reference step (a few dozen per step, the first MAX_WINDOWS steps), kept for the
    step plots (RunResult.step_windows)."""

    WINDOW = (4, 24)  # periods before and after a reference step kept for its plot
    MAX_WINDOWS = 64  # steps whose rows are kept (the plots show the first dozen)

    def __init__(self) -> None:
        self._tail: dict[str, np.ndarray] = {}  # the last rows, for step windows that start in a chunk
        self._windows: list[dict[str, Any]] = []
        self._open_windows: list[dict[str, Any]] = []
        self._seen: set[tuple[int, str]] = set()

    def begin(self, signals: list[SignalInfo], ctx: Any) -> None:
        pass

    def write(self, chunk: dict[str, np.ndarray]) -> None:
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

    def end(self, summary: dict[str, Any]) -> None:
        pass

    def windows(self) -> list[dict[str, np.ndarray]]:
        return [{**w["rows"], "at_period": np.int64(w["at"])} for w in sorted(self._windows, key=lambda w: w["at"])]
