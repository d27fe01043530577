"""`bench replay LOG`: decode any CAN log python-can reads (candump .log, .asc, .blf; from
vcan or a physical bus) into the same traces, summary, plots and Rerun view as a run.

The PDO layout comes from `layout.json` beside the log (written by every `bench run`), or
`--layout`, or else the EDS defaults (both nodes at their default node-IDs). Reference
steps are recovered from the SDO writes to the drive seen in the log."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import canopen
import numpy as np

from .eds import eds_path
from .layout import FMT, BusLayout, PdoLayout


def default_layout() -> BusLayout:
    """The TPDOs that are valid by default in the EDS files (no node needed)."""
    plant = canopen.import_od(str(eds_path("plant")), node_id=0x10)
    drive = canopen.import_od(str(eds_path("drive")), node_id=0x20)
    layout = BusLayout(0x10, 0x20, plant["COB-ID SYNC message"].default & 0x7FF)
    for name, od in (("plant", plant), ("drive", drive)):
        for n in range(4):
            cob = od[0x1800 + n][1].default
            if cob & 0x80000000:
                continue
            m = od[0x1A00 + n]
            sigs = []
            for i in range(1, m[0].default + 1):
                v = m[i].default
                var = od[v >> 16][(v >> 8) & 0xFF]
                sigs.append((f"{var.parent.name}.{var.name}", FMT[var.data_type]))
            layout.pdos.append(PdoLayout(name, f"TPDO{n + 1}", cob & 0x7FF, od[0x1800 + n][2].default, sigs))
    return layout


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", type=Path, help="CAN log (.log candump, .asc, .blf, ...)")
    p.add_argument("--layout", type=Path, default=None, help="layout.json of the run (default: beside the log, "
                   "else the EDS defaults)")
    p.add_argument("--pole-pairs", type=int, default=None, help="for id/iq (default: from capture.json or 5)")
    p.add_argument("--ts", type=float, default=None, help="control period, s (default: from capture.json or 55e-6)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: LOG's folder/replay)")
    p.add_argument("--no-viewer", action="store_true")
    p.add_argument("--serve", action="store_true")


def main(args: argparse.Namespace) -> int:
    from .plots import identification_plot, step_plots
    from .results import format_table, recorded_references
    from .runner import frames_from_log
    from .metrics import step_metrics
    from .traces import check_continuity, decode, save
    from .viewer import Viewer

    if not args.log.exists():
        print(f"bench replay: {args.log}: no such file", file=sys.stderr)
        return 2
    try:
        frames = frames_from_log(args.log)
    except Exception as exc:  # noqa: BLE001 - python-can raises many kinds
        print(f"bench replay: {args.log}: cannot read as a CAN log: {exc}", file=sys.stderr)
        return 2
    if len(frames) == 0:
        print(f"bench replay: {args.log}: no frames", file=sys.stderr)
        return 2
    here = args.log.parent
    layout_path = args.layout or (here / "layout.json")
    layout = BusLayout.load(layout_path) if layout_path.exists() else default_layout()
    cap_path = here / "capture.json"
    cap = json.loads(cap_path.read_text()) if cap_path.exists() else {}
    pp = args.pole_pairs or int(cap.get("plant", {}).get("pole_pairs", 5))
    ts = args.ts or float(cap.get("plant", {}).get("Ts_s", 55e-6))
    out = args.out or here / "replay"
    out.mkdir(parents=True, exist_ok=True)
    tr = decode(frames, layout, pp, ts, recorded_references(frames, layout))
    save(out / "traces.npz", tr)
    steps = [m.to_dict() for sig in ("iq", "id") for m in step_metrics(tr[f"{sig}_A"], tr[f"{sig}_ref_A"], sig)]
    summary = {"log": str(args.log), "periods": int(len(tr["period"])), "frames": int(len(frames)),
               "layout": str(layout_path) if layout_path.exists() else "EDS defaults", "steps": steps,
               "bus_stats": check_continuity(tr)}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    step_plots(out, tr, steps, args.log.name)
    identification_plot(out, tr, args.log.name)
    viewer = Viewer(args.log.stem, out / "replay.rrd", serve=args.serve, spawn=False if args.no_viewer else None)
    viewer.log(tr)
    viewer.close()
    print(f"bench replay: {len(frames)} frames, {summary['periods']} periods decoded with {summary['layout']}")
    print(format_table({"steps": steps}))
    print(f"results in {out}/: summary.json, traces.npz, replay.rrd, *.png")
    _ = np
    return 0
