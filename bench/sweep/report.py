"""What a study shows: a heat-map over two grid keys, the boundary line of a search, and for Monte Carlo
the distribution of each metric (percentiles, printed and in sweep.json, and a histogram)."""

from __future__ import annotations

import math
import textwrap
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

PERCENTILES = (5, 25, 50, 75, 95)


def _plt():  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _values(rows: list[dict[str, Any]], metric: str) -> np.ndarray:
    return np.array([float(r[metric]) for r in rows if r.get(metric) is not None], dtype=float)


def distributions(rows: list[dict[str, Any]], metrics: tuple[str, ...]) -> dict[str, Any]:
    """Per metric: how many points have it, mean, std and percentiles (over the points that have it);
    the statuses counted."""
    out: dict[str, Any] = {"points": len(rows), "status": dict(Counter(str(r.get("status")) for r in rows))}
    for m in metrics:
        v = _values(rows, m)
        v = v[np.isfinite(v)]
        if len(v) == 0:
            out[m] = {"n": 0}
            continue
        out[m] = {
            "n": int(len(v)),
            "mean": float(v.mean()),
            "std": float(v.std(ddof=1)) if len(v) > 1 else 0.0,
            **{f"p{p}": float(np.percentile(v, p)) for p in PERCENTILES},
        }
    return out


def format_distributions(d: dict[str, Any]) -> str:
    lines = [
        f"{'metric':<28} {'n':>6} {'mean':>11} {'std':>11} " + " ".join(f"{'p' + str(p):>11}" for p in PERCENTILES)
    ]
    for m, s in d.items():
        if m in ("points", "status") or not s.get("n"):
            continue
        lines.append(
            f"{m:<28} {s['n']:>6} {s['mean']:>11.4g} {s['std']:>11.4g} "
            + " ".join(f"{s['p' + str(p)]:>11.4g}" for p in PERCENTILES)
        )
    lines.append("status: " + ", ".join(f"{k} {v}" for k, v in sorted(d["status"].items())))
    return "\n".join(lines)


def histogram(path: Path, rows: list[dict[str, Any]], metric: str, title: str) -> bool:
    v = _values(rows, metric)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return False
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.hist(v, bins=min(60, max(10, int(math.sqrt(len(v))))), color="#4878d0")
    for p, style in ((5, ":"), (50, "-"), (95, ":")):
        x = float(np.percentile(v, p))
        ax.axvline(x, color="k", linestyle=style, linewidth=1)
        ax.text(x, ax.get_ylim()[1] * 0.95, f" p{p}", fontsize=8)
    ax.set_xlabel(metric)
    ax.set_ylabel("points")
    ax.set_title(f"{title}: {metric} over {len(v)} points")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def line_plot(path: Path, key: str, rows: list[dict[str, Any]], metrics: list[str], title: str) -> bool:
    """One grid key: each metric against it (a study over one key, e.g. the identified L_hat and a motor folder's
    true incremental inductance over the current); False when no row has a number."""
    pts = []
    for r in rows:
        try:
            pts.append((float(r[key]), r))
        except (KeyError, TypeError, ValueError):
            continue
    pts.sort(key=lambda p: p[0])
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    drawn = False
    for m in metrics:
        xy = [(x, float(r[m])) for x, r in pts if r.get(m) is not None and math.isfinite(float(r[m]))]
        if xy:
            ax.plot(*zip(*xy, strict=True), marker="o", label=m)
            drawn = True
    if drawn:
        ax.set_xlabel(key)
        ax.grid(True, alpha=0.3)
        ax.legend()
        ax.set_title(title)
        fig.tight_layout()
        fig.savefig(path, dpi=90)
    plt.close(fig)
    return drawn


def heatmap(path: Path, grid: list[tuple[str, list[str]]], rows: list[dict[str, Any]], metric: str, title: str) -> None:
    """Two grid keys; a cell is the metric's median over the cell's points (several with samples)."""
    plt = _plt()
    (k1, v1), (k2, v2) = grid
    cells: dict[tuple[str, str], list[float]] = {}
    for r in rows:
        val = r.get(metric)
        if val is not None and r.get(k1) in v1 and r.get(k2) in v2:
            cells.setdefault((r[k1], r[k2]), []).append(float(val))
    z = np.full((len(v1), len(v2)), np.nan)
    for (a, b), vals in cells.items():
        z[v1.index(a), v2.index(b)] = float(np.median(vals))
    fig, ax = plt.subplots(figsize=(min(16, 1.0 * len(v2) + 3), min(12, 0.6 * len(v1) + 2)))
    im = ax.imshow(z, origin="lower", cmap="viridis", aspect="auto")
    step2, step1 = max(1, len(v2) // 12), max(1, len(v1) // 12)
    ax.set_xticks(range(0, len(v2), step2), v2[::step2])
    ax.set_yticks(range(0, len(v1), step1), v1[::step1])
    ax.set_xlabel(k2)
    ax.set_ylabel(k1)
    if len(v1) * len(v2) <= 64:
        for i in range(len(v1)):
            for j in range(len(v2)):
                txt = "-" if np.isnan(z[i, j]) else f"{z[i, j]:.3g}"
                ax.text(j, i, txt, ha="center", va="center", color="w")
    # the colour bar's label runs along the figure's height: wrapped to it (~6 pt a 10 pt character), or a
    # small grid's figure cut it off at both ends
    label = metric + " (first iq step; '-' = none, e.g. never settles)"
    per_line = max(12, int(fig.get_figheight() * 0.8 * 72 / 6.5))
    fig.colorbar(im, label=textwrap.fill(label, per_line))
    ax.set_title(f"{title}: {metric}")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def boundary_plot(path: Path, results: list[dict[str, Any]], grid_key: str, key: str, until: str, title: str) -> None:
    """The boundary along `key` against one grid key: the bracket [lo, hi] of each search and its middle."""
    plt = _plt()
    pts = [r for r in results if r["boundary"] is not None]
    fig, ax = plt.subplots(figsize=(6.5, 4))
    if pts:
        x = [float(r[grid_key]) for r in pts]
        ax.fill_between(x, [r["lo"] for r in pts], [r["hi"] for r in pts], color="#4878d0", alpha=0.3, label="bracket")
        ax.plot(x, [r["boundary"] for r in pts], "o-", color="#4878d0", label=f"boundary ({until} changes)")
    ax.set_xlabel(grid_key)
    ax.set_ylabel(key)
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
