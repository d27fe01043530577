"""cyclictest (Debian's rt-tests), the host's floor beside the bench's real time (`bench perf --only realtime`):
one measurement thread at the plant's priority, on the plant's CPU, with mlockall and absolute deadlines; its 1 us
histogram read into the plant's quantile convention (0x2007)."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import Any

from bench.tools.perf.common import measure

PRIORITY = 80  # plant_node's SCHED_FIFO priority (plant_rt/node/plant_node_main.c)
HIST_LIMIT_US = 20_000  # cyclictest's histogram range; its max is exact beyond it
QUANTILES = (("p50", 0.5), ("p99", 0.99), ("p99_9", 0.999))


def plant_cpu() -> int:
    """The CPU the plant takes: the first one this process may use (plant_pacing_default_cpu)."""
    return min(os.sched_getaffinity(0))


# ---------------------------------------------------------------- cyclictest


def cyclictest_argv(interval_us: int, loops: int, histfile: Path) -> list[str]:
    """One measurement thread (-t 1) at SCHED_FIFO PRIORITY with mlockall, absolute deadlines (the default),
    `loops` wake-ups every interval_us; the 1 us histogram up to HIST_LIMIT_US in histfile, a summary only."""
    return [
        "cyclictest",
        "-m",
        "-t",
        "1",
        "-p",
        str(PRIORITY),
        "--policy=fifo",
        "-a",
        str(plant_cpu()),
        "-i",
        str(interval_us),
        "-l",
        str(loops),
        "-h",
        str(HIST_LIMIT_US),
        f"--histfile={histfile}",
        "-q",
    ]


def parse_histogram(text: str) -> dict[str, Any]:
    """cyclictest's histogram file (one thread): 'US COUNT' lines and '# Key: value' lines."""
    bins: dict[int, int] = {}
    head: dict[str, str] = {}
    for line in text.splitlines():
        if line.startswith("#"):
            key, sep, val = line[1:].partition(":")
            if sep:
                head[key.strip()] = val.strip()
            continue
        parts = line.split()
        if len(parts) >= 2 and parts[0].isdigit():
            count = int(parts[1])
            if count:
                bins[int(parts[0])] = count

    def first_int(key: str) -> int | None:
        vals = head.get(key, "").split()
        return int(vals[0]) if vals and vals[0].lstrip("-").isdigit() else None

    total, overflows = first_int("Total"), first_int("Histogram Overflows") or 0
    if total is None:
        raise ValueError("no '# Total:' line in cyclictest's histogram")
    return {
        "total": total,
        "overflows": overflows,
        "min": first_int("Min Latencies"),
        "mean": first_int("Avg Latencies"),
        "max": first_int("Max Latencies"),
        "bins": bins,
    }


def quantiles(bins: dict[int, int], total: int, largest: float | None = None) -> dict[str, float | None]:
    """p50 / p99 / p99.9 of cyclictest's 1 us histogram, in the plant's convention (0x2007): the upper edge of
    the quantile's bin (cyclictest's bin b holds [b, b+1) us, whole us cut off), at most the largest value;
    None when the quantile falls beyond the histogram (in its overflows)."""
    out: dict[str, float | None] = {}
    for name, q in QUANTILES:
        need = max(1, math.ceil(q * total))
        acc, value = 0, None
        for us in sorted(bins):
            acc += bins[us]
            if acc >= need:
                value = float(us + 1) if largest is None else min(float(us + 1), float(largest))
                break
        out[name] = value
    return out


def run_cyclictest(interval_us: float, loops: int) -> dict[str, Any]:
    """cyclictest to its end (timeout: twice its nominal duration + 60 s); latencies in us."""
    iv = int(round(interval_us))
    with tempfile.TemporaryDirectory(prefix="bench-perf-rt-") as td:
        hist = Path(td) / "hist.txt"
        argv = cyclictest_argv(iv, loops, hist)
        m = measure(argv, timeout=2 * loops * iv * 1e-6 + 60).check("cyclictest")
        h = parse_histogram(hist.read_text())
    lat = {"min": h["min"], "mean": h["mean"], **quantiles(h["bins"], h["total"], h["max"]), "max": h["max"]}
    return {
        "command": " ".join(a if "histfile" not in a else "--histfile=FILE" for a in argv),
        "interval_us": iv,
        "loops": h["total"],
        "lateness_us": {k: (None if v is None else float(v)) for k, v in lat.items()},
        "histogram_limit_us": HIST_LIMIT_US,
        "overflows": h["overflows"],
        # wake-ups a whole period or more late: what the plant counts as sync_overruns
        "over_period": sum(n for us, n in h["bins"].items() if us >= iv) + h["overflows"],
        # the periods those wake-ups passed: cyclictest skips the deadlines a stall passed (a 50 ms stall at 1 ms is
        # one late wake-up), the plant counts each period without its command; an overflow spans at most the max
        "over_period_periods": missed_periods(h["bins"], h["overflows"], h["max"], iv),
        "histogram_us": {str(us): n for us, n in sorted(h["bins"].items())},  # bin b: [b, b+1) us
        "wall_s": m.wall_s,
        "notes": [ln.strip() for ln in (m.stdout + m.stderr).splitlines() if ln.strip()][:4],
    }


def missed_periods(bins: dict[int, int], overflows: int, largest: int | None, interval_us: int) -> int:
    """The deadlines cyclictest's late wake-ups passed: a wake-up late by L us passed floor(L / interval) of them
    (cyclictest then sleeps to the next deadline still ahead); the overflows (beyond the histogram) at most the
    largest latency's each."""
    n = sum(c * (us // interval_us) for us, c in bins.items() if us >= interval_us)
    return n + overflows * ((largest or 0) // interval_us)
