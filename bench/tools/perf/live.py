"""The views' costs: Rerun's live buffer for 10^6 periods x 16 signals (what a viewer is served
from), and the VM live view's cost per update: `bench run` over the VM follows candump's log as it
grows (bench.run.record.sources.LogFollower -> Pipeline -> sinks); each update must cost O(new periods),
never O(periods so far)."""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.tools.perf.common import run

_RERUN_CHILD = r"""
import json, resource, sys, time
import numpy as np
import rerun as rr
periods, signals, batch, decimate = (int(a) for a in sys.argv[1:5])
limit = sys.argv[5]
def rss_kB():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4
rec = rr.RecordingStream("bench-perf-live", recording_id="live")
rec.serve_grpc(server_memory_limit=limit)   # the buffer a live viewer is served from
before = rss_kB()
t0 = time.monotonic()
k = np.arange(periods, dtype=np.int64)
sent = 0
for a in range(0, periods, batch):
    sl = slice(a, min(periods, a + batch), decimate)
    times = [rr.TimeColumn("period", sequence=k[sl])]
    for s in range(signals):
        rec.send_columns(f"/sig/{s}", indexes=times, columns=rr.Scalars.columns(scalars=np.sin(k[sl] * 1e-3 * (s + 1))))
    sent += len(k[sl])
rec.flush()
wall = time.monotonic() - t0
print(json.dumps({"rss_before_kB": before, "rss_after_kB": rss_kB(),
                  "peak_rss_kB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "wall_s": wall, "periods_per_s": periods / wall, "samples_sent": sent * signals}))
"""


def rerun_live(periods: int = 1_000_000, signals: int = 16) -> dict[str, Any]:
    """Memory of the live-view buffer (Rerun's gRPC server, what a viewer is served from) for 10^6 periods x
    16 signals, logged with send_columns in batches, at full rate and decimated by 10, with a 1 GiB cap."""
    out = {}
    for decimate in (1, 10):
        r = run(
            [sys.executable, "-c", _RERUN_CHILD, str(periods), str(signals), "10000", str(decimate), "1GiB"],
            timeout=600,
        )
        out[f"decimate_{decimate}"] = json.loads(r.strip().splitlines()[-1])
    return {"periods": periods, "signals": signals, "server_memory_limit": "1GiB", **out}


def live_follow(log: Path, periods_per_update: int = 1000, periods: int | None = None) -> dict[str, Any]:
    """Replays a finished run's candump log as if it were growing: appends it in blocks of about
    `periods_per_update` periods (cut anywhere, mid-line too) and times each update of the VM path
    of `bench run` (LogFollower.drain -> Pipeline.feed -> traces.npy + .rrd sinks, no viewer).
    Reports the median update early in the run and late in it: equal when an update is O(new)."""
    from bench.run import LogFollower, Pipeline, TraceFileSink
    from bench.view.rerun_sink import RerunSink

    size = log.stat().st_size
    if periods is None:
        with open(log, "rb") as fh:  # SYNCs (COB-ID 080) in the first MiB give the bytes per period
            head = fh.read(1 << 20)
        lines = head.count(b"\n") or 1
        syncs = head.count(b" 080#") or 1
        periods = max(1, int(size / (len(head) / lines) / (lines / syncs)))
    block = max(4096, int(size * periods_per_update / periods))
    times: list[float] = []
    rows: list[int] = []
    with tempfile.TemporaryDirectory(prefix="bench-perf-live-") as td:
        grow = Path(td) / "candump.log"
        follower = LogFollower(grow)
        sinks = [TraceFileSink(Path(td) / "traces.npy"), RerunSink("perf-live", Path(td) / "run.rrd", live="none")]
        pipe = Pipeline(None, None, sinks)  # the EDS's node-IDs
        t_all = time.perf_counter()
        with open(log, "rb") as src, open(grow, "wb") as dst:
            while True:
                data = src.read(block)
                if not data:
                    break
                dst.write(data)
                dst.flush()
                t0 = time.perf_counter()
                pipe.feed(follower.drain())
                times.append(time.perf_counter() - t0)
                rows.append(pipe.periods)
        pipe.feed(follower.drain(final=True))
        res = pipe.finish("perf-live", "log")
        wall = time.perf_counter() - t_all
        for s in sinks:
            close = getattr(s, "close", None)
            if close:
                close()
    # Early = the second tenth of the updates: by then the follower's hold window (frames within
    # 200 ms of the newest wait for late ones; in a direct-mode log that is 3,636 periods of simulated
    # time) is full, and the first update's configuration traffic is behind. Late = the last tenth.
    n = len(times)
    tenth = max(1, n // 10)
    early = sorted(times[tenth : 2 * tenth] or times[:1])
    late = sorted(times[-tenth:])
    e, l_ = early[len(early) // 2], late[len(late) // 2]
    return {
        "log_bytes": size,
        "periods": int(res.summary["periods"]),
        "updates": n,
        "block_bytes": block,
        "early_updates": [tenth, 2 * tenth],
        "late_updates": [max(0, n - tenth), n],
        "periods_per_update": periods_per_update,
        "update_ms_early_median": e * 1e3,
        "update_ms_late_median": l_ * 1e3,
        "update_ms_max": max(times) * 1e3 if times else None,
        "late_over_early": l_ / e if e > 0 else None,
        "us_per_period_late": l_ * 1e6 / periods_per_update,
        "wall_s": wall,
        "what": "append ~periods_per_update periods of candump log, then LogFollower.drain -> Pipeline.feed "
        "-> traces.npy + run.rrd (RerunSink, no viewer), timed per update",
    }
