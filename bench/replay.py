"""`bench replay LOG`: decode any CAN log python-can reads (candump .log, .asc, .blf; from
vcan or a physical bus) into the same traces, summary, plots and Rerun view as a run.

Nothing is assumed silently: the PDO layout, the plant's parameters (pole pairs, Ts), the
settings with their periods and the statuses read at the end are all SDO transfers in the
log (bench/run/decode/sdo_log.py). A log without that traffic (recorded after the configuration,
or of another master) is decoded with the EDS defaults, and replay says so.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def add_arguments(p: argparse.ArgumentParser) -> None:
    from bench.eds import add_node_id_arguments  # here: bench.eds imports canopen

    p.add_argument("log", type=Path, help="CAN log (.log candump, .asc, .blf, ...)")
    add_node_id_arguments(p)
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default: LOG's folder/replay); must not exist or be empty",
    )
    p.add_argument(
        "--expect",
        action="append",
        default=None,
        metavar="STATUS",
        help="the status the recorded run was meant to end with (as the scenario's expect; repeatable); "
        "default: the expect of summary.json beside the log, else ok",
    )
    p.add_argument("--no-viewer", action="store_true", help="never spawn the Rerun viewer")
    p.add_argument("--serve", action="store_true", help="serve the Rerun web viewer (until Ctrl-C or --serve-for)")
    p.add_argument("--serve-for", type=float, default=None, metavar="SECONDS")
    p.add_argument("--web-port", type=int, default=9090)
    p.add_argument("--grpc-port", type=int, default=9876)
    p.add_argument("--serve-bind", default="127.0.0.1", metavar="ADDR", help="with --serve: the address it listens on")


def main(args: argparse.Namespace) -> int:
    import json
    import os
    import shutil

    from bench.run.outputs import Progress, print_result
    from bench.run.pipeline import replay_log
    from bench.run.sinks import TRACES_FILE, TraceFileSink
    from bench.view.plots import overview_plot, step_plots
    from bench.view.rerun_sink import RerunSink

    if args.log.is_dir():
        hint = " (its CAN log is bus.log)" if (args.log / "bus.log").is_file() else ""
        print(f"bench replay: {args.log}: is a directory, not a CAN log{hint}", file=sys.stderr)
        return 2
    if not args.log.is_file():
        print(f"bench replay: {args.log}: no such file", file=sys.stderr)
        return 2
    from bench.scenario import STATUSES

    expect = args.expect
    beside = args.log.parent / "summary.json"
    if expect is None and beside.is_file():
        expect = json.loads(beside.read_text()).get("expect")
    expect = tuple(expect or ("ok",))
    bad = [e for e in expect if e not in STATUSES]
    if bad:
        print(f"bench replay: --expect {bad[0]}: expected one of {', '.join(STATUSES)}", file=sys.stderr)
        return 2
    out: Path = args.out or args.log.parent / "replay"
    from bench.paths import lost_in_vm

    if (lost := lost_in_vm(out)) is not None:
        print(f"bench replay: --out {lost}", file=sys.stderr)
        return 2
    if out.exists() and any(out.iterdir()):
        print(f"bench replay: {out} exists and is not empty; choose another --out", file=sys.stderr)
        return 2
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)

    def refuse(message: str) -> int:  # bad input: nothing is left behind
        rerun.close()
        if created:
            shutil.rmtree(out, ignore_errors=True)
        else:
            for f in out.iterdir():
                f.unlink()
        print(f"bench replay: {message}", file=sys.stderr)
        return 2

    live = "serve" if args.serve else ("spawn" if not args.no_viewer and os.environ.get("DISPLAY") else "none")
    rerun = RerunSink(
        args.log.name,
        out / "run.rrd",
        live=live,  # type: ignore[arg-type]
        web_port=args.web_port,
        grpc_port=args.grpc_port,
        bind=args.serve_bind,
    )
    est_frames = max(1, args.log.stat().st_size // 33)  # a candump line is ~33 bytes: an estimate for the bar
    bar = Progress(est_frames, f"replay {args.log.name}", unit="frames")
    try:
        res = replay_log(
            args.log,
            args.plant_id,
            args.drive_id,
            sinks=[TraceFileSink(out / TRACES_FILE), rerun],
            expect=expect,
            progress=bar.update,
        )
    except Exception as exc:  # noqa: BLE001 - python-can raises many kinds
        bar.close()
        return refuse(f"{args.log}: cannot decode: {exc}")
    bar.close()
    s = res.summary
    if s["periods"] == 0:
        return refuse(f"{args.log}: {_nothing_to_decode(s)}")
    if s["log"]["sdo_transfers"] == 0:
        print(
            "bench replay: the log holds no SDO traffic (recorded after the configuration, or of another "
            f"master): decoded with the EDS defaults: the default PDO layout, pole pairs "
            f"{s['plant'].get('pole_pairs')}, Ts {s['Ts_s']:g} s",
            file=sys.stderr,
        )
    plots = step_plots(out, res.step_windows, s["steps"], args.log.name)
    ov = overview_plot(out, res.envelopes, args.log.name, s["Ts_s"])
    s["files"] = {
        "traces": TRACES_FILE,
        "recording": "run.rrd",
        "plots": [p.name for p in plots] + ([ov.name] if ov else []),
    }
    (out / "summary.json").write_text(json.dumps(s, indent=2, default=str))
    print(f"bench replay: {s['bus_stats']['frames']} frames, {s['periods']} periods decoded; {_left_out(s['log'])}")
    print_result(out, res)
    if args.serve:
        rerun.serve_until(args.serve_for)
    rerun.close()
    return res.exit_code


def _left_out(log: dict[str, Any]) -> str:
    """What the log held that was not decoded: skipped frames, unparsable lines, a cut last line."""
    parts = [
        f"{log['frames_skipped']} frames skipped (not 11-bit data frames"
        + (f"; {log['extended_frames']} extended-ID" if log.get("extended_frames") else "")
        + ")"
    ]
    if log.get("unparsable_lines"):
        parts.append(
            f"{log['unparsable_lines']} unparsable lines (no candump frame; the first at line "
            f"{log['first_unparsable_line']})"
        )
    cut = log.get("truncated_line")
    if cut:
        parts.append(
            f"the log is TRUNCATED: it ends mid-line at line {cut} (no end of line; "
            + ("that line does not parse: dropped)" if log.get("truncated_line_dropped") else "its frame kept)")
        )
    return "; ".join(parts)


def _nothing_to_decode(s: dict[str, Any]) -> str:
    """Why a log gave no period: what it held instead."""
    log, frames = s["log"], s["bus_stats"]["frames"]
    if frames == 0 and log.get("extended_frames"):
        what = (
            f"it holds {log['extended_frames']} extended-ID (29-bit) frames and no 11-bit CANopen frame "
            "(CANopen's PDOs, SYNC and SDOs use 11-bit identifiers)"
        )
    elif frames == 0:
        what = "it holds no 11-bit CANopen frame"
    else:
        what = f"no SYNC found among its {frames} 11-bit frames"
    return f"{what}: nothing to decode ({_left_out(log)})"
