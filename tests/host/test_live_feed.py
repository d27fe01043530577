"""The live viewer's stream (bench/view/live_feed.py): the min/max envelope keeps every bucket's extremes at their own
periods, its bucket follows the rate rows come at, and a viewer that falls behind loses live rows (counted) without
holding up the caller; the recording is the caller's and is not touched here (tests/host/test_rerun_sink.py)."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.view.live_feed import QUEUE_CHUNKS, LiveFeed, envelope_index


@pytest.mark.parametrize("n, bucket", [(1000, 1), (1000, 10), (1003, 10), (7, 3), (2, 50), (999, 1000)])
def test_the_envelope_keeps_each_buckets_smallest_and_largest_value(n: int, bucket: int) -> None:
    rng = np.random.default_rng(n + bucket)
    values = rng.normal(size=n)
    values[n // 2] = 40.0  # a one-period spike: every Nth period would miss it
    rows = envelope_index(values, bucket)
    assert np.all(np.diff(rows) > 0), "in row order, each row once"
    if bucket == 1 or n <= 2:
        np.testing.assert_array_equal(rows, np.arange(n))
        return
    kept = set(rows.tolist())
    for start in range(0, n, bucket):
        block = values[start : start + bucket]
        assert start + int(block.argmin()) in kept and start + int(block.argmax()) in kept, start
        assert len(kept & set(range(start, start + len(block)))) <= 2
    assert n // 2 in kept


def test_a_bucket_with_a_nan_keeps_the_gap() -> None:
    values = np.arange(20, dtype=np.float64)
    values[13] = np.nan
    rows = envelope_index(values, 10)
    assert 13 in rows.tolist() and np.isnan(values[rows]).sum() == 1
    assert {0, 9} <= set(rows.tolist())  # the bucket without NaN keeps its extremes


class FakeStream:
    """A live recording stream whose viewer takes nothing until `release` is set (rerun's full channel)."""

    def __init__(self) -> None:
        self.entered, self.release = threading.Event(), threading.Event()
        self.rows = 0

    def send_columns(self, path: str, indexes: Any, columns: Any) -> None:
        self.entered.set()
        self.release.wait()
        self.rows += len(indexes[0].times) if hasattr(indexes[0], "times") else 0


def _clock(step: float) -> Any:
    """Arrival times of the chunks: `step` seconds apart."""
    times = iter(np.arange(step, 1e4, step))  # the first chunk `step` after the feed began (at 0)
    return lambda: float(next(times))


def _chunk(n: int, first: int) -> tuple[list[tuple[str, np.ndarray]], np.ndarray, np.ndarray]:
    period = np.arange(first, first + n, dtype=np.int64)
    return [("/A/iq_A", np.sin(period * 0.01)), ("/V/vq_V", np.cos(period * 0.01))], period, period * 55e-6


def test_a_viewer_that_falls_behind_loses_live_rows_and_never_holds_up_the_caller() -> None:
    stream = FakeStream()
    safety = threading.Timer(60.0, stream.release.set)  # a put that blocked would hang the test: then it fails
    safety.start()
    feed = LiveFeed(stream, decimate=None)  # type: ignore[arg-type]
    feed._clock = _clock(0.125)  # a chunk of 1,000 rows each 0.125 s: 8,000 rows/s
    feed._last = 0.0
    feed.put(*_chunk(1000, 0), seen=0)
    assert stream.entered.wait(30.0), "the sending thread sent the first chunk"  # and is stuck in the viewer
    chunks = 3 * QUEUE_CHUNKS
    for k in range(1, chunks + 1):  # QUEUE_CHUNKS wait for the thread, the rest are dropped
        feed.put(*_chunk(1000, 1000 * k), seen=1000 * k)
    stats = feed.stats()
    assert not stream.release.is_set(), "no put waited for the viewer"
    assert stats["periods"] == 1000 * (chunks + 1)
    assert stats["periods_dropped"] == 1000 * (chunks - QUEUE_CHUNKS)
    assert stats["mode"] == "envelope" and stats["buckets"] == [8, 8]  # 8,000 rows/s: buckets of 8
    # an envelope of 125 buckets of 8 rows: at most 250 points of a signal a chunk
    assert stats["points_sent"] <= 2 * 250 * (1 + QUEUE_CHUNKS)
    stream.release.set()
    feed.close()
    safety.cancel()


def test_every_nth_period_when_asked() -> None:
    stream = FakeStream()
    stream.release.set()
    feed = LiveFeed(stream, decimate=7)  # type: ignore[arg-type]
    rows = []
    seen = 0
    for n in (3, 250, 1, 746):
        cols, period, t_s = _chunk(n, seen)
        item = feed._thin(cols, period, t_s, seen, None)
        rows += item[0][2].tolist()
        seen += n
    assert rows == list(range(0, 1000, 7))
    feed.close()
    assert feed.stats()["mode"] == "every_nth" and feed.stats()["decimate"] == 7


def test_the_live_recording_of_a_run_is_its_envelope_and_the_file_has_every_period(tmp_path: Path) -> None:
    """Through RerunSink as a run drives it: the live stream (a memory recording standing in for the viewer) gets
    each bucket's extremes at their own periods, run.rrd every period."""
    import rerun as rr
    from rrd_util import read_recording

    from bench.signals import SignalInfo
    from bench.view import rerun_sink

    n = 4000
    period = np.arange(n, dtype=np.int64)
    iq = np.sin(period * 0.003)
    iq[2501] = 9.0  # one period's spike
    sink = rerun_sink.RerunSink("envelope", tmp_path / "full.rrd")
    live = rr.RecordingStream(rerun_sink.APPLICATION_ID, recording_id="envelope")
    memory = live.memory_recording()
    sink.live = live
    sink.begin([SignalInfo.of("iq_A", "x")])
    assert sink.feed is not None
    sink.feed._clock = _clock(0.125)  # 1,000 rows each 0.125 s: buckets of 8
    sink.feed._last = 0.0
    for a in range(0, n, 1000):
        sink.write({"period": period[a : a + 1000], "t_s": period[a : a + 1000] * 1e-4, "iq_A": iq[a : a + 1000]})
    sink.end()
    stats = sink.live_stats()
    (tmp_path / "live.rrd").write_bytes(memory.drain_as_bytes())
    sink.close()
    full, thin = read_recording(tmp_path / "full.rrd")["/A/iq_A"], read_recording(tmp_path / "live.rrd")["/A/iq_A"]
    np.testing.assert_array_equal(full["period"], period)
    rows = envelope_index(iq[:1000], 8)
    expected = np.concatenate([a + envelope_index(iq[a : a + 1000], 8) for a in range(0, n, 1000)])
    np.testing.assert_array_equal(thin["period"], expected)
    np.testing.assert_array_equal(thin["value"], iq[expected])
    assert 2501 in thin["period"].tolist() and len(rows) <= 250
    assert stats == {
        "mode": "envelope",
        "periods": n,
        "periods_dropped": 0,
        "buckets": [8, 8],
        "points_sent": len(expected),
    }
