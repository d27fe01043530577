"""The end of a study: sweep.json (the study, where and how fast it ran, distributions, boundaries), the
plots, and what is printed."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from bench.sweep.report import boundary_plot, distributions, format_distributions, heatmap, histogram, line_plot
from bench.sweep.table import TABLE

SHOWN = ("status", "periods_to_settle", "overshoot_pct", "steady_state_error_A", "error_growth_per_period")


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _print_rows(rows: list[dict[str, Any]], keys: list[str], limit: int = 30) -> None:
    cols = [*keys, *SHOWN]
    widths = [max(len(c), *(len(_fmt(r.get(c))) for r in rows[:limit])) for c in cols]
    print("  ".join(c.ljust(w) for c, w in zip(cols, widths, strict=True)))
    for r in rows[:limit]:
        print("  ".join(_fmt(r.get(c)).ljust(w) for c, w in zip(cols, widths, strict=True)))
    if len(rows) > limit:
        print(f"... {len(rows) - limit} more rows in {TABLE}")


def write_outputs(
    out: Path,
    args: argparse.Namespace,
    sc: Any,
    spec: dict[str, Any],
    space: Any,
    rows: list[dict[str, Any]],
    results: list[dict[str, Any]] | None,
    engine: Any,
    wall: float,
    ran: int,
    skipped: int,
) -> None:
    from bench.sweep.point import NUMERIC

    keys = space.keys + ([args.bisect.partition("=")[0]] if args.bisect else [])
    metric = (
        args.metric
        or (args.until and next((m for m in NUMERIC if args.until.strip().startswith(m)), None))
        or "periods_to_settle"
    )
    plots: list[str] = []
    summary: dict[str, Any] = {
        "study": spec,
        "state": "done",
        "scenario": sc.name,
        "periods_per_point": sc.periods,
        "where": engine.where,
        "workers": engine.workers,
        "points": len(rows),
        "points_run": ran,
        "points_resumed": skipped,
        "wall_s": wall,
        "points_per_s": ran / wall if wall > 0 else None,
        "mean_point_s": _mean(rows, "point_s"),
        "mean_loop_s": _mean(rows, "loop_s"),
    }
    if not args.bisect:
        _print_rows(rows, keys)
    if len(space.grid) == 2 and not args.bisect:
        name = f"heatmap_{metric}.png"
        heatmap(out / name, space.grid, rows, metric, sc.name)
        plots.append(name)
    if len(space.grid) == 1 and not args.bisect and not space.samples:
        # one key: the metric against it; with a motor folder, the identified inductances against its truth
        truth = sorted({k for r in rows for k in r if k.startswith("motor.L")})
        ident = sorted({k for r in rows for k in r if k.startswith("identified.") and k.endswith("L_hat_H")})
        lines = [*ident, *truth] if truth and ident and args.metric is None else [metric]
        name = f"line_{'inductance' if lines != [metric] else metric}.png"
        if line_plot(out / name, space.grid[0][0], rows, lines, sc.name):
            plots.append(name)
    if space.samples:
        from bench.sweep.point import NUMERIC as M

        ident = sorted({k for r in rows for k in r if k.startswith("identified.")})
        metrics = tuple(m for m in M if m not in ("loop_s", "point_s", "periods")) + tuple(ident)
        summary["distributions"] = dist = distributions(rows, metrics)
        print(format_distributions(dist))
        name = f"histogram_{metric}.png"
        if histogram(out / name, rows, metric, sc.name):
            plots.append(name)
    if results is not None:
        summary["boundaries"] = results
        key = args.bisect.partition("=")[0]
        for r in results:
            at = ", ".join(f"{k}={r[k]}" for k in space.keys)
            where = f" at {at}" if at else ""
            if r["boundary"] is None:
                print(f"bench sweep: {key}{where}: {r['note']}")
            else:
                print(
                    f"bench sweep: {key}{where}: {args.until} changes between {r['lo']:.6g} and {r['hi']:.6g} "
                    f"(boundary {r['boundary']:.6g}; {r['condition_at_lo']} below, {r['condition_at_hi']} above; "
                    f"{r['runs']} runs in {r['rounds']} rounds)"
                )
        if len(space.grid) == 1:
            name = "boundary.png"
            boundary_plot(out / name, results, space.grid[0][0], key, args.until, sc.name)
            plots.append(name)
    summary["plots"] = plots
    (out / "sweep.json").write_text(json.dumps(summary, indent=2, default=str))
    rate = f", {ran / wall:.1f} points/s" if wall > 0 and ran else ""
    print(
        f"bench sweep: {len(rows)} points ({ran} run{rate}, {skipped} from before) in {wall:.1f} s; "
        f"table {out / TABLE}" + (f", plots {', '.join(plots)}" if plots else "")
    )


def _mean(rows: list[dict[str, Any]], col: str) -> float | None:
    v = [float(r[col]) for r in rows if r.get(col) is not None]
    return sum(v) / len(v) if v else None
