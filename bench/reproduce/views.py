"""Each kept run's Rerun recording (run.rrd) and overview figure (overview.png), made from the trace the run
decoded: its traces.npy, written by the run's own pipeline as it decodes (bench/claims run_raw). The CAN log is never
decoded again; that a log replays to the run's trace is the tests' to check (tests/host/test_replay_truth.py).
Wherever the claims ran (here, or in the VM over vcan), the views are made here from the run's folder."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any


def make_views(out: Path) -> int:
    """run.rrd and overview.png of every kept run (out/runs/NAME, from this host or the VM) from its traces.npy.
    Runs that already have run.rrd are left as they are. Returns the number of runs without views (each
    reported)."""
    root = out / "runs"
    todo = (
        [r for r in sorted(root.iterdir()) if (r / "bus.log").exists() and not (r / "run.rrd").exists()]
        if root.exists()
        else []
    )
    failed = 0
    for i, run in enumerate(todo):
        t0 = time.monotonic()
        try:
            note = "" if run_views(run) else ", no figure (no current trace)"
        except Exception as exc:  # noqa: BLE001 - one run's views cost its figure, not the report
            failed += 1
            note = f", FAILED: {type(exc).__name__}: {exc}"
        print(f"views [{i + 1}/{len(todo)}] {run.name} ({time.monotonic() - t0:.1f} s{note})", flush=True)
    return failed


def run_views(run: Path) -> bool:
    """One run's Rerun recording and overview figure from its folder; whether it has a figure."""
    import numpy as np

    from bench.run.sinks import TRACES_FILE
    from bench.signals import SignalInfo
    from bench.view.rerun_sink import RerunSink

    if not (run / TRACES_FILE).exists():
        raise FileNotFoundError(f"{run / TRACES_FILE}: the run wrote no trace (it did not run to its end)")
    arr = np.load(run / TRACES_FILE)
    names = arr.dtype.names or ()
    # float64 as the run held them (traces.npy keeps a REAL32 or a small integer in float32, exactly)
    trace = {n: np.ascontiguousarray(arr[n], dtype=np.int64 if n == "period" else np.float64) for n in names}
    summary = json.loads((run / "summary.json").read_text()) if (run / "summary.json").exists() else None
    with RerunSink(run.name, run / "run.rrd") as sink:
        sink.begin([SignalInfo.of(n, f"{run.name}/{TRACES_FILE}") for n in names])
        if len(arr):
            sink.write(trace)
        sink.end(summary)
    return overview_plot(run, trace, run.name) is not None


def overview_plot(run: Path, tr: dict[str, Any], title: str) -> Path | None:
    """The currents against their references around the first reference steps, and the voltage commands."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = len(tr.get("period", ()))
    if n == 0 or not all(c in tr for c in ("iq_A", "iq_ref_A", "id_A", "id_ref_A", "vd_V", "vq_V")):
        return None
    tr = dict(tr)
    if "drive_iq_ref_active_A" in tr and not np.any(tr["iq_ref_A"]):
        tr["iq_ref_A"] = np.nan_to_num(tr["drive_iq_ref_active_A"])  # speed/position mode: the loop's own iq*
    changes = np.nonzero(np.abs(np.diff(tr["iq_ref_A"])) + np.abs(np.diff(tr["id_ref_A"])) > 1e-9)[0]
    lo = max(0, int(changes[0]) - 5) if len(changes) else 0
    hi = min(n, lo + (100 if len(changes) <= 8 else 400))
    k = tr["period"][lo:hi]
    fig = Figure(figsize=(7, 4.2))
    fig.subplots_adjust(left=0.1, right=0.97, top=0.92, bottom=0.11, hspace=0.12)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    a1.plot(k, tr["iq_ref_A"][lo:hi], "k", lw=1, drawstyle="steps-post", label="iq*")
    a1.plot(k, tr["iq_A"][lo:hi], ".-", ms=2, lw=0.8, label="iq")
    if np.nanmax(np.abs(tr["id_ref_A"][lo:hi])) > 0 or np.nanmax(np.abs(tr["id_A"][lo:hi])) > 0.05:
        a1.plot(k, tr["id_ref_A"][lo:hi], "k--", lw=0.8, drawstyle="steps-post", label="id*")
        a1.plot(k, tr["id_A"][lo:hi], ".-", ms=2, lw=0.8, label="id")
    a1.set_ylabel("A")
    a1.legend(loc="best", fontsize=7)
    a1.grid(alpha=0.3)
    a1.set_title(title, fontsize=9)
    a2.plot(k, tr["vq_V"][lo:hi], lw=0.8, label="vq*")
    a2.plot(k, tr["vd_V"][lo:hi], lw=0.8, label="vd*")
    a2.set_ylabel("V")
    a2.set_xlabel("control period")
    a2.legend(loc="best", fontsize=7)
    a2.grid(alpha=0.3)
    FigureCanvasAgg(fig)
    path = run / "overview.png"
    fig.savefig(path, dpi=80)
    return path
