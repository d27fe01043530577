"""`bench sweep`: a grid of scenario variants in direct mode, on every core.

    bench sweep scenarios/you2019_step.toml --grid controller.L_hat_ratio=0.5,0.8,1.0,1.2 \\
                                            --grid controller.R_hat_ratio=0.5,1.0,1.5

Each grid point is the scenario with `--set KEY=VALUE` overrides, run in-process (the same
C nodes and frames as over vcan) in a worker process. Writes sweep.csv, sweep.json and,
for two grid keys, a heat-map PNG of the chosen metric of the first reference step.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path
from typing import Any

METRICS = ("periods_to_settle", "overshoot_pct", "overshoot_A", "steady_state_error_A")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", type=Path)
    p.add_argument(
        "--grid",
        action="append",
        required=True,
        metavar="KEY=V1,V2,...",
        help="a scenario key and its values (repeatable: the grid is the product)",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="fixed overrides applied to every point",
    )
    p.add_argument("--metric", choices=METRICS, default="periods_to_settle", help="heat-map metric")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all cores)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default runs/sweep-NAME-TIMESTAMP)")


def _parse_grid(items: list[str]) -> list[tuple[str, list[str]]]:
    grid = []
    for item in items:
        key, sep, values = item.partition("=")
        vals = [v.strip() for v in values.split(",") if v.strip()]
        if not sep or not key.strip() or not vals:
            raise ValueError(f"--grid {item!r}: expected KEY=V1,V2,... e.g. controller.L_hat_ratio=0.5,1.0")
        grid.append((key.strip(), vals))
    return grid


def _point(task: tuple[str, list[str]]) -> dict[str, Any]:
    """Run one grid point in memory (in a worker process): no file is written or read."""
    from .run import RunOptions, run_scenario
    from .scenario import load

    path, overrides = task
    try:
        res = run_scenario(load(Path(path), overrides), RunOptions(bus="direct"))
    except Exception as exc:  # noqa: BLE001 - a point the node refuses is a row, not the end of the sweep
        return {
            "overrides": overrides,
            **{m: None for m in METRICS},
            "status": f"failed: {exc}",
            "K1_active_V_A": None,
            "L_hat_H": None,
        }
    steps = [s for s in res.summary["steps"] if s["signal"] == "iq"]
    first = steps[0] if steps else {}
    ident = res.summary["identified"]
    return {
        "overrides": overrides,
        **{m: first.get(m) for m in METRICS},
        "status": res.status,
        "K1_active_V_A": ident.get("K1_active_V_A"),
        "L_hat_H": ident.get("L_hat_H"),
    }


def run_grid(
    path: Path, grid: list[tuple[str, list[str]]], fixed: list[str], jobs: int, progress: bool = True
) -> list[dict[str, Any]]:
    from tqdm import tqdm

    combos = list(itertools.product(*[[f"{k}={v}" for v in vals] for k, vals in grid]))
    tasks = [(str(path), [*fixed, *c]) for c in combos]
    ctx = mp.get_context("spawn")
    results: list[dict[str, Any]] = [{} for _ in tasks]
    with (
        ctx.Pool(processes=max(1, jobs)) as pool,
        tqdm(total=len(tasks), unit="run", disable=not (progress and sys.stderr.isatty())) as bar,
    ):
        for i, res in enumerate(pool.imap(_point, tasks)):
            results[i] = res
            bar.update(1)
    return results


def main(args: argparse.Namespace) -> int:
    from .scenario import ScenarioError, load

    try:
        grid = _parse_grid(args.grid)
        sc = load(args.scenario, args.overrides)
        for key, vals in grid:  # validate every value before starting anything
            for v in vals:
                load(args.scenario, [*args.overrides, f"{key}={v}"])
    except (ScenarioError, ValueError) as exc:
        print(f"bench sweep: {exc}", file=sys.stderr)
        return 2
    if args.jobs < 1:
        print("bench sweep: --jobs must be >= 1", file=sys.stderr)
        return 2
    out = args.out or Path("runs") / f"sweep-{sc.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out.mkdir(parents=True, exist_ok=True)
    n = 1
    for _, vals in grid:
        n *= len(vals)
    print(f"bench sweep: {n} runs of {sc.name} ({sc.periods} periods each) on {args.jobs} processes")
    t0 = time.monotonic()
    results = run_grid(args.scenario, grid, args.overrides, args.jobs)
    wall = time.monotonic() - t0
    keys = [k for k, _ in grid]
    with open(out / "sweep.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*keys, *METRICS, "status", "K1_active_V_A", "L_hat_H"])
        for r in results:
            vals = [o.split("=", 1)[1] for o in r["overrides"][len(args.overrides) :]]
            w.writerow([*vals, *[r.get(m) for m in METRICS], r["status"], r.get("K1_active_V_A"), r.get("L_hat_H")])
    (out / "sweep.json").write_text(
        json.dumps({"scenario": sc.name, "grid": grid, "jobs": args.jobs, "wall_s": wall, "results": results}, indent=2)
    )
    if len(grid) == 2:
        _heatmap(out / f"heatmap_{args.metric}.png", grid, results, args.metric, sc.name)
    print((out / "sweep.csv").read_text().rstrip())
    print(f"bench sweep: {n} runs in {wall:.1f} s; results in {out}/")
    return 0


def _heatmap(
    path: Path, grid: list[tuple[str, list[str]]], results: list[dict[str, Any]], metric: str, title: str
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    (k1, v1), (k2, v2) = grid
    z = np.full((len(v1), len(v2)), np.nan)
    for i, r in enumerate(results):
        val = r.get(metric)
        z[i // len(v2), i % len(v2)] = np.nan if val is None else float(val)
    fig, ax = plt.subplots(figsize=(1.2 * len(v2) + 3, 0.8 * len(v1) + 2))
    im = ax.imshow(z, origin="lower", cmap="viridis", aspect="auto")
    ax.set_xticks(range(len(v2)), v2)
    ax.set_yticks(range(len(v1)), v1)
    ax.set_xlabel(k2)
    ax.set_ylabel(k1)
    for i in range(len(v1)):
        for j in range(len(v2)):
            ax.text(j, i, "-" if np.isnan(z[i, j]) else f"{z[i, j]:.3g}", ha="center", va="center", color="w")
    fig.colorbar(im, label=metric + " (first iq step; '-' = never settles)")
    ax.set_title(f"{title}: {metric}")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
