"""`bench perf --only realtime`: the plant's real-time timing in direct real time, beside cyclictest.

For each period Ts (default 100 us and 55 us), in one command and one after the other:

* `cyclictest` (Debian's rt-tests) at the same interval and priority as the plant: one thread, SCHED_FIFO 80,
  mlockall, absolute clock_nanosleep deadlines, as many loops as the bench has periods; its histogram
  (1 us bins, `--histfile`) gives p50 / p99 / p99.9 and its own min / mean / max;
* the whole `bench run scenarios/you2019_step.toml --bus direct --no-viewer --set scenario.timing=realtime
  --set drive.Ts_s=TS --set scenario.periods=N` process, as a user runs it; its summary.json "realtime"
  (the plant's record 0x2007 read at the end of the run, and the bus-side view from the frames' stamps)
  gives the SYNC lateness (the quantity cyclictest measures: wake-up minus absolute deadline), the
  controller's turnaround and the overruns.

The issue's targets (reported, never asserted): the plant's lateness p99 within 1.5x of cyclictest's p99 at
the same interval; 0 overruns at Ts = 100 us over 10^6 periods whenever cyclictest's max stays below the
period. `--realtime-burners N` runs both under N busy loops (killed by their pid at the end)."""

from __future__ import annotations

import contextlib
import json
import math
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from bench.paths import REPO
from bench.tools.perf.common import REALTIME_PERIODS, REALTIME_QUICK_PERIODS, REALTIME_TS_US, measure
from bench.tools.perf.pipeline import bench_command

SCENARIO = REPO / "scenarios" / "you2019_step.toml"
PRIORITY = 80  # plant_node's SCHED_FIFO priority (plant_rt/node/plant_node_main.c)
HIST_LIMIT_US = 20_000  # cyclictest's histogram range; its max is exact beyond it
DEFAULT_PERIODS = REALTIME_PERIODS
QUICK_PERIODS = REALTIME_QUICK_PERIODS
DEFAULT_TS_US = REALTIME_TS_US
TARGET_P99_RATIO = 1.5
TARGET_OVERRUN_TS_US = 100.0
BURNER = "while :; do :; done"
MISSING = "bench perf: the realtime section needs cyclictest (Debian's rt-tests): apt-get install rt-tests"
QUANTILES = (("p50", 0.5), ("p99", 0.99), ("p99_9", 0.999))
STATS = ("min", "mean", "p50", "p99", "p99_9", "max")


@dataclass
class RtSizes:
    periods: int = DEFAULT_PERIODS
    ts_us: tuple[float, ...] = DEFAULT_TS_US
    burners: int = 0


def have_cyclictest() -> bool:
    return shutil.which("cyclictest") is not None


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
        "histogram_us": {str(us): n for us, n in sorted(h["bins"].items())},  # bin b: [b, b+1) us
        "wall_s": m.wall_s,
        "notes": [ln.strip() for ln in (m.stdout + m.stderr).splitlines() if ln.strip()][:4],
    }


# ---------------------------------------------------------------- the bench


def bench_argv(ts_us: float, periods: int, out: Path) -> list[str]:
    return [
        *bench_command(),
        "run",
        str(SCENARIO.relative_to(REPO)),
        "--bus",
        "direct",
        "--no-viewer",
        "--set",
        "scenario.timing=realtime",
        "--set",
        f"drive.Ts_s={ts_us * 1e-6:g}",
        "--set",
        f"scenario.periods={periods}",
        "--out",
        str(out),
    ]


def _six(src: dict[str, Any], prefix: str) -> dict[str, float | None]:
    """The six statistics of one quantity of the plant record ('sync_lateness' -> min .. max)."""
    return {k: src.get(f"{prefix}_{k}_us") for k in STATS}


def bench_realtime(ts_us: float, periods: int, work: Path) -> dict[str, Any]:
    """One whole `bench run` in direct real time; its summary's "realtime" (all of it kept in the JSON)."""
    out = work / f"rt_{ts_us:g}us"
    argv = bench_argv(ts_us, periods, out)
    m = measure(argv, timeout=3 * periods * ts_us * 1e-6 + 900, cwd=REPO)
    text = m.stdout + m.stderr
    notes = [ln.strip() for ln in text.splitlines() if "SCHED_FIFO" in ln or "mlockall" in ln or "real time" in ln]
    summary_file = out / "summary.json"
    if not summary_file.exists():
        tail = " | ".join(text.strip().splitlines()[-3:])
        for d in (out, out.with_name(out.name + ".failed")):  # a failed run keeps what it recorded there
            shutil.rmtree(d, ignore_errors=True)
        raise RuntimeError(f"bench run (status {m.returncode}) wrote no summary.json: {tail}")
    summary = json.loads(summary_file.read_text())
    shutil.rmtree(out, ignore_errors=True)  # hundreds of MB at 10^6 periods: the figures are kept
    rt = summary.get("realtime")
    if not isinstance(rt, dict) or not isinstance(rt.get("plant"), dict):
        raise RuntimeError(f"bench run (status {m.returncode}, {summary.get('status')}): no 'realtime' in summary.json")
    plant = rt["plant"]
    return {
        "command": " ".join(["bench", *argv[len(bench_command()) :]]).replace(str(out), "DIR"),
        "exit_status": m.returncode,
        "status": summary.get("status"),
        "periods": summary.get("periods"),
        "wall_s": m.wall_s,
        "peak_rss_kB": m.peak_rss_kB,
        "lateness_us": _six(plant, "sync_lateness"),
        "turnaround_us": _six(plant, "turnaround"),
        "counts": {
            k: plant.get(k)
            for k in ("periods", "commands_timed", "overruns", "sync_overruns", "missed_commands", "late_commands")
        },
        "worst_period": plant.get("worst_period"),
        "bus": rt.get("bus"),
        "realtime": rt,
        "notes": notes[:4],
    }


# ---------------------------------------------------------------- side by side


@contextlib.contextmanager
def burners(n: int) -> Iterator[list[int]]:
    """n busy loops (bash), each in its own session; killed by their pid on the way out."""
    procs = [
        subprocess.Popen(
            ["bash", "-c", BURNER],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        for _ in range(n)
    ]
    try:
        yield [p.pid for p in procs]
    finally:
        for p in procs:
            p.kill()
            p.wait()


def _ratio(a: float | None, b: float | None) -> float | None:
    return a / b if a is not None and b is not None and b > 0 else None


def compare(ts_us: float, bench: dict[str, Any], ct: dict[str, Any], periods: int = DEFAULT_PERIODS) -> dict[str, Any]:
    """Ratios bench / cyclictest and the issue's two targets (None: not judged; the overrun target is over 10^6
    periods at Ts = 100 us, when cyclictest's max stays below the period)."""
    if "error" in bench or "error" in ct:
        return {"p99_ratio": None, "max_ratio": None, "p99_target_met": None, "overrun_target_met": None}
    b, c = bench["lateness_us"], ct["lateness_us"]
    p99 = _ratio(b.get("p99"), c.get("p99"))
    overruns = bench["counts"].get("overruns")
    judged = (
        ts_us == TARGET_OVERRUN_TS_US and periods >= DEFAULT_PERIODS and c.get("max") is not None and c["max"] < ts_us
    )
    return {
        "p99_ratio": p99,
        "max_ratio": _ratio(b.get("max"), c.get("max")),
        "p99_target_met": None if p99 is None else p99 <= TARGET_P99_RATIO,
        "overrun_target_met": (overruns == 0) if judged and overruns is not None else None,
        "overrun_target_note": _overrun_note(ts_us, periods, judged, c.get("max")),
    }


def _overrun_note(ts_us: float, periods: int, judged: bool, ct_max: float | None) -> str | None:
    if ts_us != TARGET_OVERRUN_TS_US:
        return f"the target is at Ts = {TARGET_OVERRUN_TS_US:g} us"
    if periods < DEFAULT_PERIODS:
        return f"the target is over {DEFAULT_PERIODS:,} periods, this run {periods:,}"
    if judged:
        return None
    return "cyclictest gave no max" if ct_max is None else f"cyclictest's max {ct_max:g} us >= the period"


def _part(fn: Any, *a: Any) -> dict[str, Any]:
    try:
        return dict(fn(*a))
    except Exception as exc:  # noqa: BLE001 - reported in the section, the other side still runs
        return {"error": f"{type(exc).__name__}: {exc}"}


def realtime(sizes: RtSizes, note: Any = None, work: Path | None = None) -> dict[str, Any]:
    """The section: for each Ts, cyclictest then the bench, under sizes.burners busy loops."""
    if not have_cyclictest():
        return {"error": MISSING}
    say = note or (lambda _msg: None)
    rows: dict[str, Any] = {}
    with burners(sizes.burners) as pids, tempfile.TemporaryDirectory(prefix="bench-perf-rt-", dir=work) as td:
        for ts in sizes.ts_us:
            say(f"realtime: cyclictest at {ts:g} us, {sizes.periods:,} loops")
            ct = _part(run_cyclictest, ts, sizes.periods)
            say(f"realtime: bench run in direct real time at Ts = {ts:g} us, {sizes.periods:,} periods")
            bench = _part(bench_realtime, ts, sizes.periods, Path(td))
            rows[f"{ts:g}"] = {
                "ts_us": ts,
                "cyclictest": ct,
                "bench": bench,
                "compare": compare(ts, bench, ct, sizes.periods),
            }
    errors = [
        f"Ts {k} us, {side}: {r[side]['error']}"
        for k, r in rows.items()
        for side in ("cyclictest", "bench")
        if "error" in r[side]
    ]
    return {
        "sizes": asdict(sizes),
        "load": f"{sizes.burners} busy loop(s) `{BURNER}`" if sizes.burners else "idle",
        "burner_pids": pids,
        "scenario": str(SCENARIO.relative_to(REPO)),
        "priority": PRIORITY,
        "targets": {"p99_ratio_le": TARGET_P99_RATIO, "overruns_at_ts_us": TARGET_OVERRUN_TS_US},
        "runs": rows,
        **({"errors": errors} if errors else {}),
    }
