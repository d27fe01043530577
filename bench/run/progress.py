"""Progress on every phase of a run that takes time: a tqdm bar on a terminal, else lines a CI log keeps (Progress);
the trace sink that moves it with the periods decoded (ProgressSink). Used by `bench run` and `bench replay`."""

from __future__ import annotations

import sys
import time
from typing import Any


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


class ProgressSink:
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
