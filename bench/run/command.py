"""`bench run`: one scenario end to end, and `bench capture` (its bus half, run inside the VM).

The result folder is built in NAME.partial and renamed when complete; a failed run is left in
NAME.failed; an existing folder is never touched. The exit status is the run's verdict, one code
per status (bench/run/verdict/summary.py's EXIT_CODES: exit_codes_help() lists them for --help); 0 also
for the status the scenario expects, 7 when it expected another; 1 failure, 2 bad input,
130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import threading
import time
from pathlib import Path
from typing import Any

from bench.eds import add_node_id_arguments
from bench.paths import lost_in_vm
from bench.run.bus.buses import bus_problem
from bench.run.console import print_result
from bench.run.motor_block import motor_block
from bench.run.outputs import Outputs
from bench.run.record.canlog import LOG_FORMATS
from bench.run.vm_run import run_in_vm_capture
from bench.scenario import (
    Scenario,
    ScenarioError,
    add_set_argument,
    load,
    scenario_path,
    unselected_law,
    unselected_python_law,
)


def default_out(sc: Scenario) -> Path:
    return Path("runs") / f"{sc.name}-{time.strftime('%Y%m%d-%H%M%S')}"


EXIT_FAILURE, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 1, 2, 130


def exit_codes_help() -> str:
    """The exit codes of a run, for --help, from the table that defines them (summary.EXIT_CODES)."""
    from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET

    codes = sorted(
        [*EXIT_CODES.items(), ("expected status not reached", EXIT_EXPECTATION_NOT_MET)], key=lambda kv: kv[1]
    )
    verdicts = ", ".join(f"{code} {name}" for name, code in codes)
    return (
        f"{verdicts} (0 also when the status is one the scenario expects); {EXIT_FAILURE} failure, "
        f"{EXIT_BAD_INPUT} bad input, {EXIT_INTERRUPTED} interrupted"
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    """`bench run`'s own options: the scenario, the bus and the nodes, then the outputs."""
    p.add_argument("scenario", type=scenario_path, help="scenario TOML file (see scenarios/)")
    add_set_argument(
        p,
        "override a scenario value with a dotted key following the TOML layout, "
        "e.g. --set controller.L_hat_ratio=0.5 (repeatable)",
    )
    p.add_argument(
        "--bus",
        default="vcan0",
        help="'direct' (in-process, no bus), or a CAN channel: vcan0 (default; on hosts without kernel CAN the "
        "CAN box supplies it: one VM booted once, `bench box`), can0, ...",
    )
    p.add_argument(
        "--box",
        action="store_true",
        help="run the vcan buses in the CAN box even where this host could carry them (also BENCH_BOX=1); "
        "without it the box is used only where the host cannot (no SocketCAN, or vcan cannot be made)",
    )
    p.add_argument(
        "--interface",
        default="socketcan",
        help="python-can interface for the bench's master (default socketcan; the C nodes always use SocketCAN)",
    )
    p.add_argument("--channel", dest="bus", default=argparse.SUPPRESS, help="alias of --bus for python-can users")
    p.add_argument(
        "--drive-bus",
        default=None,
        metavar="NAME",
        help="the drive node's own interface, another adapter on the same bus (a lab bench with two USB "
        "adapters: --bus can0 --drive-bus can1 puts the plant, master and recorder on can0 and the drive on "
        "can1; on hosts without CAN the VM supplies can0/can1 as emulated Kvaser PCIcan controllers on one "
        "emulated bus); default: the drive is on --bus. A scenario with [[faults]] puts the drive on a bus of "
        "its own, joined to --bus by the fault gateway (docs/FAULTS.md): vcanN+1 for --bus vcanN",
    )
    p.add_argument(
        "--drive",
        choices=("node", "mcu"),
        default="node",
        help="the drive firmware as: 'node', the Linux process build/bin/drive_node (default); 'mcu', the same "
        "sources built for a Cortex-M4F (make mcu) running under qemu-system-arm (mps2-an386), its CAN over "
        "its UART in SLCAN, joined to the bus by slcand and can-gw (processor in the loop; docs/PORTING.md)",
    )
    p.add_argument(
        "--bitrate",
        type=int,
        default=None,
        help="bit rate of a CAN controller link the bench brings up (ip link set canX type can bitrate ...; "
        "default 1000000 when the link has none); a link already up keeps its rate",
    )
    p.add_argument("--fd", action="store_true", help="open the bus as CAN FD (python-can fd=True)")
    p.add_argument("--data-bitrate", type=int, default=None, help="CAN FD data-phase bit rate")
    p.add_argument("--no-plant", action="store_true", help="do not start the C plant (a physical plant is on the bus)")
    p.add_argument(
        "--no-drive",
        action="store_true",
        help="do not start the C drive (a physical drive implementing drive.eds is on the bus)",
    )
    p.add_argument(
        "--py-law",
        default=None,
        metavar="FILE.py:CLASS",
        help="a current law prototyped in Python, in place of the registered law its class's `law` names (its record "
        "configures it): a class with the C interface's face, called each period in the direct loop (--bus "
        "direct only; docs/YOUR_CONTROLLER.md 'Prototype in Python first'); also module:CLASS",
    )
    add_node_id_arguments(p)
    _output_arguments(p)


def _output_arguments(p: argparse.ArgumentParser) -> None:
    """Where a run's results go and how they are shown: the folder, the log formats, the live viewer."""
    p.add_argument(
        "--out", type=Path, default=None, help="output folder (default runs/NAME-TIMESTAMP); must not exist or be empty"
    )
    p.add_argument(
        "--log-format",
        choices=LOG_FORMATS,
        action="append",
        default=None,
        help="CAN log formats to write besides bus.log (candump, always written): asc, blf "
        "(python-can's writers; slow for long runs). Repeatable",
    )
    p.add_argument(
        "--serve",
        action="store_true",
        help="serve the Rerun web viewer: prints the address a browser opens, streams while the run "
        "goes, and keeps serving after it until Ctrl-C (or --serve-for)",
    )
    p.add_argument(
        "--serve-for",
        type=float,
        default=None,
        metavar="SECONDS",
        help="with --serve: stop serving this many seconds after the run (default: until Ctrl-C)",
    )
    p.add_argument("--web-port", type=int, default=9090, help="web viewer port for --serve (default 9090)")
    p.add_argument("--grpc-port", type=int, default=9876, help="Rerun gRPC port for --serve (default 9876)")
    p.add_argument(
        "--serve-bind",
        default="127.0.0.1",
        metavar="ADDR",
        help="with --serve: the address both ports listen on (default 127.0.0.1: this machine only; "
        "0.0.0.0 or :: lets anyone on the network watch the run)",
    )
    p.add_argument("--no-viewer", action="store_true", help="never spawn the Rerun viewer (the .rrd is still saved)")
    p.add_argument(
        "--live-decimate",
        type=int,
        default=None,
        metavar="N",
        help="send every Nth period to the live viewer; default: a min/max envelope of every signal, ~1000 buckets "
        "a second of wall time whatever the run's rate, so the viewer keeps up (run.rrd has every period either "
        "way; a viewer that falls behind loses live rows, counted in summary.json live_view, never holds up the run)",
    )
    p.add_argument(
        "--no-rrd",
        action="store_true",
        help="do not write run.rrd, the Rerun recording (a live viewer, --serve or spawned, still shows the run; "
        "bench replay of bus.log makes the recording later); with --no-plots and no live viewer the run starts no "
        "helper process and imports neither rerun nor pygal",
    )
    p.add_argument("--no-plots", action="store_true", help="do not write the SVG plots")


def _check_args(args: argparse.Namespace) -> None:
    for name in ("plant_id", "drive_id"):
        v = getattr(args, name)
        if not 1 <= v <= 127:
            raise ScenarioError(f"--{name.replace('_', '-')} = {v}: a node-ID is 1 .. 127")
    if args.plant_id == args.drive_id:
        raise ScenarioError("--plant-id and --drive-id must differ")
    if args.live_decimate is not None and args.live_decimate < 1:
        raise ScenarioError(f"--live-decimate = {args.live_decimate}: must be >= 1")
    if args.serve_for is not None and (args.serve_for < 0 or not args.serve):
        raise ScenarioError("--serve-for needs --serve and a number of seconds >= 0")
    if args.serve:
        from bench.view.serve import check_bind

        try:
            check_bind(args.serve_bind)
        except ValueError as exc:
            raise ScenarioError(str(exc)) from None
    for port in ("web_port", "grpc_port"):
        if not 1 <= getattr(args, port) <= 65535:
            raise ScenarioError(f"--{port.replace('_', '-')} = {getattr(args, port)}: a port is 1 .. 65535")


def _python_law(args: argparse.Namespace, sc: Scenario) -> None:
    """--py-law FILE.py:CLASS (or bench.api.run's object, args.py_law_obj): loaded and checked against the build's
    laws (bench/law_py.py), before anything is written; the direct bus only."""
    if getattr(args, "py_law_obj", None) is None and getattr(args, "py_law", None) is None:
        return
    from bench.law_py import LawError, checked
    from bench.run.bus.buses import bus_of_args

    if not bus_of_args(args).in_process:
        raise ScenarioError(f"--py-law runs in the direct loop only: --bus direct, not --bus {args.bus}")
    try:
        args.py_law_obj = checked(getattr(args, "py_law_obj", None), args.py_law)
    except LawError as exc:
        raise ScenarioError(str(exc)) from None
    if (unselected := unselected_python_law(sc, args.py_law_obj.law)) is not None:
        raise ScenarioError(unselected)


def run(args: argparse.Namespace) -> int:
    return execute(args)[0]


def execute(args: argparse.Namespace, given: Scenario | None = None) -> tuple[int, Any, Path | None]:
    """`bench run` with its parsed arguments: (exit status, RunResult or None, result folder or None). `given`: the
    scenario already loaded (bench.api.run's, from a dict or a Scenario), instead of args.scenario's file."""
    try:
        sc = given if given is not None else load(args.scenario, args.overrides)
        if (unselected := unselected_law([sc])) is not None:
            raise ScenarioError(unselected)
        _check_args(args)
        _python_law(args, sc)
    except ScenarioError as exc:
        print(f"bench run: {exc}", file=sys.stderr)
        return 2, None, None
    motor = motor_block(sc)  # the files as the scenario's load read them, not as they are at the run's end
    problem, in_vm = bus_problem(args)
    if problem:
        print(f"bench run: {problem}", file=sys.stderr)
        return 2, None, None
    out: Path = args.out or default_out(sc)
    if (lost := lost_in_vm(out)) is not None:
        print(f"bench run: --out {lost}", file=sys.stderr)
        return 2, None, None
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        print(f"bench run: {out} exists and is not an empty folder; choose another --out", file=sys.stderr)
        return 2, None, None
    partial = out.with_name(out.name + ".partial")
    if partial.exists():
        print(
            f"bench run: {partial} exists (another run writing there, or left by a crash); remove it or "
            "choose another --out",
            file=sys.stderr,
        )
        return 2, None, None
    partial.mkdir(parents=True)
    print(f"bench run: {sc.name}: {sc.periods} periods on bus {args.bus} ({sc.timing})", flush=True)
    outputs: Outputs | None = None
    try:
        outputs = Outputs(partial, sc, args)
        if in_vm:
            result = run_in_vm_capture(args, sc, partial, outputs)
        else:
            result = _run_here(args, sc, partial, outputs)
    except KeyboardInterrupt:
        if outputs is not None:
            outputs.abort()
        print("bench run: interrupted; nodes and recorder stopped", file=sys.stderr)
        _discard(partial, out)
        return 130, None, None
    except Exception as exc:  # noqa: BLE001 - report every failure the same way
        if outputs is not None:
            outputs.abort()
        from bench.canbus import LinkError
        from bench.run.loop.configure import SettingRefused

        if isinstance(exc, SettingRefused | LinkError):  # bad input or a link not usable: said, nothing left
            print(f"bench run: {exc}", file=sys.stderr)
            shutil.rmtree(partial, ignore_errors=True)
            return 2, None, None
        print(f"bench run: FAILED: {exc}", file=sys.stderr)
        _discard(partial, out)
        return 1, None, None
    except BaseException:  # in a caller's process (bench/cli_in_process.py): a test cancelled, a SystemExit
        if outputs is not None:
            outputs.abort()
        _discard(partial, out)
        raise
    # The loop is complete and decoded: from here on its results are kept, whatever comes.
    assert outputs is not None
    result.summary["motor"] = motor
    # in the caller's process (bench/cli_in_process.py) a Ctrl-C is the caller's: it stops the writing at once
    cut, pending = _finish_keeping(outputs, result, partial, own_sigint=not getattr(args, "in_caller", False))
    if out.exists():
        out.rmdir()
    partial.rename(out)
    print_result(out, result)
    if cut:
        print(
            f"bench run: the results were not all written; the run is complete and kept in {out} ({cut})",
            file=sys.stderr,
        )
        if pending is not None:  # the caller's (a cancelled test): its folder kept, then its exception
            raise pending
        return (130 if cut.startswith("interrupted") else 1), result, out
    if outputs.interrupted:  # Ctrl-C while the results were written: they are, and serving is not wanted
        outputs.abort()
    else:
        outputs.serve(args)
    return result.exit_code, result, out


def _finish_keeping(
    outputs: Outputs, result: Any, partial: Path, own_sigint: bool = True
) -> tuple[str | None, BaseException | None]:
    """Write the results of a complete run. A first Ctrl-C waits for them (said on the terminal); a
    second stops the writing, and what it did not get to is said (the summary is always written). Without
    `own_sigint` (a run in the caller's process) the first Ctrl-C stops the writing. Returns None or what the
    Ctrl-C left out, and an exception of the caller's that stopped the writing (pytest's cancel: bench/pytest_plugin/
    cancel.py), for the caller to raise again once the folder is complete."""
    import signal

    presses = [0]

    def on_sigint(signum: int, frame: Any) -> None:
        presses[0] += 1
        outputs.interrupted = True
        if presses[0] == 1:  # os.write: print() may be in use by the interrupted code
            os.write(
                2,
                b"\nbench run: the loop is complete; finishing its results (a few seconds). Ctrl-C "
                b"again stops now, keeping what is written.\n",
            )
            return
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a third press must not cut the saving below
        raise KeyboardInterrupt

    main = own_sigint and threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, on_sigint) if main else None
    try:
        outputs.finish(result)
        return None, None
    except BaseException as exc:  # noqa: BLE001 - the run's data is kept whatever failed
        if main:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        why = "interrupted" if isinstance(exc, KeyboardInterrupt) else f"writing failed: {exc}"
        if not isinstance(exc, KeyboardInterrupt | Exception):
            why = f"stopped by the caller ({type(exc).__name__}: {exc})"
        try:
            outputs.abort()
        finally:
            outputs.write_summary(result, complete=False)
        missing = [f for f in ("bus.log", "run.rrd") if not (partial / f).exists()]
        pending = None if isinstance(exc, KeyboardInterrupt | Exception) else exc
        return f"{why}; the plots and the recording may be incomplete" + (
            f"; missing: {', '.join(missing)}" if missing else ""
        ), pending
    finally:
        if main:
            signal.signal(signal.SIGINT, old)


def _discard(partial: Path, out: Path) -> None:
    failed = out.with_name(out.name + ".failed")
    if failed.exists():
        n = 2
        while out.with_name(f"{out.name}.failed-{n}").exists():
            n += 1
        failed = out.with_name(f"{out.name}.failed-{n}")
    if partial.exists():
        partial.rename(failed)
        print(f"bench run: what was recorded is in {failed}", file=sys.stderr)


def _run_here(args: argparse.Namespace, sc: Scenario, partial: Path, outputs: Outputs) -> Any:
    from bench.run.options import run_options
    from bench.run.pipeline import run_scenario

    with outputs.progress(sc.periods, "run") as bar:
        return run_scenario(
            sc,
            run_options(args, partial),
            sinks=outputs.sinks,
            frame_sinks=outputs.frame_sinks,
            progress=lambda done, total: bar.update(done - bar.n),
        )
