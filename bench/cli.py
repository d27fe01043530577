"""The `bench` command."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _cmd_doctor(args: argparse.Namespace) -> int:
    from bench.tools.doctor import report

    return report()


def _cmd_vm(args: argparse.Namespace) -> int:
    from bench.run.bus.vm import VmError, VmOptions, run_in_vm

    cmd = list(args.cmd)
    if cmd and cmd[0] == "--":
        cmd = cmd[1:]
    if not cmd:
        print("bench vm: give the command after `--`, e.g. `bench vm -- ip link show vcan0`", file=sys.stderr)
        return 64
    opts = VmOptions(
        cpus=args.cpus,
        memory=args.memory,
        timeout_s=args.timeout,
        kvm=args.kvm,
        interfaces=tuple(args.iface or ["vcan0"]),
        rwdirs=[Path(p) for p in args.rwdir or []],
        can_controllers=args.can_controllers,
    )
    if not 0 <= args.can_controllers <= 4:
        print(f"bench vm: --can-controllers = {args.can_controllers}: 0 .. 4", file=sys.stderr)
        return 64
    try:
        return run_in_vm(cmd, opts)
    except VmError as exc:
        print(f"bench vm: {exc}", file=sys.stderr)
        return 69


def _cmd_pingpong(args: argparse.Namespace) -> int:
    from bench.tools.pingpong import run_pingpong

    res = run_pingpong(args.iface, args.count)
    print(res.echo_output.strip())
    print(res.ping_output.strip())
    return 0 if res.bad == 0 and res.verified == res.frames else 1


def _cmd_plan(args: argparse.Namespace) -> int:
    from bench.tools.plan import format_plan, make_plan

    try:
        plan = make_plan(
            args.bitrate, args.ts, args.fd, args.data_bitrate, args.max_load, args.trace_pdos, args.trace_decimation
        )
    except ValueError as exc:  # bad input: exit 2, as every command's
        print(f"bench plan: {exc}", file=sys.stderr)
        return 2
    print(plan.to_json() if args.json else format_plan(plan))
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    if args.drive_profile == "cia402":
        from bench.cia402.command import run as run_cia402

        return run_cia402(args)
    from bench.run.command import run

    return run(args)


def _cmd_capture(args: argparse.Namespace) -> int:
    from bench.run.vm_run import capture_only

    return capture_only(args)


def _cmd_replay(args: argparse.Namespace) -> int:
    from bench.replay import main as replay_main

    return replay_main(args)


def _cmd_export(args: argparse.Namespace) -> int:
    from bench.run.record.canlog import LOG_FORMATS, export

    ext = args.dest.suffix.lstrip(".")
    if ext not in LOG_FORMATS:
        print(f"bench export: {args.dest}: the extension must be one of {', '.join(LOG_FORMATS)}", file=sys.stderr)
        return 2
    if not args.log.is_file():
        print(f"bench export: {args.log}: no such file", file=sys.stderr)
        return 2
    if args.dest.exists():
        print(f"bench export: {args.dest} exists; choose another name", file=sys.stderr)
        return 2
    n = export(args.log, args.dest)
    print(f"bench export: {n} frames written to {args.dest}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from bench.sweep import main as sweep_main

    return sweep_main(args)


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from bench.reproduce import main as reproduce_main

    return reproduce_main(args)


def _cmd_faults(args: argparse.Namespace) -> int:
    from bench.faults.command import main as faults_main

    return faults_main(args)


def _cmd_perf(args: argparse.Namespace) -> int:
    from bench.tools.perf import main as perf_main

    return perf_main(args)


def _cmd_demo(args: argparse.Namespace) -> int:
    from bench.demo import main as demo_main

    return demo_main(args)


def _law_option(p: argparse.ArgumentParser) -> None:
    """--law DIR, taken off the command line before parsing (_with_law); here for --help."""
    from bench.law import HELP

    p.add_argument("--law", type=Path, default=None, metavar="DIR", help=HELP)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="bench",
        description="Hardware-in-the-loop bench for PMSM deadbeat current control over CANopen "
        "(SocketCAN; a virtme-ng VM supplies vcan when the host kernel has no CAN).",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    d = sub.add_parser(
        "doctor",
        help="report kernel CAN, vcan0, VM fallback and tool versions",
        description="One screen: what the bench found, each problem with the command that fixes it. "
        "Exit 0 when CAN work can run (on the host or in the VM).",
    )
    d.set_defaults(func=_cmd_doctor)

    v = sub.add_parser(
        "vm",
        help="run a command inside the micro-VM with a real vcan0",
        description="Boot Debian's stock kernel under QEMU (virtme-ng), bring up vcan0, run CMD in the "
        "current directory (the repository and the current directory are shared "
        "read-write) and return CMD's exit status. Example: bench vm -- candump -n 1 vcan0",
    )
    v.add_argument("--cpus", type=int, default=2, help="guest CPUs (default 2)")
    v.add_argument("--memory", default="2G", help="guest memory (default 2G)")
    v.add_argument("--timeout", type=float, default=3600.0, help="seconds before the VM is killed (default 3600)")
    v.add_argument("--kvm", action="store_true", help="use KVM acceleration (off by default: it fails on many hosts)")
    v.add_argument("--iface", action="append", help="vcan interface to create (repeatable; default vcan0)")
    v.add_argument("--rwdir", action="append", help="extra host directory shared read-write (repeatable)")
    v.add_argument(
        "--can-controllers",
        type=int,
        default=0,
        metavar="N",
        help="also attach N emulated CAN controllers (QEMU kvaser_pci, SJA1000) on one emulated bus: can0 .. "
        "can{N-1}, link type can, down until given a bit rate (0 .. 4; default 0)",
    )
    v.add_argument("cmd", nargs=argparse.REMAINDER, help="-- CMD [ARGS...]")
    v.set_defaults(func=_cmd_vm)

    pp = sub.add_parser(
        "pingpong",
        help="C ping-pong between two processes on a CAN interface (needs SocketCAN)",
        description="Start an echo and a ping C process on IFACE, verify every answer, print "
        "round-trip statistics. Run it through `bench vm --` on hosts without CAN.",
    )
    pp.add_argument("--iface", default="vcan0")
    pp.add_argument("--count", type=int, default=1000)
    pp.set_defaults(func=_cmd_pingpong)

    pl = sub.add_parser(
        "plan",
        help="will the PDO set fit a real-time period on this bus?",
        description="Bits per control period of the configured PDO set (from the EDS files) with "
        "worst-case bit stuffing, bus load, whether Ts fits in real time, the fastest "
        "period that does, and what to change. Example: bench plan --bitrate 1000000 "
        "--ts 55e-6",
    )
    pl.add_argument("--bitrate", type=float, default=1e6, help="nominal bit rate, bit/s (default 1e6)")
    pl.add_argument("--fd", action="store_true", help="CAN FD with bit-rate switch")
    pl.add_argument("--data-bitrate", type=float, default=None, help="CAN FD data-phase bit rate, bit/s")
    pl.add_argument("--ts", type=float, default=55e-6, help="control period Ts, s (default 55e-6, You 2019)")
    pl.add_argument("--max-load", type=float, default=0.8, help="highest acceptable bus load (default 0.8)")
    pl.add_argument("--trace-pdos", type=int, default=0, help="live-trace PDOs added per period (default 0)")
    pl.add_argument("--trace-decimation", type=int, default=1, help="one trace PDO every N periods (default 1)")
    pl.add_argument("--json", action="store_true", help="print one JSON object")
    pl.set_defaults(func=_cmd_plan)

    from bench.run.command import add_arguments, exit_codes_help

    r = sub.add_parser(
        "run",
        help="run a scenario: configure by SDO, run, record every frame, summarize",
        description="Bring the bus up (host or VM), start the plant and drive processes, reset them "
        "by NMT, configure them by SDO from the EDS, run the scenario in lockstep, record "
        "every frame, and write summary.json, traces.npy, the CAN log, SVG plots and a "
        f"Rerun recording. The exit status is the run's verdict: {exit_codes_help()}. "
        "Example: bench run scenarios/you2019_step.toml --bus direct",
    )
    add_arguments(r)
    from bench.cia402.command import add_arguments as cia402_arguments

    cia402_arguments(r)
    _law_option(r)
    r.set_defaults(func=_cmd_run)
    # internal (the VM half of a run over a VM's bus): no `help`, so argparse lists no entry for it (a
    # help=argparse.SUPPRESS still lists "capture ==SUPPRESS==" in the command listing before Python 3.14)
    c = sub.add_parser("capture")
    c.add_argument("scenario", type=Path)
    c.add_argument("--set", dest="overrides", action="append", default=[])
    c.add_argument("--bus", default="vcan0")
    c.add_argument("--drive-bus", default=None)
    c.add_argument("--drive", choices=("node", "mcu"), default="node")
    c.add_argument("--drive-tty", default=None)
    c.add_argument("--bitrate", type=int, default=None)
    c.add_argument("--out", type=Path, required=True)
    from bench.eds import add_node_id_arguments

    add_node_id_arguments(c)
    c.set_defaults(func=_cmd_capture)

    from bench.replay import add_arguments as replay_args

    rp = sub.add_parser(
        "replay",
        help="decode a CAN log (candump/ASC/BLF, any bus) into traces and views",
        description="Decode any log python-can reads (candump .log, .asc, .blf) into traces.npy, "
        "summary.json, SVG plots and a Rerun recording, as the run did: the PDO layout, "
        "the plant's parameters and every setting come from the SDO traffic in the log "
        "(the EDS defaults when it has none, said so). The exit status is the verdict, "
        f"as for bench run: {exit_codes_help()}.",
    )
    replay_args(rp)
    _law_option(rp)
    rp.set_defaults(func=_cmd_replay)

    ex = sub.add_parser(
        "export",
        help="convert a CAN log (candump .log, .asc, .blf) to another format",
        description="Convert a CAN log: .asc (Vector ASCII) and .blf (Vector binary) with "
        "python-can's writers, .log (candump) with the bench's C writer. Example: "
        "bench export runs/x/bus.log runs/x/bus.blf",
    )
    ex.add_argument("log", type=Path, help="the log to read")
    ex.add_argument("dest", type=Path, help="the file to write (.log, .asc or .blf)")
    ex.set_defaults(func=_cmd_export)

    from bench.sweep import add_arguments as sweep_args

    sw = sub.add_parser(
        "sweep",
        help="robustness studies (grids, Monte Carlo, boundary search) in direct mode, on Dask",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Runs every point of a study as the scenario with --set overrides, in direct mode and in\n"
        "memory, on an embedded Dask LocalCluster (all cores) or an existing cluster (--scheduler).\n"
        "Rows stream to OUT/sweep.parquet; --resume continues a killed study.\n\n"
        "Examples:\n"
        "  bench sweep scenarios/you2019_step.toml --grid controller.L_hat_ratio=0.5:1.5:0.1 \\\n"
        "      --grid controller.R_hat_ratio=0.5,1.0,1.5             # heat-map of two keys\n"
        "  bench sweep scenarios/yao2020_identification.toml --sample controller.R_hat_ratio='normal(1,0.1)' \\\n"
        "      --samples 500 --seed 7                                 # Monte Carlo: percentiles\n"
        "  bench sweep scenarios/zhao2022_stability.toml --bisect controller.L_hat_ratio=1.25:1.6667 \\\n"
        "      --until 'error_growth_per_period>=1'                   # Zhao 2022's stability boundary\n",
    )
    sweep_args(sw)
    _law_option(sw)
    sw.set_defaults(func=_cmd_sweep)

    from bench.reproduce import add_arguments as reproduce_args

    rep = sub.add_parser(
        "reproduce",
        help="run every claim of the three papers and write a report",
        description="Runs, over vcan by default, a scenario for each quantitative claim of You 2019, "
        "Yao 2020 and Zhao 2022, and writes report.md, report.html and report.json with "
        "the paper's value, the bench's value, the tolerance and a verdict per claim.",
    )
    reproduce_args(rep)
    rep.set_defaults(func=_cmd_reproduce)

    from bench.faults.command import add_arguments as faults_args

    fl = sub.add_parser(
        "faults",
        help="inject each fault kind into the loop and judge the nodes' reactions (safe states, held "
        "commands, EMCYs, reaction times)",
        description="Runs the fault checks: each injects one fault (a dropped, delayed, duplicated, corrupted or "
        "reordered frame; a lost heartbeat; a frozen, killed or reset node) into the You 2019 loop, runs "
        "the same scenario without it, and judges the reaction against what a real drive and inverter "
        "must do (docs/FAULTS.md). Exit 0 when every check passes. To inject faults into your own "
        "scenario, give it [[faults]] tables and use bench run.",
    )
    faults_args(fl)
    _law_option(fl)
    fl.set_defaults(func=_cmd_faults)

    from bench.tools.perf import add_arguments as perf_args

    pf = sub.add_parser(
        "perf",
        help="benchmarks: what a user waits for (whole commands beside the loop and a peer "
        "simulator), cores, instruction counts, Cortex-M4F size, CANopen, vcan",
        description="Prints measured figures (never asserted), side by side in one run: the whole "
        "`bench run` process beside the loop's own rate, the Python API and "
        "gym-electric-motor on the same scenario (pipeline section, with its targets); "
        "plant and controller cost per period in-process, instruction counts under "
        "callgrind, Cortex-M4F code size, CANopen frame cost, and (unless --quick) "
        "lockstep periods/s over vcan beside the C ping-pong floor of the same frames, "
        "in one VM run. --only SECTION,... runs some sections.",
    )
    perf_args(pf)
    pf.set_defaults(func=_cmd_perf)

    dm = sub.add_parser(
        "demo",
        help="the headline demo (the README's main job)",
        description="You 2019 motor with L_hat = 0.5 L, a current-step train, online tuning switched "
        "on halfway, over vcan0 (VM if needed), recorded and shown in Rerun; ends with a "
        "before/after table and the paths of the results.",
    )
    dm.add_argument("--bus", default="vcan0", help="vcan0 (default) or direct")
    dm.add_argument("--out", type=Path, default=None, help="output folder (default runs/demo-TIMESTAMP)")
    dm.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    dm.add_argument("--serve", action="store_true", help="serve the Rerun web viewer")
    dm.add_argument(
        "--serve-bind",
        default="127.0.0.1",
        metavar="ADDR",
        help="with --serve: the address it listens on (default 127.0.0.1: this machine only)",
    )
    dm.add_argument("--no-viewer", action="store_true", help="do not spawn the Rerun viewer")
    dm.set_defaults(func=_cmd_demo)
    return p


def main(argv: list[str] | None = None) -> int:
    """The command: Ctrl-C exits 130 and SIGTERM 143 through the command's own cleanup, from the first
    instruction on (bench/stop.py); a closed stdout (`bench plan --json | head -1`) ends it quietly."""
    from bench import stop

    try:
        stop.install()
        rc = _main(sys.argv[1:] if argv is None else argv)
        sys.stdout.flush()  # a closed pipe is found here, not in the interpreter's exit
        return rc
    except KeyboardInterrupt:
        print("terminated" if stop.terminated() else "interrupted", file=sys.stderr)
        return stop.exit_status()
    except BrokenPipeError:
        _stdout_gone()
        return stop.EXIT_SIGPIPE  # as a shell reports a command ended by SIGPIPE
    finally:
        worker = sys.modules.get(f"{__package__}.view.worker")
        if worker is not None:
            with stop.deferred():
                worker.discard()  # viewer processes a run started and did not use: stopped now, not waited for
        try:
            sys.stdout.flush()  # what a SystemExit (argparse's --help, a usage error) left in the buffer
        except BrokenPipeError:
            _stdout_gone()


def _stdout_gone() -> None:
    """docs.python.org, "Note on SIGPIPE": the reader went away; nothing more can be shown, and Python's
    exit must not fail flushing the same stdout again: stdout becomes /dev/null."""
    import os

    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def _with_law(argv: list[str]) -> tuple[list[str], int]:
    """`--law DIR` of a command that runs the drive (bench/law.py): built, then BENCH_BUILD_DIR points the
    bench at its build; argv without it, and 0 or the exit status of a law that does not build."""
    import os

    from bench.law import LawBuildError, take_law, use

    try:
        law, argv = take_law(argv)
    except LawBuildError as exc:
        print(f"bench: {exc}", file=sys.stderr)
        return argv, 2
    if law is None or {"-h", "--help"} & set(argv):
        return argv, 0
    rc = use(law)
    if rc == 0 and "bench.paths" in sys.modules:  # something read the default build already: start afresh
        os.execv(sys.executable, [sys.executable, "-m", "bench.cli", *argv])
    return argv, rc


def _main(argv: list[str]) -> int:
    argv, rc = _with_law(argv)
    if rc:
        return rc
    if argv[:1] in (["run"], ["demo"]) and not {"-h", "--help"} & set(argv) and not _cia402(argv):
        from bench.view.worker import prestart

        prestart()  # the viewer and plot processes import rerun and matplotlib while we import the rest
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 64
    rc = int(args.func(args))
    if rc == 130:  # the command's own "interrupted": 143 when it was a SIGTERM
        from bench import stop

        rc = stop.exit_status()
    return rc


def _cia402(argv: list[str]) -> bool:
    """`bench run --drive-profile cia402` draws its own plot: no viewer processes."""
    return "--drive-profile=cia402" in argv or any(
        a == "--drive-profile" and b == "cia402" for a, b in zip(argv, argv[1:], strict=False)
    )


if __name__ == "__main__":
    sys.exit(main())
