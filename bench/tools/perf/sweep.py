"""`bench sweep` as a user runs it (whole commands), on the embedded Dask LocalCluster:

- 1,000 points of 2,000 periods on 1 and on 2 workers: points/s and the speed-up (target >= 1.8x on 2),
  a point's own loop time next to what the point costs in all (configuration by SDO, decoding, summary)
  and next to what the command spends per point (cluster start-up, scheduling, the table);
- a 10^4-point study (a 100 x 100 grid of L_hat/L x R_hat/R) on all cores: its wall time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.paths import REPO

SCENARIO = REPO / "scenarios" / "you2019_step.toml"
PERIODS = 2000


def _sweep(out: Path, workers: int, grid: list[str]) -> dict[str, Any]:
    args = [sys.executable, "-m", "bench.cli", "sweep", str(SCENARIO), "--set", f"scenario.periods={PERIODS}"]
    for g in grid:
        args += ["--grid", g]
    args += ["--workers", str(workers), "--no-dashboard", "--out", str(out)]
    t0 = time.monotonic()
    res = subprocess.run(args, cwd=REPO, capture_output=True, text=True)
    wall = time.monotonic() - t0
    if res.returncode != 0:
        return {"error": res.stderr.strip()[-500:]}
    meta = json.loads((out / "sweep.json").read_text())
    n = meta["points"]
    return {
        "points": n,
        "workers": workers,
        "command_wall_s": wall,
        "points_per_s": n / wall,
        "sweep_wall_s": meta["wall_s"],  # from the first point sent to the last row in
        "mean_point_ms": 1e3 * meta["mean_point_s"],  # a point in its worker, all included
        "mean_loop_ms": 1e3 * meta["mean_loop_s"],  # of which the loop itself
        "command_ms_per_point_per_worker": 1e3 * wall * workers / n,
    }


def sweep_scaling(points: int = 1000, study_points: int = 10_000) -> dict[str, Any]:
    cores = os.cpu_count() or 1
    out: dict[str, Any] = {"cores": cores, "periods_per_point": PERIODS}
    with tempfile.TemporaryDirectory(prefix="perf-sweep-") as tmp:
        grid = [f"controller.L_hat_ratio=0.5:{0.5 + (points - 1) * 0.001:.3f}:0.001"]
        runs = {w: _sweep(Path(tmp) / f"w{w}", w, grid) for w in sorted({1, 2, cores})}
        out["runs"] = runs
        if all("error" not in r for r in runs.values()) and 2 in runs:
            out["speedup_2"] = runs[2]["points_per_s"] / runs[1]["points_per_s"]
        side = round(study_points**0.5)
        last = 0.5 + (side - 1) * 0.01
        study = _sweep(
            Path(tmp) / "study",
            cores,
            [f"controller.L_hat_ratio=0.5:{last:.2f}:0.01", f"controller.R_hat_ratio=0.5:{last:.2f}:0.01"],
        )
        out["study"] = study
    return out
