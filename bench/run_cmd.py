"""`bench run`: one scenario, end to end."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

from .scenario import Scenario, ScenarioError, load

LOG_FORMATS = ("log", "asc", "blf")


def default_out(sc: Scenario) -> Path:
    return Path("runs") / f"{sc.name}-{time.strftime('%Y%m%d-%H%M%S')}"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", type=Path, help="scenario TOML file (see scenarios/)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value with a dotted key following the TOML layout, "
                        "e.g. --set controller.L_hat_ratio=0.5 (repeatable)")
    p.add_argument("--bus", default="vcan0",
                   help="'direct' (in-process, no bus), or a CAN channel: vcan0 (default; the VM supplies it on "
                        "hosts without CAN), can0, ...")
    p.add_argument("--interface", default="socketcan", help="python-can interface for the bench's master "
                   "(default socketcan; the C nodes always use SocketCAN)")
    p.add_argument("--channel", dest="bus", default=argparse.SUPPRESS, help="alias of --bus for python-can users")
    p.add_argument("--bitrate", type=int, default=None, help="bit rate for interfaces that need one")
    p.add_argument("--fd", action="store_true", help="open the bus as CAN FD (python-can fd=True)")
    p.add_argument("--data-bitrate", type=int, default=None, help="CAN FD data-phase bit rate")
    p.add_argument("--no-plant", action="store_true", help="do not start the C plant (a physical plant is on the bus)")
    p.add_argument("--no-drive", action="store_true",
                   help="do not start the C drive (a physical drive implementing drive.eds is on the bus)")
    p.add_argument("--plant-id", type=lambda s: int(s, 0), default=0x10, help="plant node-ID (default 0x10)")
    p.add_argument("--drive-id", type=lambda s: int(s, 0), default=0x20, help="drive node-ID (default 0x20)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default runs/NAME-TIMESTAMP)")
    p.add_argument("--log-format", choices=LOG_FORMATS, default="log",
                   help="CAN log written by python-can: log (candump, default), asc, blf")
    p.add_argument("--serve", action="store_true", help="serve the Rerun web viewer")
    p.add_argument("--no-viewer", action="store_true", help="never spawn the Rerun viewer (the .rrd is still saved)")
    p.add_argument("--live-decimate", type=int, default=1, help="send every Nth period to the live viewer")


def _validate_ids(args: argparse.Namespace) -> None:
    for name in ("plant_id", "drive_id"):
        v = getattr(args, name)
        if not 1 <= v <= 127:
            raise ScenarioError(f"--{name.replace('_', '-')} = {v}: a node-ID is 1 .. 127")
    if args.plant_id == args.drive_id:
        raise ScenarioError("--plant-id and --drive-id must differ")


def run(args: argparse.Namespace) -> int:
    from .canbus import host_has_vcan

    try:
        sc = load(args.scenario, args.overrides)
        _validate_ids(args)
    except ScenarioError as exc:
        print(f"bench run: {exc}", file=sys.stderr)
        return 2
    out: Path = args.out or default_out(sc)
    if out.exists() and any(out.iterdir()):
        print(f"bench run: {out} exists and is not empty; choose another --out", file=sys.stderr)
        return 2
    partial = out.with_name(out.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    print(f"bench run: {sc.name}: {sc.periods} periods on bus {args.bus} ({sc.timing})")
    try:
        if args.bus != "direct" and args.interface == "socketcan" and not host_has_vcan(args.bus):
            if not args.bus.startswith("vcan"):
                raise RuntimeError(f"bus {args.bus}: this host has no SocketCAN; only vcan buses can be "
                                   "supplied by the VM fallback")
            rc = _capture_in_vm_with_live_view(args, sc, partial)
            if rc != 0:
                raise RuntimeError(f"the capture inside the VM failed with status {rc}")
        else:
            _capture_here(args, sc, partial)
        summary = _postprocess(args, sc, partial)
    except KeyboardInterrupt:
        print("bench run: interrupted; nodes and recorder stopped", file=sys.stderr)
        _discard(partial, out)
        return 130
    except Exception as exc:  # noqa: BLE001 - report every failure the same way
        print(f"bench run: FAILED: {exc}", file=sys.stderr)
        _discard(partial, out)
        return 1
    if out.exists():
        out.rmdir()
    partial.rename(out)
    _print_result(out, summary)
    return 0


def _discard(partial: Path, out: Path) -> None:
    failed = out.with_name(out.name + ".failed")
    shutil.rmtree(failed, ignore_errors=True)
    if partial.exists():
        partial.rename(failed)
        print(f"bench run: what was recorded is in {failed}", file=sys.stderr)


def _capture_here(args: argparse.Namespace, sc: Scenario, out: Path) -> None:
    from tqdm import tqdm

    from .runner import RunOptions, capture

    opts = RunOptions(bus=args.bus, interface=args.interface, bitrate=args.bitrate, fd=args.fd,
                      data_bitrate=args.data_bitrate, plant_id=args.plant_id,
                      drive_id=args.drive_id, start_plant=not args.no_plant, start_drive=not args.no_drive, out=out)
    with tqdm(total=sc.periods, unit="period", desc=sc.name, disable=not sys.stderr.isatty()) as bar:
        def progress(done: int, total: int) -> None:
            bar.update(done - bar.n)

        capture(sc, opts, progress)


def _live_wanted(args: argparse.Namespace) -> bool:
    import os

    return bool(args.serve or (not args.no_viewer and (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))))


def _capture_in_vm_with_live_view(args: argparse.Namespace, sc: Scenario, partial: Path) -> int:
    """The capture runs in the VM; the host follows its recording file and streams it live."""
    if not _live_wanted(args):
        return _capture_in_vm(args, partial)
    from .live import LiveTail
    from .viewer import Viewer

    viewer = Viewer(sc.name + "-live", partial / "live.rrd", serve=args.serve, spawn=not args.serve)
    tail = LiveTail(partial, lambda tr, a, b: viewer.log(tr, a, b, live_decimate=args.live_decimate))
    tail.start()
    try:
        return _capture_in_vm(args, partial)
    finally:
        tail.stop()
        viewer.close()


def _capture_in_vm(args: argparse.Namespace, partial: Path) -> int:
    from .vm import VmOptions, run_in_vm

    cmd = [sys.executable, "-m", "bench.cli", "capture", str(args.scenario.resolve()), "--bus", args.bus,
           "--out", str(partial.resolve()), "--plant-id", str(args.plant_id), "--drive-id", str(args.drive_id)]
    for o in args.overrides:
        cmd += ["--set", o]
    print("bench run: host kernel has no SocketCAN; capturing inside the virtme-ng VM (boot ~20 s)")
    return run_in_vm(cmd, VmOptions(timeout_s=3600, rwdirs=[partial.resolve().parent]))


def capture_only(args: argparse.Namespace) -> int:
    """`bench capture` (used inside the VM): run and record, no post-processing."""
    from .runner import RunOptions, capture

    try:
        sc = load(args.scenario, args.overrides)
    except ScenarioError as exc:
        print(f"bench capture: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    cap = capture(sc, RunOptions(bus=args.bus, plant_id=args.plant_id, drive_id=args.drive_id, out=args.out))
    print(f"bench capture: {cap.frames} frames, {sc.periods} periods in {cap.run_wall_s:.2f} s")
    return 0


def _postprocess(args: argparse.Namespace, sc: Scenario, out: Path) -> dict[str, object]:
    from .plots import identification_plot, step_plots
    from .results import summarize
    from .traces import load as load_traces
    from .viewer import Viewer

    summary = summarize(out, "." + args.log_format)
    tr = load_traces(out / "traces.npz")
    step_plots(out, tr, summary["steps"], sc.name)  # type: ignore[arg-type]
    identification_plot(out, tr, sc.name)
    viewer = Viewer(sc.name, out / "run.rrd", serve=args.serve, spawn=False if args.no_viewer else None)
    viewer.log(tr, live_decimate=args.live_decimate)
    viewer.close()
    return summary


def _print_result(out: Path, summary: dict[str, object]) -> None:
    from .results import format_table

    print(format_table(summary))
    ident = summary["identified"]
    bs = summary["bus_stats"]
    print(f"identified: K1_avg {ident['K1_avg_V_A']:.3f} V/A, K2_avg {ident['K2_avg_V_A']:.3f} V/A, "  # type: ignore[index]
          f"L_hat {ident['L_hat_H'] * 1e3:.4f} mH, active K1 {ident['K1_active_V_A']:.3f} V/A")  # type: ignore[index]
    print(f"bus: {bs['frames']} frames, {bs['lost_frames']} lost, missed commands {bs['plant_missed_commands']}, "  # type: ignore[index]
          f"late {bs['plant_late_commands']}")  # type: ignore[index]
    print(f"results in {out}/: summary.json, traces.npz, {summary['files']['log']}, run.rrd, *.png")  # type: ignore[index]
    _ = json  # summary.json already written
