"""`bench sweep` as a user runs it: on Dask (a LocalCluster of 2 workers, and a separately started
`dask scheduler` + `dask worker`), serially, killed and resumed, Monte Carlo, and Zhao 2022's stability
boundary found by bisection against the closed-loop polynomial's (bench/claims/zhao2022.py)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from bench_cli import bench_cli, spawn_bench

from bench.paths import REPO
from bench.sweep.space import build, expand_range

STEP = REPO / "scenarios" / "you2019_step.toml"
ZHAO = REPO / "scenarios" / "zhao2022_stability.toml"
TIMING = ("point_s", "loop_s", "worker_pid")  # where and how fast a point ran: not the study's result
STUDY = [
    str(STEP),
    "--grid",
    "controller.L_hat_ratio=0.6:1.4:0.4",
    "--sample",
    "controller.R_hat_ratio=uniform(0.8,1.2)",
    "--samples",
    "2",
    "--seed",
    "3",
    "--set",
    "scenario.periods=300",
    "--no-dashboard",
]


def rows(out: Path) -> list[dict[str, Any]]:
    return pq.read_table(out / "sweep.parquet").to_pylist()


def results(out: Path) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows(out)]


@pytest.fixture(scope="module")
def serial(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("serial") / "study"
    bench_cli("sweep", *STUDY, "--serial", "--out", str(out), expect=0)
    return out


# ---------------------------------------------------------------------------------------- the points


def test_ranges_are_decimal_and_include_stop() -> None:
    assert expand_range("k", "0.1:0.5:0.1") == ["0.1", "0.2", "0.3", "0.4", "0.5"]
    assert expand_range("k", "1:10:3") == ["1", "4", "7", "10"]
    assert expand_range("k", "0:1:0.3") == ["0", "0.3", "0.6", "0.9"]


def test_samples_are_reproducible_from_their_seed() -> None:
    a = build(["x=1,2"], ["y=normal(1,0.1)"], 5, 7).points()
    assert a == build(["x=1,2"], ["y=normal(1,0.1)"], 5, 7).points()
    assert a != build(["x=1,2"], ["y=normal(1,0.1)"], 5, 8).points()
    assert len(a) == 10 and {p["x"] for p in a} == {"1", "2"}
    drawn = np.array([float(p["y"]) for p in build([], ["y=uniform(2,3)"], 2000, 1).points()])
    assert 2 <= drawn.min() and drawn.max() < 3 and abs(drawn.mean() - 2.5) < 0.03


@pytest.mark.parametrize(
    "args,says",
    [
        (["--grid", "controller.L_hat_ratio=1:0.5:0.1"], "STOP must be >= START"),
        (["--grid", "controller.L_hat_ratio=0.5:1:0"], "STEP must be > 0"),
        (["--grid", "controller.L_hat_ratio=0.5:x:0.1"], "is not a number"),
        (["--grid", "controller.L_hat_ratio=0.5,-1"], "controller.L_hat_ratio = -1: a ratio must be"),
        (["--grid", "controller.nonsense=1"], "nonsense"),
        (["--sample", "controller.R_hat_ratio=uniform(2,1)"], "LOW < HIGH"),
        (["--sample", "controller.R_hat_ratio=gamma(1,2)"], "uniform(LOW,HIGH) or normal(MEAN,STD)"),
        (["--sample", "controller.R_hat_ratio=normal(1,0.1)"], "--samples N"),
        (["--grid", "scenario.seed=1,2", "--samples", "3"], "nothing to draw"),
        (["--bisect", "controller.L_hat_ratio=1:2"], "--until"),
        (["--bisect", "controller.L_hat_ratio=1:2", "--until", "speed>3"], "unknown metric 'speed'"),
        (["--bisect", "controller.L_hat_ratio=1:2", "--until", "status>ok"], "only == and !="),
        (["--grid", "controller.L_hat_ratio=1", "--grid", "controller.L_hat_ratio=2"], "given twice"),
        (["--grid", "controller.L_hat_ratio=1", "--workers", "0"], "--workers 0"),
        (["--grid", "controller.L_hat_ratio=1", "--resume"], "--resume needs --out"),
        ([], "nothing to sweep"),
    ],
)
def test_bad_input_is_refused_before_anything_runs(tmp_path: Path, args: list[str], says: str) -> None:
    out = tmp_path / "never"
    res = bench_cli("sweep", str(STEP), *args, *(["--out", str(out)] if "--resume" not in args else []), expect=2)
    assert says in res.stderr, res.stderr
    assert not out.exists()


# ---------------------------------------------------------------------------------------- where it runs


def test_a_local_cluster_of_two_workers_gives_the_serial_table(serial: Path, tmp_path: Path) -> None:
    out = tmp_path / "cluster"
    res = bench_cli("sweep", *STUDY, "--workers", "2", "--out", str(out), expect=0)
    assert "local Dask cluster of 2 worker processes" in res.stdout
    got, ref = results(out), results(serial)
    assert len(ref) == 6 and got == ref
    assert len({r["worker_pid"] for r in rows(out)}) == 2  # both workers ran points
    assert len({r["worker_pid"] for r in rows(serial)}) == 1
    # 3 grid points x the same 2 draws at each (common random numbers: grid points compared on equal draws)
    assert len({r["controller.L_hat_ratio"] for r in ref}) == 3
    assert len({r["controller.R_hat_ratio"] for r in ref}) == 2
    assert len({(r["controller.L_hat_ratio"], r["controller.R_hat_ratio"]) for r in ref}) == 6
    assert len({r["steady_state_error_A"] for r in ref}) == 6  # six different loops
    assert all(r["status"] == "ok" for r in ref)


def test_a_separately_started_dask_cluster(serial: Path, tmp_path: Path) -> None:
    dask = str(Path(sys.executable).with_name("dask"))
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    sched = subprocess.Popen(
        [
            dask,
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--no-dashboard",
            "--scheduler-file",
            str(sched_file),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    worker = None
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        worker = subprocess.Popen(
            [dask, "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        out = tmp_path / "remote"
        res = bench_cli("sweep", *STUDY, "--scheduler", address, "--out", str(out), expect=0)
        assert f"the Dask cluster at {address} (1 workers)" in res.stdout
        assert results(out) == results(serial)
        assert {r["worker_pid"] for r in rows(out)} <= _descendants(worker.pid)  # the points ran in that worker
        # the scheduler file works as the address too
        res = bench_cli("sweep", *STUDY, "--scheduler", str(sched_file), "--out", str(tmp_path / "by-file"), expect=0)
        assert results(tmp_path / "by-file") == results(serial), res.stderr
    finally:
        for p in (worker, sched):
            if p is not None:
                p.terminate()
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()


def _descendants(pid: int) -> set[int]:
    """The processes a `dask worker` started (its nanny's worker process runs the points)."""
    out: set[int] = set()
    todo = [pid]
    while todo:
        p = todo.pop()
        for t in Path(f"/proc/{p}/task").iterdir():
            kids = [int(k) for k in (t / "children").read_text().split()]
            out.update(kids)
            todo += kids
    return out


def test_an_unreachable_scheduler_is_said(tmp_path: Path) -> None:
    res = bench_cli("sweep", *STUDY, "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path / "x"), expect=2)
    assert "--scheduler tcp://127.0.0.1:9" in res.stderr, res.stderr


# ---------------------------------------------------------------------------------------- kill and resume


def test_a_killed_sweep_resumes_without_rerunning_finished_points(tmp_path: Path) -> None:
    out = tmp_path / "killed"
    # points enough that the study is not over when the second part is written (a part a second; ~80 points/s)
    n = 1001
    args = [str(STEP), "--grid", "controller.L_hat_ratio=0.5:1.5:0.001", "--set", "scenario.periods=2000"]
    args += ["--workers", "2", "--no-dashboard", "--out", str(out)]
    proc = spawn_bench("sweep", *args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    parts = out / "sweep.parts"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(parts.glob("part-*.parquet"))) < 2:
        time.sleep(0.1)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = {r["point_id"]: r for p in sorted(parts.glob("part-*.parquet")) for r in pq.read_table(p).to_pylist()}
    assert 0 < len(before) < n, "killed mid-study"
    assert not (out / "sweep.parquet").exists()
    res = bench_cli("sweep", *args, "--resume", expect=0)
    assert f"resuming: {len(before)} of {n} points already in" in res.stdout
    after = rows(out)
    assert [float(r["controller.L_hat_ratio"]) for r in after] == pytest.approx([0.5 + 0.001 * i for i in range(n)])
    for r in after:
        if r["point_id"] in before:  # not run again: the same row, down to its timing
            assert r == before[r["point_id"]]
    assert sum(r["point_id"] not in before for r in after) == n - len(before)
    assert not (out / "sweep.parts").exists()
    meta = json.loads((out / "sweep.json").read_text())
    assert meta["points_resumed"] == len(before) and meta["points_run"] == n - len(before)


def test_a_folder_holding_another_study_is_not_mixed(serial: Path) -> None:
    res = bench_cli("sweep", *STUDY, "--serial", "--out", str(serial), expect=2)
    assert "already holds a study" in res.stderr
    res = bench_cli("sweep", *STUDY, "--seed", "4", "--serial", "--out", str(serial), "--resume", expect=2)
    assert "another study (seed differ)" in res.stderr, res.stderr


# ---------------------------------------------------------------------------------------- outputs


def test_monte_carlo_percentiles_are_the_tables(serial: Path) -> None:
    meta = json.loads((serial / "sweep.json").read_text())
    table = rows(serial)
    for metric in ("steady_state_error_A", "periods_to_settle"):
        vals = np.array([r[metric] for r in table if r[metric] is not None], dtype=float)
        got = meta["distributions"][metric]
        assert got["n"] == len(vals)
        for p in (5, 50, 95):
            assert got[f"p{p}"] == pytest.approx(np.percentile(vals, p), rel=1e-12)
    assert meta["distributions"]["status"] == {"ok": 6}
    assert (serial / "histogram_periods_to_settle.png").stat().st_size > 0


def test_grid_heatmap_and_csv(tmp_path: Path) -> None:
    out = tmp_path / "grid"
    grid = ["--grid", "controller.L_hat_ratio=0.5,1.0", "--grid", "controller.R_hat_ratio=1.0,1.5"]
    bench_cli("sweep", STEP, *grid, "--serial", "--csv", "--out", out, expect=0)
    csv = (out / "sweep.csv").read_text().splitlines()
    assert len(csv) == 5 and csv[0].startswith('"point_id","controller.L_hat_ratio","controller.R_hat_ratio"')
    table = {(r["controller.L_hat_ratio"], r["controller.R_hat_ratio"]): r for r in rows(out)}
    assert table[("1.0", "1.0")]["periods_to_settle"] == 2  # matched: deadbeat
    assert table[("0.5", "1.0")]["periods_to_settle"] > 5  # L_hat = 0.5 L: slow
    assert (out / "heatmap_periods_to_settle.png").stat().st_size > 0


def test_error_growth_is_the_stability_claims_judgement() -> None:
    """bench/metrics.py error_growth, the Zhao 2022 boundary claim's measure and the sweep's error_growth_per_period:
    < 1 exactly when the error decays. A cycle held by the voltage limit, over half the step and shrinking by a hair
    (0.9999998 per period), does not decay: the error's swing alone (the sweep's former measure) read it as decaying."""
    from bench.metrics import error_growth, growth_windows

    k = np.arange(700)
    step = 0.05

    def judge(err: np.ndarray) -> tuple[float, bool]:
        windows = growth_windows(len(err), 20)
        assert windows is not None
        g = error_growth(err, step, *windows)
        return g.per_period, g.decays

    held = 0.12 * 0.9999998**k * np.sin(2.1 * k)
    assert judge(held) == (1.0, False)
    growing = 1e-3 * 1.001**k * np.sin(2.1 * k)
    g, decays = judge(growing)
    assert g == pytest.approx(1.001, abs=5e-4) and not decays
    decaying = 0.05 * 0.99**k * np.sin(2.1 * k)
    g, decays = judge(decaying)
    assert g == pytest.approx(0.99, abs=5e-4) and decays
    assert judge(np.full(700, 1e-8)) == (0.0, True)  # down at the float32 floor
    assert judge(np.where(k > 600, np.nan, 0.01))[0] == math.inf
    assert growth_windows(30, 20) is None


def test_error_growth_per_period_in_a_study(tmp_path: Path) -> None:
    """On the Zhao 2022 motor: settled (at the float32 floor), decaying slowly (L/L0 = 0.704, root radius 0.995),
    and past the boundary (L/L0 = 0.70), where the voltage limit holds the loop in a bounded cycle."""
    out = tmp_path / "growth"
    bench_cli("sweep", ZHAO, "--grid", "controller.L_hat_ratio=1.25,1.42,1.4286", "--serial", "--out", out, expect=0)
    g = {r["controller.L_hat_ratio"]: r["error_growth_per_period"] for r in rows(out)}
    assert g["1.25"] == 0.0 and 0.99 < g["1.42"] < 1.0 and g["1.4286"] >= 1.0, g


def test_zhao2022_stability_boundary_by_bisection(tmp_path: Path) -> None:
    """Zhao 2022 Eq. 34-42: the bench's boundary (run status: diverged once the loop no longer settles)
    within 0.5 % of where the exact closed-loop polynomial's spectral radius crosses 1 (L/L0 ~ 0.70 on the
    Table 1 motor at Ts = 100 us; the paper's Ts -> 0 limit says 3/4)."""
    from bench.claims.zhao2022 import L, R, poly_boundary, q_incremental

    out = tmp_path / "zhao"
    bisect = ["--bisect", "controller.L_hat_ratio=1.25:1.6667", "--until", "status!=ok", "--tol", "0.002"]
    bench_cli("sweep", ZHAO, *bisect, "--workers", "2", "--no-dashboard", "--out", out, expect=0)
    (b,) = json.loads((out / "sweep.json").read_text())["boundaries"]
    assert b["hi"] - b["lo"] <= 0.002 and b["condition_at_lo"] is False and b["condition_at_hi"] is True
    exact = 1.0 / poly_boundary(lambda lam: q_incremental(R, L, R, L / lam))  # L_hat_ratio = L0/L
    assert abs(b["boundary"] - exact) / exact < 0.005, (b, exact)
    # every run on the stable side settled; every run on the other did not
    for r in rows(out):
        x = float(r["controller.L_hat_ratio"])
        assert (r["status"] == "ok") == (x <= b["lo"]), r


def test_the_embedded_clusters_workers_run_no_statistical_profiler() -> None:
    """Dask's profiler calls sys._current_frames() every 10 ms; on CPython 3.11 that can hang a worker whose point
    starts a thread (bench/sweep/engine.py): the embedded cluster's workers must not run it."""
    from bench.sweep.engine import Engine

    engine = Engine(None, 2, False, dashboard=False)
    try:
        running = engine.client.run(lambda dask_worker: "profile" in dask_worker.periodic_callbacks)
    finally:
        engine.close()
    assert len(running) == 2 and not any(running.values()), running
