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
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bench.run import RunResult
    from bench.view.rerun_sink import RerunSink


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


class _Refused(Exception):
    """Bad input, said in one line on stderr (exit status 2)."""


def _inputs(args: argparse.Namespace) -> tuple[tuple[str, ...], Path]:
    """The input checked before anything is written: the log is a file; the statuses it is judged against
    (--expect, else the expect of summary.json beside the log, else ok); the output folder (--out, else
    LOG's folder/replay), which must not exist or be empty. _Refused says what is wrong."""
    import json

    if args.log.is_dir():
        hint = " (its CAN log is bus.log)" if (args.log / "bus.log").is_file() else ""
        raise _Refused(f"{args.log}: is a directory, not a CAN log{hint}")
    if not args.log.is_file():
        raise _Refused(f"{args.log}: no such file")
    from bench.scenario import STATUSES

    expect = args.expect
    beside = args.log.parent / "summary.json"
    if expect is None and beside.is_file():
        expect = json.loads(beside.read_text()).get("expect")
    expect = tuple(expect or ("ok",))
    bad = [e for e in expect if e not in STATUSES]
    if bad:
        raise _Refused(f"--expect {bad[0]}: expected one of {', '.join(STATUSES)}")
    out: Path = args.out or args.log.parent / "replay"
    from bench.paths import lost_in_vm

    if (lost := lost_in_vm(out)) is not None:
        raise _Refused(f"--out {lost}")
    if out.exists() and any(out.iterdir()):
        raise _Refused(f"{out} exists and is not empty; choose another --out")
    return expect, out


class _NoRecording:
    """The Rerun sink's place in a replay without the [view] extra: takes everything, writes nothing."""

    def begin(self, *a: Any, **k: Any) -> None: ...
    def write(self, *a: Any, **k: Any) -> None: ...
    def end(self, *a: Any, **k: Any) -> None: ...
    def close(self) -> None: ...
    def serve_until(self, *a: Any) -> None: ...


def _rerun_sink(args: argparse.Namespace, out: Path) -> RerunSink:
    """The Rerun recording out/run.rrd, with a live viewer: served (--serve), spawned (a display and no
    --no-viewer) or none."""
    import os

    from bench.extras import lacking, missing_extra

    live = "serve" if args.serve else ("spawn" if not args.no_viewer and os.environ.get("DISPLAY") else "none")
    if lacking("view") is not None:  # the plain install: the traces and the summary, no recording
        print(f"bench replay: no run.rrd: {missing_extra('view', 'a Rerun recording')}", file=sys.stderr)
        return _NoRecording()  # type: ignore[return-value]
    from bench.view.rerun_sink import RerunSink

    return RerunSink(
        args.log.name,
        out / "run.rrd",
        live=live,  # type: ignore[arg-type]
        web_port=args.web_port,
        grpc_port=args.grpc_port,
        bind=args.serve_bind,
    )


def _refuse(message: str, rerun: RerunSink, out: Path, created: bool) -> int:
    """Bad input found while decoding: nothing is left behind (the folder removed if replay made it, else
    emptied), the message on stderr, exit status 2."""
    import shutil

    rerun.close()
    if created:
        shutil.rmtree(out, ignore_errors=True)
    else:
        for f in out.iterdir():
            f.unlink()
    print(f"bench replay: {message}", file=sys.stderr)
    return 2


def _write_summary(out: Path, res: RunResult, name: str) -> None:
    """The step and overview plots, and summary.json naming the files written beside it."""
    import json

    from bench.run.sinks import TRACES_FILE
    from bench.view.plots import overview_plot, step_plots

    s = res.summary
    plots = step_plots(out, res.step_windows, s["steps"], name)
    ov = overview_plot(out, res.envelopes, name, s["Ts_s"])
    s["files"] = {
        "traces": TRACES_FILE,
        "recording": "run.rrd" if (out / "run.rrd").exists() else None,
        "plots": [p.name for p in plots] + ([ov.name] if ov else []),
    }
    (out / "summary.json").write_text(json.dumps(s, indent=2, default=str))


def main(args: argparse.Namespace) -> int:
    from bench.run.console import print_result
    from bench.run.pipeline import replay_log
    from bench.run.progress import Progress
    from bench.run.sinks import TRACES_FILE, TraceFileSink

    try:
        expect, out = _inputs(args)
    except _Refused as exc:
        print(f"bench replay: {exc}", file=sys.stderr)
        return 2
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    rerun = _rerun_sink(args, out)
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
        return _refuse(f"{args.log}: cannot decode: {exc}", rerun, out, created)
    bar.close()
    s = res.summary
    if s["periods"] == 0:
        return _refuse(f"{args.log}: {_nothing_to_decode(s)}", rerun, out, created)
    if s["log"]["sdo_transfers"] == 0:
        print(
            "bench replay: the log holds no SDO traffic (recorded after the configuration, or of another "
            f"master): decoded with the EDS defaults: the default PDO layout, pole pairs "
            f"{s['plant'].get('pole_pairs')}, Ts {s['Ts_s']:g} s",
            file=sys.stderr,
        )
    _write_summary(out, res, args.log.name)
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
