"""`bench run`: one scenario end to end, and `bench capture` (its bus half, run inside the VM).

The result folder is built in NAME.partial and renamed when complete; a failed run is left in
NAME.failed; an existing folder is never touched. The exit status is the run's verdict
(bench/run/summary.py): 0 ok (or the status the scenario expects), 3 tripped, 4 diverged,
5 non-finite values, 6 frames lost, 7 expected status not reached; 1 failure, 2 bad input,
130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import threading
import time
from pathlib import Path
from typing import Any

from ..scenario import Scenario, ScenarioError, load
from .canlog import LOG_FORMATS
from .outputs import Outputs, print_result

CAPTURE_REFUSED = 65  # `bench capture` in the VM: a node refused a value of the scenario (EX_DATAERR)


def default_out(sc: Scenario) -> Path:
    return Path("runs") / f"{sc.name}-{time.strftime('%Y%m%d-%H%M%S')}"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", type=Path, help="scenario TOML file (see scenarios/)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario value with a dotted key following the TOML layout, "
        "e.g. --set controller.L_hat_ratio=0.5 (repeatable)",
    )
    p.add_argument(
        "--bus",
        default="vcan0",
        help="'direct' (in-process, no bus), or a CAN channel: vcan0 (default; the VM supplies it on "
        "hosts without CAN), can0, ...",
    )
    p.add_argument(
        "--interface",
        default="socketcan",
        help="python-can interface for the bench's master (default socketcan; the C nodes always use SocketCAN)",
    )
    p.add_argument("--channel", dest="bus", default=argparse.SUPPRESS, help="alias of --bus for python-can users")
    p.add_argument("--bitrate", type=int, default=None, help="bit rate for interfaces that need one")
    p.add_argument("--fd", action="store_true", help="open the bus as CAN FD (python-can fd=True)")
    p.add_argument("--data-bitrate", type=int, default=None, help="CAN FD data-phase bit rate")
    p.add_argument("--no-plant", action="store_true", help="do not start the C plant (a physical plant is on the bus)")
    p.add_argument(
        "--no-drive",
        action="store_true",
        help="do not start the C drive (a physical drive implementing drive.eds is on the bus)",
    )
    p.add_argument("--plant-id", type=lambda s: int(s, 0), default=0x10, help="plant node-ID (default 0x10)")
    p.add_argument("--drive-id", type=lambda s: int(s, 0), default=0x20, help="drive node-ID (default 0x20)")
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
    p.add_argument("--no-viewer", action="store_true", help="never spawn the Rerun viewer (the .rrd is still saved)")
    p.add_argument("--live-decimate", type=int, default=1, help="send every Nth period to the live viewer")


def _check_args(args: argparse.Namespace) -> None:
    for name in ("plant_id", "drive_id"):
        v = getattr(args, name)
        if not 1 <= v <= 127:
            raise ScenarioError(f"--{name.replace('_', '-')} = {v}: a node-ID is 1 .. 127")
    if args.plant_id == args.drive_id:
        raise ScenarioError("--plant-id and --drive-id must differ")
    if args.live_decimate < 1:
        raise ScenarioError(f"--live-decimate = {args.live_decimate}: must be >= 1")
    if args.serve_for is not None and (args.serve_for < 0 or not args.serve):
        raise ScenarioError("--serve-for needs --serve and a number of seconds >= 0")
    for port in ("web_port", "grpc_port"):
        if not 1 <= getattr(args, port) <= 65535:
            raise ScenarioError(f"--{port.replace('_', '-')} = {getattr(args, port)}: a port is 1 .. 65535")


def _bus_problem(args: argparse.Namespace) -> tuple[str | None, bool]:
    """(what is wrong with --bus, whether the VM supplies it)."""
    import re

    from ..canbus import can_interfaces, host_has_vcan, interface_state, probe_af_can

    if args.bus == "direct" or args.interface != "socketcan":
        return None, False
    virtual = re.fullmatch(r"vcan\d{1,3}", args.bus) is not None
    if not probe_af_can().af_can:
        if virtual:
            return None, True  # the VM creates it
        return (
            f"--bus {args.bus}: this host's kernel has no SocketCAN; the VM fallback supplies virtual buses "
            "only (--bus vcan0, vcan1, ...), or use --bus direct"
        ), False
    if virtual and host_has_vcan(args.bus):  # a vcan is made when missing (as root); a real bus never is
        return None, False
    state = interface_state(args.bus)
    cans = can_interfaces()
    buses = ", ".join(f"{n} ({s})" for n, s in cans) or "none"
    if state is not None and args.bus not in {n for n, _ in cans}:
        return f"--bus {args.bus}: a network interface, but not a CAN one; the CAN interfaces here: {buses}", False
    if not virtual and state == "up":
        return None, False
    if state is None:
        return (
            f"--bus {args.bus}: no such CAN interface; this machine has: {buses}"
            + ("" if virtual else "; or use --bus direct or a vcan name")
        ), False
    return f"--bus {args.bus}: the interface is {state} (bring it up: ip link set {args.bus} up)", False


def run(args: argparse.Namespace) -> int:
    return execute(args)[0]


def execute(args: argparse.Namespace) -> tuple[int, Any, Path | None]:
    """`bench run` with its parsed arguments: (exit status, RunResult or None, result folder or None)."""
    try:
        sc = load(args.scenario, args.overrides)
        _check_args(args)
        if args.bus == "direct" and sc.timing == "realtime":
            from .pipeline import DIRECT_IS_LOCKSTEP

            raise ScenarioError(DIRECT_IS_LOCKSTEP)
    except ScenarioError as exc:
        print(f"bench run: {exc}", file=sys.stderr)
        return 2, None, None
    problem, in_vm = _bus_problem(args)
    if problem:
        print(f"bench run: {problem}", file=sys.stderr)
        return 2, None, None
    out: Path = args.out or default_out(sc)
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
            result = _run_in_vm(args, sc, partial, outputs)
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
        from .session import SettingRefused

        if isinstance(exc, SettingRefused):  # bad input: said, and nothing left behind
            print(f"bench run: {exc}", file=sys.stderr)
            shutil.rmtree(partial, ignore_errors=True)
            return 2, None, None
        print(f"bench run: FAILED: {exc}", file=sys.stderr)
        _discard(partial, out)
        return 1, None, None
    # The loop is complete and decoded: from here on its results are kept, whatever comes.
    assert outputs is not None
    cut = _finish_keeping(outputs, result, partial)
    if out.exists():
        out.rmdir()
    partial.rename(out)
    print_result(out, result)
    if cut:
        print(
            f"bench run: the results were not all written; the run is complete and kept in {out} ({cut})",
            file=sys.stderr,
        )
        return (130 if cut.startswith("interrupted") else 1), result, out
    outputs.serve(args)
    return result.exit_code, result, out


def _finish_keeping(outputs: Outputs, result: Any, partial: Path) -> str | None:
    """Write the results of a complete run. A first Ctrl-C waits for them (said on the terminal); a
    second stops the writing, and what it did not get to is said (the summary is always written).
    Returns None, or what the second Ctrl-C left out."""
    import signal

    presses = [0]

    def on_sigint(signum: int, frame: Any) -> None:
        presses[0] += 1
        if presses[0] == 1:  # os.write: print() may be in use by the interrupted code
            os.write(
                2,
                b"\nbench run: the loop is complete; finishing its results (a few seconds). Ctrl-C "
                b"again stops now, keeping what is written.\n",
            )
            return
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a third press must not cut the saving below
        raise KeyboardInterrupt

    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, on_sigint) if main else None
    try:
        outputs.finish(result)
        return None
    except (KeyboardInterrupt, Exception) as exc:  # noqa: BLE001 - the run's data is kept whatever failed
        if main:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        why = "interrupted" if isinstance(exc, KeyboardInterrupt) else f"writing failed: {exc}"
        try:
            outputs.abort()
        finally:
            outputs.write_summary(result, complete=False)
        missing = [f for f in ("bus.log", "run.rrd") if not (partial / f).exists()]
        return f"{why}; the plots and the recording may be incomplete" + (
            f"; missing: {', '.join(missing)}" if missing else ""
        )
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


def _run_options(args: argparse.Namespace, out: Path) -> Any:
    from .session import RunOptions

    return RunOptions(
        bus=args.bus,
        interface=args.interface,
        bitrate=args.bitrate,
        fd=args.fd,
        data_bitrate=args.data_bitrate,
        plant_id=args.plant_id,
        drive_id=args.drive_id,
        start_plant=not args.no_plant,
        start_drive=not args.no_drive,
        out=out,
    )


def _run_here(args: argparse.Namespace, sc: Scenario, partial: Path, outputs: Outputs) -> Any:
    from .pipeline import run_scenario

    with outputs.progress(sc.periods, "run") as bar:
        return run_scenario(
            sc,
            _run_options(args, partial),
            sinks=outputs.sinks,
            frame_sinks=outputs.frame_sinks,
            progress=lambda done, total: bar.update(done - bar.n),
        )


def _run_in_vm(args: argparse.Namespace, sc: Scenario, partial: Path, outputs: Outputs) -> Any:
    """The bus half runs in the VM (`bench capture`: nodes, master, candump); the host follows
    candump's log on the shared folder and feeds the same pipeline as it grows (live view included)."""
    import uuid

    from ..paths import REPO
    from ..tools.vm import VmOptions, run_in_vm
    from .pipeline import Pipeline
    from .sources import LogFollower

    # The guest's /tmp is its own: stage the capture in the repository (always shared with the VM).
    stage = REPO / "build" / "capture" / uuid.uuid4().hex[:12]
    stage.mkdir(parents=True)
    pipe = Pipeline(args.plant_id, args.drive_id, outputs.sinks, outputs.frame_sinks, sc.expect)
    follower = LogFollower(stage / "candump.log")
    stop = threading.Event()
    errors: list[BaseException] = []

    def follow() -> None:
        try:
            while not stop.wait(0.5):
                pipe.feed(follower.drain())
                bar.update(pipe.periods - bar.n)
        except BaseException as exc:  # noqa: BLE001 - reported by the main thread
            errors.append(exc)

    cmd = [
        sys.executable,
        "-m",
        "bench.cli",
        "capture",
        str(args.scenario.resolve()),
        "--bus",
        args.bus,
        "--out",
        str(stage),
        "--plant-id",
        str(args.plant_id),
        "--drive-id",
        str(args.drive_id),
    ]
    for o in args.overrides:
        cmd += ["--set", o]
    print(
        "bench run: host kernel has no SocketCAN; the bus runs inside the virtme-ng VM (boot ~20 s); "
        "the host decodes candump's log as it grows",
        flush=True,
    )
    t0 = time.monotonic()
    try:
        with outputs.progress(sc.periods, "run (VM)") as bar:
            th = threading.Thread(target=follow, daemon=True, name="bench-follow")
            th.start()
            try:
                rc = run_in_vm(cmd, VmOptions(timeout_s=3600, interfaces=(args.bus,)), stdout=_Quiet())
            finally:
                stop.set()
                th.join()
            if errors:
                raise errors[0]
            if rc == CAPTURE_REFUSED:
                from .session import SettingRefused

                raise SettingRefused("a node refused a value of the scenario (the line above says which)")
            if rc != 0:
                raise RuntimeError(f"the capture inside the VM failed with status {rc}")
            pipe.feed(follower.drain(final=True))
            bar.update(pipe.periods - bar.n)
        if not (stage / "capture.json").exists():
            raise RuntimeError("the capture inside the VM ended without saying how (no capture.json)")
        cap = json.loads((stage / "capture.json").read_text())
        (stage / "capture.json").unlink(missing_ok=True)
    finally:  # what was recorded goes with the run (NAME.failed when it failed)
        for f in stage.iterdir():  # candump.log (-> bus.log) and the node processes' output
            shutil.move(str(f), partial / f.name)
        stage.rmdir()
    return pipe.finish(
        sc.name,
        args.bus,
        {"wall_s": time.monotonic() - t0, "run_wall_s": cap.get("run_wall_s", 0.0)},
        cap.get("stopped"),
    )


class _Quiet:
    """The VM's console: only the guest command's own lines that matter reach the user."""

    def write(self, text: str) -> None:
        for line in text.splitlines():
            if line.startswith(("bench ", "Traceback", "RuntimeError", "  File", "Error", "error")):
                sys.stderr.write(line + "\n")

    def flush(self) -> None:
        sys.stderr.flush()


def capture_only(args: argparse.Namespace) -> int:
    """`bench capture` (run inside the VM): configure, run and record candump.log; no decoding
    (the host does it). Writes capture.json with the run's wall time."""
    from .pipeline import capture_to_log
    from .session import RunOptions

    try:
        sc = load(args.scenario, args.overrides)
    except ScenarioError as exc:
        print(f"bench capture: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    opts = RunOptions(bus=args.bus, plant_id=args.plant_id, drive_id=args.drive_id, out=args.out)
    from .session import SettingRefused

    try:
        run_wall, stopped = capture_to_log(sc, opts)
    except SettingRefused as exc:  # bad input: the host exits 2
        print(f"bench capture: {exc}", file=sys.stderr)
        return CAPTURE_REFUSED
    except Exception as exc:  # noqa: BLE001 - one line the host shows (the VM's console is filtered)
        print(f"bench capture: FAILED: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    (args.out / "capture.json").write_text(json.dumps({"run_wall_s": run_wall, "pid": os.getpid(), "stopped": stopped}))
    if stopped:
        print(f"bench capture: stopped: {stopped['message']}")
    else:
        print(f"bench capture: {sc.periods} periods in {run_wall:.2f} s")
    return 0
