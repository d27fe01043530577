"""PNG plots of a run, from its result (no file read back): one per reference step, and an
overview of the whole run (min/max envelopes: a run of any length costs the same).

matplotlib's object API with the Agg canvas (no pyplot, no display, no tight_layout: each
of those costs a large share of a short run's wall time)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


# Bus bookkeeping, not signals of the loop: in the summary, not in the overview.
BOOKKEEPING = {"sync_counter", "sample_index"}


def _save(fig: Figure, path: Path) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=90)
    return path


def step_plots(out: Path, windows: list[dict[str, Any]], steps: list[dict[str, Any]], title: str) -> list[Path]:
    """One figure per reference step: the sampled current against its reference, and the command."""
    paths = []
    for i, s in enumerate(steps):
        p, sig = int(s["at_period"]), str(s["signal"])
        w = next((w for w in windows if int(w["at_period"]) == p and f"{sig}_A" in w), None)
        if w is None:
            continue
        k = w["period"] - p
        fig = Figure(figsize=(7, 4), layout=None)
        fig.subplots_adjust(left=0.1, right=0.88, top=0.86, bottom=0.12)
        ax = fig.add_subplot()
        ax.step(k, w[f"{sig}_ref_A"], where="post", label=f"{sig}* (A)", color="k", lw=1)
        ax.plot(k, w[f"{sig}_A"], "o-", label=f"{sig} sampled (A)", ms=3)
        ax.set_xlabel("control periods after the reference step")
        ax.set_ylabel("current (A)")
        vname = "vq_V" if sig == "iq" else "vd_V"
        if vname in w:
            ax2 = ax.twinx()
            ax2.step(k, w[vname], where="post", color="tab:red", alpha=0.6, label=f"{vname[:2]}* (V)")
            ax2.set_ylabel("voltage command (V)", color="tab:red")
        settle = s["periods_to_settle"]
        ax.set_title(f"{title}: {sig} {s['from_A']:.2f} -> {s['to_A']:.2f} A at period {p}\n"
                     f"settles in {settle} periods, overshoot {s['overshoot_A']:.3g} A", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right")
        paths.append(_save(fig, out / f"step_{i:02d}_{sig}_p{p}.png"))
    return paths


def overview_plot(out: Path, envelopes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], title: str,
                  ts_s: float, name: str = "overview.png", max_panels: int = 8) -> Path | None:
    """Every traced signal over the whole run, one panel per unit (as in the Rerun view), drawn as
    min/max bands per bucket of periods; references as lines."""
    from ..run.signals import unit_of

    by_unit: dict[str, list[str]] = {}
    for n in envelopes:
        if n in BOOKKEEPING:
            continue
        by_unit.setdefault(unit_of(n), []).append(n)
    order = sorted(by_unit, key=lambda u: (u not in ("A", "V"), u != "A", u))[:max_panels]
    if not order:
        return None
    fig = Figure(figsize=(9, 1.9 * len(order) + 0.8))
    fig.subplots_adjust(left=0.1, right=0.8, top=0.95, bottom=0.06, hspace=0.25)
    axes = fig.subplots(len(order), 1, sharex=True, squeeze=False)[:, 0]
    for ax, unit in zip(axes, order):
        for n in by_unit[unit]:
            start, lo, hi = envelopes[n]
            t = start * ts_s
            if n.endswith("_ref_A"):
                ax.plot(t, hi, "k--" if n.startswith("id") else "k", lw=0.8, drawstyle="steps-post", label=n)
            else:
                (line,) = ax.plot(t, hi, lw=0.7, drawstyle="steps-post", label=n)
                if not np.array_equal(lo, hi, equal_nan=True):
                    ax.plot(t, lo, lw=0.7, drawstyle="steps-post", color=line.get_color())
                    ax.fill_between(t, lo, hi, step="post", alpha=0.3, color=line.get_color(), lw=0)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    axes[0].set_title(title, fontsize=10)
    axes[-1].set_xlabel("simulated time (s)")
    return _save(fig, out / name)
