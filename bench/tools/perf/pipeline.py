"""What the user waits for, side by side in one run: whole `bench run` processes (the 1 s scenario
and 10^6 periods with every output), the Python API with the outputs a sweep needs (10^6 and
10^7 periods) against the loop's own rate, the VM live view's cost per update, and the peer
(gym-electric-motor on the same 1 s scenario). Every child runs in a fresh process, so each
peak RSS is that run's own (wait4)."""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from bench.paths import REPO
from bench.tools.perf.common import measure, stats

SCENARIO = REPO / "scenarios" / "you2019_step.toml"
ONE_SECOND_PERIODS = 18_182  # 1.0 s of You 2019's Ts = 55 us


def _target(label: str, unit: str, target: float, le: bool, was: float | None, what: str) -> dict[str, Any]:
    return {"label": label, "unit": unit, "target": target, "le": le, "was": was, "what": what}


# Targets (docs/BENCHMARKS.md; reported, never asserted). "was": before the run pipeline's rewrite.
TARGETS: dict[str, dict[str, Any]] = {
    "one_second_wall_s": _target(
        "1 s scenario, whole process, median",
        "s",
        1.5,
        True,
        6.0,
        "1 s scenario (18,182 periods), whole `bench run --bus direct --no-viewer` process, median wall s",
    ),
    "whole_1e6_wall_s": _target(
        "10^6 periods, whole process, all outputs",
        "s",
        5.0,
        True,
        41.0,
        "10^6 periods, whole `bench run` process with traces, summary, plots, .rrd and CAN log, wall s",
    ),
    "whole_1e6_peak_rss_MB": _target(
        "peak RSS, 10^6, whole process",
        "MB",
        400.0,
        True,
        1100.0,
        "10^6 periods, whole `bench run` process, peak RSS MB",
    ),
    "api_over_loop": _target(
        "API 10^6 (summary+traces) / loop rate",
        "x",
        0.5,
        False,
        0.022,
        "10^6 periods via run_scenario with summary + traces.npy, periods/s / the loop's own periods/s",
    ),
    "api_over_gem": _target(
        "API 10^6 periods/s / gym-electric-motor",
        "x",
        100.0,
        False,
        5.9,
        "10^6 periods via run_scenario, periods/s / gym-electric-motor's periods/s (its loop, same 1 s scenario)",
    ),
    "api_rss_1e7_over_1e6": _target(
        "peak RSS 10^7 / 10^6 (API)",
        "x",
        1.02,
        True,
        None,
        "peak RSS of run_scenario at 10^7 periods / at 10^6 ('no larger'; 2% measurement slack)",
    ),
    "live_update_growth": _target(
        "VM live view: late / early update",
        "x",
        1.5,
        True,
        None,
        "VM live view: median update late in a run / early in it (O(new periods) per update: ~1)",
    ),
}


@dataclass
class Sizes:
    one_second_periods: int = ONE_SECOND_PERIODS
    repetitions: int = 5  # whole-process runs of the 1 s scenario (and up to 3 of the peer)
    whole_periods: int = 1_000_000  # whole process, every output
    api_periods: tuple[int, ...] = (1_000_000, 10_000_000)
    loop_periods: int = 1_000_000
    live_periods_per_update: int = 1_000
    peers: bool = True

    @classmethod
    def quick(cls) -> Sizes:
        return cls(repetitions=1, whole_periods=100_000, api_periods=(100_000,), loop_periods=100_000, peers=False)


def bench_command() -> list[str]:
    exe = Path(sys.executable).with_name("bench")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "bench.cli"]


def _bytes(folder: Path) -> dict[str, int]:
    return {p.name: p.stat().st_size for p in sorted(folder.iterdir()) if p.is_file()}


def whole_run(periods: int, out: Path, extra: tuple[str, ...] = ()) -> dict[str, Any]:
    """One `bench run ... --bus direct --no-viewer [extra]` process to its end (fresh out folder)."""
    argv = [
        *bench_command(),
        "run",
        str(SCENARIO),
        "--bus",
        "direct",
        "--no-viewer",
        "--set",
        f"scenario.periods={periods}",
        *extra,
        "--out",
        str(out),
    ]
    m = measure(argv, timeout=1800, cwd=REPO).check(f"bench run ({periods} periods)")
    summary = json.loads((out / "summary.json").read_text())
    return {
        "wall_s": m.wall_s,
        "peak_rss_kB": m.peak_rss_kB,
        "status": summary["status"],
        "periods": summary["periods"],
        "loop_run_wall_s": summary.get("timing", {}).get("run_wall_s"),
        "bytes": _bytes(out),
    }


def whole_runs(periods: int, reps: int, tmp: Path, keep_last: bool = False) -> dict[str, Any]:
    runs = []
    for k in range(reps):
        out = tmp / f"run-{periods}-{k}"
        runs.append(whole_run(periods, out))
        if not (keep_last and k == reps - 1):
            shutil.rmtree(out, ignore_errors=True)
    walls = [r["wall_s"] for r in runs]
    return {
        "periods": periods,
        "repetitions": reps,
        "wall_s": stats(walls),
        "peak_rss_kB": max(r["peak_rss_kB"] for r in runs),
        "status": runs[-1]["status"],
        "loop_run_wall_s": runs[-1]["loop_run_wall_s"],
        "bytes": runs[-1]["bytes"],
        "total_bytes": sum(runs[-1]["bytes"].values()),
        "periods_per_s_whole_process": periods / stats(walls)["median"],
        "command": f"bench run {SCENARIO.relative_to(REPO)} --bus direct --no-viewer "
        f"--set scenario.periods={periods} --out TMP",
    }


def _child(mode: str, periods: int, folder: Path | None = None) -> dict[str, Any]:
    argv = [sys.executable, "-m", "bench.tools.perf.child", mode, "--periods", str(periods)]
    if folder is not None:
        argv += ["--dir", str(folder)]
    m = measure(argv, timeout=3600, cwd=REPO).check(f"perf child {mode} ({periods} periods)")
    out = json.loads(m.stdout.strip().splitlines()[-1])
    out["process_wall_s"] = m.wall_s
    out["peak_rss_kB"] = m.peak_rss_kB
    return out


def api_runs(sizes: Sizes, tmp: Path, loop_rate: float | None) -> dict[str, Any]:
    res: dict[str, Any] = {}
    for n in sizes.api_periods:
        folder = tmp / f"api-{n}"
        r = _child("api", n, folder)
        shutil.rmtree(folder, ignore_errors=True)
        if loop_rate:
            r["over_loop"] = r["periods_per_s"] / loop_rate
        res[str(n)] = r
    return res


def _rss_ratio(api: dict[str, Any]) -> dict[str, Any] | None:
    if "1000000" in api and "10000000" in api:
        a, b = api["1000000"]["peak_rss_kB"], api["10000000"]["peak_rss_kB"]
        return {"rss_1e6_kB": a, "rss_1e7_kB": b, "ratio": b / a}
    return None


def pipeline(
    sizes: Sizes | None = None, work: Path | None = None, note: Callable[[str], None] | None = None
) -> dict[str, Any]:
    """The section. `work`: where the runs write (a temporary folder, removed, by default)."""
    from bench.tools.perf.live import live_follow
    from bench.tools.perf.peers import gem

    sizes = sizes or Sizes()
    say = note or (lambda msg: None)
    tmp = Path(tempfile.mkdtemp(prefix="bench-perf-pipeline-", dir=work))
    res: dict[str, Any] = {
        "sizes": {**asdict(sizes), "api_periods": list(sizes.api_periods)},
        "scenario": str(SCENARIO.relative_to(REPO)),
    }
    errors: dict[str, str] = {}

    def part(name: str, what: str, fn: Callable[[], Any]) -> Any:
        """One measurement; a failure is kept in its place and the others still run."""
        say(f"pipeline: {what}")
        try:
            res[name] = fn()
        except Exception as exc:  # noqa: BLE001 - reported in the section
            res[name] = {"error": f"{type(exc).__name__}: {exc}"}
            errors[name] = res[name]["error"]
        return res[name]

    try:
        part(
            "one_second",
            f"1 s scenario, whole process x{sizes.repetitions}",
            lambda: whole_runs(sizes.one_second_periods, sizes.repetitions, tmp),
        )
        part(
            "whole",
            f"{sizes.whole_periods:,} periods, whole process, every output",
            lambda: whole_runs(sizes.whole_periods, 1, tmp, keep_last=True),
        )
        log = tmp / f"run-{sizes.whole_periods}-0" / "bus.log"
        part(
            "live_follow",
            "VM live view cost per update (following that run's log)",
            lambda: live_follow(log, sizes.live_periods_per_update, sizes.whole_periods),
        )
        shutil.rmtree(log.parent, ignore_errors=True)
        loop = part(
            "loop", f"the loop alone, {sizes.loop_periods:,} periods", lambda: _child("loop", sizes.loop_periods)
        )
        loop_rate = loop["loop"]["periods_per_s"] if "loop" in loop else None
        api = part(
            "api",
            f"run_scenario with summary + traces, {', '.join(f'{n:,}' for n in sizes.api_periods)} periods",
            lambda: api_runs(sizes, tmp, loop_rate),
        )
        res["api_rss_growth"] = _rss_ratio(api)
        if sizes.peers:
            part("gem", "gym-electric-motor on the 1 s scenario", lambda: gem(min(sizes.repetitions, 3), say))
        else:
            res["gem"] = {"skipped": "no peers (--quick)"}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    g, one = res["gem"], res.get("one_second", {})
    if "wall_s" in g and "wall_s" in one:
        res["one_second_gem_over_bench"] = g["wall_s"]["median"] / one["wall_s"]["median"]
    a6 = (api.get("1000000") or next(iter(api.values()), None)) if "error" not in api else None
    res["api_over_gem"] = a6["periods_per_s"] / g["sim_periods_per_s"] if a6 and g.get("sim_periods_per_s") else None
    res["targets"] = target_rows(res)
    if errors:
        res["errors"] = errors
    return res


def _row(key: str, measured: float | None, note: str = "") -> dict[str, Any]:
    t = TARGETS[key]
    met = None
    if measured is not None:
        met = measured <= t["target"] if t["le"] else measured >= t["target"]
    return {
        "key": key,
        "label": t["label"],
        "unit": t["unit"],
        "what": t["what"],
        "target": t["target"],
        "op": "<=" if t["le"] else ">=",
        "measured": measured,
        "ratio": None if measured is None else measured / t["target"],
        "was": t["was"],
        "met": met,
        "note": note,
    }


def target_rows(res: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per target: measured, measured/target, met (None when not measured in this run)."""
    sizes = res["sizes"]
    full = sizes["whole_periods"] == 1_000_000
    size_note = "" if full else f"measured at {sizes['whole_periods']:,} periods, not 10^6"
    rows = []
    one = res.get("one_second", {})
    one_ok = sizes["one_second_periods"] == ONE_SECOND_PERIODS
    rows.append(
        _row(
            "one_second_wall_s",
            one.get("wall_s", {}).get("median") if one_ok else None,
            "" if one_ok else f"{sizes['one_second_periods']} periods, not 18,182",
        )
    )
    whole = res.get("whole", {})
    rows.append(_row("whole_1e6_wall_s", whole.get("wall_s", {}).get("median") if full else None, size_note))
    rss = whole.get("peak_rss_kB")
    rows.append(_row("whole_1e6_peak_rss_MB", rss / 1024 if full and rss else None, size_note))
    api = res.get("api", {})
    api_full = "1000000" in api
    a6 = api.get("1000000") or (next((v for k, v in api.items() if k != "error"), None))
    off = f"at {a6['periods']:,} periods" if a6 and not api_full else ""
    rows.append(
        _row(
            "api_over_loop",
            a6.get("over_loop") if a6 and api_full else None,
            f"{off}: {a6['over_loop']:.3f}" if off and a6 and a6.get("over_loop") else "",
        )
    )
    gem = res.get("gem") or {}
    ratio = res.get("api_over_gem")
    why = gem.get("skipped") or gem.get("unavailable") or gem.get("error") or ""
    rows.append(
        _row("api_over_gem", ratio if api_full else None, why or (f"{off}: {ratio:.3g}x" if off and ratio else ""))
    )
    g = res.get("api_rss_growth")
    rows.append(_row("api_rss_1e7_over_1e6", g["ratio"] if g else None, "" if g else "10^7 not run"))
    lf = res.get("live_follow") or {}
    rows.append(_row("live_update_growth", lf.get("late_over_early")))
    return rows
