"""`bench perf`'s pipeline section on its smallest path: the keys of its JSON and that every
number it measured is a positive finite number. Timings are never asserted (docs/BENCHMARKS.md
quotes them from a full `bench perf` run)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import pytest

from bench.tools.perf.common import measure
from bench.tools.perf.pipeline import TARGETS, Sizes, pipeline, target_rows
from bench.tools.perf.report import format_report

TINY = Sizes(
    one_second_periods=2000,
    repetitions=1,
    whole_periods=2000,
    api_periods=(2000,),
    loop_periods=2000,
    live_periods_per_update=200,
    peers=False,
)


def positive(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def test_pipeline_section_smallest_path(tmp_path: Path) -> None:
    res = pipeline(TINY, work=tmp_path)
    json.dumps(res)  # the section is JSON as it stands
    assert {
        "sizes",
        "scenario",
        "one_second",
        "whole",
        "live_follow",
        "loop",
        "api",
        "api_rss_growth",
        "gem",
        "targets",
    } <= res.keys()
    assert list(tmp_path.iterdir()) == []  # every run's folder removed

    for key in ("one_second", "whole"):
        w = res[key]
        assert w["periods"] == 2000 and w["status"] == "ok" and w["repetitions"] == 1
        assert all(positive(w["wall_s"][k]) for k in ("min", "median", "max"))
        assert w["wall_s"]["min"] <= w["wall_s"]["median"] <= w["wall_s"]["max"]
        assert positive(w["peak_rss_kB"]) and positive(w["periods_per_s_whole_process"])
        assert {"bus.log", "traces.npy", "summary.json", "run.rrd"} <= w["bytes"].keys()
        assert all(positive(b) for b in w["bytes"].values())

    loop = res["loop"]
    for part in ("loop", "loop_recorded"):
        assert loop[part]["periods"] == 2000
        assert positive(loop[part]["periods_per_s"]) and positive(loop[part]["run_wall_s"])
        assert loop[part]["plant_missed_commands"] == 0
    assert loop["loop_recorded"]["frames"] >= 4 * 2000  # SYNC, two measurements, the command, per period
    assert positive(loop["peak_rss_kB"])

    api = res["api"]["2000"]
    assert api["periods"] == 2000 and api["status"] == "ok"
    for k in (
        "api_wall_s",
        "run_wall_s",
        "periods_per_s",
        "run_periods_per_s",
        "over_loop",
        "process_wall_s",
        "peak_rss_kB",
    ):
        assert positive(api[k]), k
    assert {"traces.npy", "summary.json"} <= api["bytes"].keys()
    assert res["api_rss_growth"] is None  # no 10^7 run on this path

    lf = res["live_follow"]
    assert lf["periods"] == 2000 and lf["updates"] >= 5
    for k in ("update_ms_early_median", "update_ms_late_median", "late_over_early", "us_per_period_late"):
        assert positive(lf[k]), k

    assert res["gem"] == {"skipped": "no peers (--quick)"}
    rows = {r["key"]: r for r in res["targets"]}
    assert rows.keys() == TARGETS.keys()
    # Off the real sizes nothing is judged except the live view's growth (a ratio at any size).
    assert all(r["met"] is None for k, r in rows.items() if k != "live_update_growth")

    text = format_report({"pipeline": res, "wall_s": 1.0})
    assert "what the user waits for" in text and "verdict" in text
    assert "not judged" in text


def test_target_rows_judge_each_target_by_its_direction() -> None:
    """met/not met from given numbers (no measurement here)."""
    res = {
        "sizes": {"one_second_periods": 18_182, "whole_periods": 1_000_000, "api_periods": [1_000_000, 10_000_000]},
        "one_second": {"wall_s": {"median": 1.2}},
        "whole": {"wall_s": {"median": 6.0}, "peak_rss_kB": 300 * 1024},
        "api": {
            "1000000": {"over_loop": 0.6, "periods_per_s": 600_000.0, "peak_rss_kB": 100_000},
            "10000000": {"over_loop": 0.6, "periods_per_s": 600_000.0, "peak_rss_kB": 100_500},
        },
        "api_rss_growth": {"ratio": 1.005},
        "gem": {"sim_periods_per_s": 4000.0},
        "api_over_gem": 150.0,
        "live_follow": {"late_over_early": 1.1},
    }
    rows = {r["key"]: r for r in target_rows(res)}
    assert rows["one_second_wall_s"]["met"] is True
    assert rows["whole_1e6_wall_s"]["met"] is False and rows["whole_1e6_wall_s"]["ratio"] == pytest.approx(1.2)
    assert rows["whole_1e6_peak_rss_MB"]["met"] is True
    assert rows["api_over_loop"]["met"] is True
    assert rows["api_over_gem"]["measured"] == pytest.approx(150.0) and rows["api_over_gem"]["met"] is True
    assert rows["api_rss_1e7_over_1e6"]["met"] is True
    assert rows["live_update_growth"]["met"] is True


def test_target_rows_leave_failed_parts_unjudged() -> None:
    res = {
        "sizes": {"one_second_periods": 18_182, "whole_periods": 1_000_000, "api_periods": [1_000_000]},
        "one_second": {"error": "RuntimeError: x"},
        "whole": {"error": "RuntimeError: y"},
        "api": {"error": "RuntimeError: z"},
        "api_rss_growth": None,
        "gem": {"unavailable": "no Python 3.12"},
        "live_follow": {"error": "FileNotFoundError"},
    }
    rows = target_rows(res)
    assert all(r["met"] is None and r["measured"] is None for r in rows)
    assert {r["key"]: r for r in rows}["api_over_gem"]["note"] == "no Python 3.12"
    text = format_report({"pipeline": {**res, "targets": rows}, "wall_s": 1.0})
    assert "one_second: ERROR RuntimeError: x" in text and "no Python 3.12" in text


def test_measure_reports_the_childs_own_peak_rss() -> None:
    """A child that touches ~64 MB reports at least that; a small one after it reports less, and
    less than this (pytest) process's own mark, which a child spawned straight from here would
    inherit (RUSAGE_CHILDREN would also report the largest child so far for both)."""
    import resource

    ballast = bytearray(96 << 20)
    ballast[::4096] = b"x" * len(ballast[::4096])  # this process's mark >= 96 MB
    big = measure([sys.executable, "-c", "b = bytearray(64 << 20); b[::4096] = b'x' * len(b[::4096])"]).check("big")
    small = measure([sys.executable, "-c", "pass"]).check("small")
    assert big.peak_rss_kB >= 64 * 1024
    assert 0 < small.peak_rss_kB < big.peak_rss_kB
    assert small.peak_rss_kB < resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    del ballast
    assert positive(big.wall_s) and positive(small.wall_s)


def test_perf_cli_options() -> None:
    from bench.tools.perf import add_arguments

    p = argparse.ArgumentParser()
    add_arguments(p)
    a = p.parse_args(["--quick", "--only", "pipeline", "--no-peers"])
    assert a.quick and a.only == "pipeline" and a.no_peers
