"""What a run's summary needs, accumulated chunk by chunk in bounded memory: step-response
metrics per reference step, the extremes of the currents, and a min/max envelope per
signal for the overview plots. Same definitions as bench/metrics.py (which works on a
whole trace in memory and is what the claims use): a test checks that both agree.
"""

from __future__ import annotations

import numpy as np

from bench.metrics import BAND, StepMetrics

STEP_SIGNALS = (("iq", "iq_A", "iq_ref_A"), ("id", "id_A", "id_ref_A"))


def _blocks(n0: int, length: int, block: int) -> tuple[np.ndarray, np.ndarray]:
    """Blocks touched by samples n0 .. n0+length-1 and where each starts in the segment."""
    first, last = n0 // block, (n0 + length - 1) // block
    blk = np.arange(first, last + 1)
    starts = np.maximum(blk * block - n0, 0)
    return blk, starts


class BlockSums:
    """Sum and count of a growing series in at most `cap` blocks: blocks double in size when
    full, so a window of any length costs bounded memory. The mean over the last fifth is
    exact while the window has at most `cap` periods (2^20 by default) and off by under one
    block beyond."""

    def __init__(self, cap: int = 1 << 20) -> None:
        self.cap = cap
        self.block = 1
        self.sums = np.zeros(min(cap, 1024))  # grown on demand: a short window costs a short array
        self.counts = np.zeros(len(self.sums), dtype=np.int64)
        self.n = 0  # samples

    def _room(self, blocks: int) -> None:
        if blocks > len(self.sums):
            size = min(self.cap, max(blocks, 2 * len(self.sums)))
            self.sums = np.concatenate([self.sums, np.zeros(size - len(self.sums))])
            self.counts = np.concatenate([self.counts, np.zeros(size - len(self.counts), dtype=np.int64)])

    def add(self, x: np.ndarray) -> None:
        i = 0
        while i < len(x):
            if self.n >= self.cap * self.block:
                self._merge()
            room = min(len(x) - i, self.cap * self.block - self.n)
            seg = x[i : i + room]
            good = ~np.isnan(seg)
            blk, starts = _blocks(self.n, len(seg), self.block)
            self._room(int(blk[-1]) + 1)
            self.sums[blk] += np.add.reduceat(np.where(good, seg, 0.0), starts)
            self.counts[blk] += np.add.reduceat(good.astype(np.int64), starts)
            self.n += len(seg)
            i += room

    def _merge(self) -> None:
        self._room(self.cap)
        half = self.cap // 2
        self.sums[:half] = self.sums[0::2] + self.sums[1::2]
        self.counts[:half] = self.counts[0::2] + self.counts[1::2]
        self.sums[half:] = 0
        self.counts[half:] = 0
        self.block *= 2

    def tail_mean(self, start: int) -> float:
        b = start // self.block
        c = self.counts[b:].sum()
        return float(self.sums[b:].sum() / c) if c else float("nan")


class StepTracker:
    """bench.metrics.step_metrics for one signal, streamed: a window opens at each change of the
    reference and closes at the next (or at the end of the run)."""

    def __init__(self, signal: str, min_step_A: float = 1e-6) -> None:
        self.signal = signal
        self.min_step = min_step_A
        self.done: list[StepMetrics] = []
        self._prev_ref: float | None = None
        self._open: dict[str, object] | None = None

    def add(self, period: np.ndarray, x: np.ndarray, ref: np.ndarray) -> None:
        if len(ref) == 0:
            return
        prev = ref[0] if self._prev_ref is None else self._prev_ref
        r = np.concatenate([[prev], ref])  # r[j] = the reference before local period j
        changes = (np.nonzero(np.abs(np.diff(r)) > self.min_step)[0]).tolist()
        edges = [0, *changes, len(x)]
        for k in range(len(edges) - 1):
            a, b = edges[k], edges[k + 1]
            if k > 0:  # a reference step at local period a
                self._close()
                self._begin(int(period[a]), float(r[a]), float(ref[a]))
            if self._open is not None and b > a:
                self._extend(x[a:b])
        self._prev_ref = float(ref[-1])

    def _begin(self, at: int, r0: float, r1: float) -> None:
        self._open = {
            "at": at,
            "r0": r0,
            "r1": r1,
            "n": 0,
            "last_out": -1,
            "over": -np.inf,
            "all_nan": True,
            "sums": BlockSums(),
            "env": Envelope(4096),
        }

    def _extend(self, seg: np.ndarray) -> None:
        w = self._open
        assert w is not None
        r1, step = float(w["r1"]), float(w["r1"]) - float(w["r0"])  # type: ignore[arg-type]
        band = BAND * abs(step)
        out = np.nonzero(~(np.abs(seg - r1) <= band))[0]
        n0 = int(w["n"])  # type: ignore[arg-type]
        if len(out):
            w["last_out"] = n0 + int(out[-1])
        if not np.isnan(seg).all():
            w["all_nan"] = False
            w["over"] = max(float(w["over"]), float(np.nanmax(np.sign(step) * (seg - r1))))  # type: ignore[arg-type]
        w["sums"].add(seg - r1)  # type: ignore[union-attr]
        w["env"].add(seg - r1)  # type: ignore[union-attr]
        w["n"] = n0 + len(seg)

    def _close(self) -> None:
        w, self._open = self._open, None
        if w is None:
            return
        n = int(w["n"])  # type: ignore[arg-type]
        if n < 3 or w["all_nan"]:
            return
        r0, r1 = float(w["r0"]), float(w["r1"])  # type: ignore[arg-type]
        last = int(w["last_out"])  # type: ignore[arg-type]
        settle = None if last == n - 1 else last + 1
        over = max(float(w["over"]), 0.0)  # type: ignore[arg-type]
        start = n - max(1, n // 5)
        tail = w["sums"].tail_mean(start)  # type: ignore[union-attr]
        p2p = w["env"].tail_range(start)  # type: ignore[union-attr]
        self.done.append(
            StepMetrics(
                self.signal,
                int(w["at"]),
                r0,
                r1,
                settle,
                over,  # type: ignore[arg-type]
                100.0 * over / abs(r1 - r0),
                tail,
                n,
                p2p,
            )
        )

    def finish(self) -> list[StepMetrics]:
        self._close()
        return self.done


class Envelope:
    """Min and max of a signal over at most `buckets` buckets of periods (doubling like BlockSums):
    what an overview plot of a run of any length needs."""

    def __init__(self, buckets: int = 2048) -> None:
        self.cap = buckets
        self.block = 1
        self.lo = np.full(buckets, np.inf)
        self.hi = np.full(buckets, -np.inf)
        self.n = 0

    def add(self, x: np.ndarray) -> None:
        i = 0
        while i < len(x):
            if self.n >= self.cap * self.block:
                half = self.cap // 2
                self.lo[:half] = np.fmin(self.lo[0::2], self.lo[1::2])
                self.hi[:half] = np.fmax(self.hi[0::2], self.hi[1::2])
                self.lo[half:], self.hi[half:] = np.inf, -np.inf
                self.block *= 2
            room = min(len(x) - i, self.cap * self.block - self.n)
            seg = x[i : i + room]
            good = np.isfinite(seg)
            blk, starts = _blocks(self.n, len(seg), self.block)
            self.lo[blk] = np.fmin(self.lo[blk], np.minimum.reduceat(np.where(good, seg, np.inf), starts))
            self.hi[blk] = np.fmax(self.hi[blk], np.maximum.reduceat(np.where(good, seg, -np.inf), starts))
            self.n += len(seg)
            i += room

    def tail_range(self, start: int) -> float | None:
        """max - min from sample `start` on (from the start of its bucket); None if nothing finite."""
        b = start // self.block
        nb = (self.n + self.block - 1) // self.block
        lo, hi = self.lo[b:nb], self.hi[b:nb]
        if not np.isfinite(lo).any():
            return None
        return float(np.max(hi[np.isfinite(hi)]) - np.min(lo[np.isfinite(lo)]))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(first period of each bucket, min, max); empty buckets are NaN."""
        nb = (self.n + self.block - 1) // self.block
        lo, hi = self.lo[:nb].copy(), self.hi[:nb].copy()
        lo[~np.isfinite(lo)] = np.nan
        hi[~np.isfinite(hi)] = np.nan
        return np.arange(nb) * self.block, lo, hi
