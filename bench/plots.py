"""PNG plots of a run (matplotlib, no display needed): one per reference step, and the
identification quantities."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def step_plots(out: Path, tr: dict[str, np.ndarray], steps: list[dict[str, object]], title: str,
               before: int = 4, after: int = 24) -> list[Path]:
    paths = []
    for i, s in enumerate(steps):
        p = int(s["at_period"])  # type: ignore[arg-type]
        sig = str(s["signal"])
        lo, hi = max(0, p - before), min(len(tr["period"]), p + after)
        k = tr["period"][lo:hi] - p
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.step(k, tr[f"{sig}_ref_A"][lo:hi], where="post", label=f"{sig}* (A)", color="k", lw=1)
        ax.plot(k, tr[f"{sig}_A"][lo:hi], "o-", label=f"{sig} sampled (A)", ms=3)
        ax.set_xlabel("control periods after the reference step")
        ax.set_ylabel("current (A)")
        ax2 = ax.twinx()
        vname = "vq_V" if sig == "iq" else "vd_V"
        if vname in tr:
            ax2.step(k, tr[vname][lo:hi], where="post", color="tab:red", alpha=0.6, label=f"{vname[:2]}* (V)")
            ax2.set_ylabel("voltage command (V)", color="tab:red")
        settle = s["periods_to_settle"]
        ax.set_title(f"{title}: {sig} {s['from_A']:.2f} -> {s['to_A']:.2f} A at period {p}\n"
                     f"settles in {settle} periods, overshoot {s['overshoot_A']:.3f} A")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right")
        fig.tight_layout()
        path = out / f"step_{i:02d}_{sig}_p{p}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        paths.append(path)
    return paths


def identification_plot(out: Path, tr: dict[str, np.ndarray], title: str) -> Path | None:
    names = [n for n in ("det_A2", "K1_hat", "K1_active_V_A", "L_hat_H") if n in tr]
    if not names or all(np.nanmax(np.abs(tr[n])) == 0 for n in names if np.isfinite(tr[n]).any()):
        return None
    fig, axes = plt.subplots(len(names) + 1, 1, figsize=(8, 1.8 * (len(names) + 1)), sharex=True)
    axes[0].plot(tr["period"], tr["iq_A"], lw=0.8, label="iq (A)")
    axes[0].plot(tr["period"], tr["iq_ref_A"], lw=0.8, color="k", label="iq* (A)")
    axes[0].legend(loc="upper right")
    axes[0].set_title(title)
    for ax, n in zip(axes[1:], names):
        ax.plot(tr["period"], tr[n], lw=0.8)
        ax.set_ylabel(n)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("control period")
    fig.tight_layout()
    path = out / "identification.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
