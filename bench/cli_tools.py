"""`bench` commands that look at the machine, the bus and the bench itself: doctor, vm, pingpong, plan, export, perf
(each its parser and its handler; bench/cli.py puts them together)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def _cmd_doctor(args: argparse.Namespace) -> int:
    from bench.tools.doctor import report

    return report()


def add_doctor(sub: Any) -> None:
    d = sub.add_parser(
        "doctor",
        help="report kernel CAN, vcan0, VM fallback and tool versions",
        description="One screen: what the bench found, each problem with the command that fixes it. "
        "Exit 0 when CAN work can run (on the host or in the VM).",
    )
    d.set_defaults(func=_cmd_doctor)


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


def add_vm(sub: Any) -> None:
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


def _cmd_pingpong(args: argparse.Namespace) -> int:
    from bench.tools.pingpong import run_pingpong

    res = run_pingpong(args.iface, args.count)
    print(res.echo_output.strip())
    print(res.ping_output.strip())
    return 0 if res.bad == 0 and res.verified == res.frames else 1


def add_pingpong(sub: Any) -> None:
    pp = sub.add_parser(
        "pingpong",
        help="C ping-pong between two processes on a CAN interface (needs SocketCAN)",
        description="Start an echo and a ping C process on IFACE, verify every answer, print "
        "round-trip statistics. Run it through `bench vm --` on hosts without CAN.",
    )
    pp.add_argument("--iface", default="vcan0")
    pp.add_argument("--count", type=int, default=1000)
    pp.set_defaults(func=_cmd_pingpong)


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


def add_plan(sub: Any) -> None:
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


def add_export(sub: Any) -> None:
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


def _cmd_perf(args: argparse.Namespace) -> int:
    from bench.root import INSTALLED
    from bench.tools.perf import main as perf_main

    if INSTALLED:
        print(
            "bench perf: measures the bench in a clone of its repository (it builds the peers with scripts/peers.sh "
            "and keeps its files in build/perf): run it there, not from an installed package",
            file=sys.stderr,
        )
        return 2

    return perf_main(args)


def add_perf(sub: Any) -> None:
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
        "in one VM run; real time (realtime section): 10^6 periods of `bench run` in direct real time at 100 and "
        "55 us beside cyclictest at the same interval and priority (SYNC lateness p50/p99/p99.9/max, overruns, the "
        "ratio). --only SECTION,... runs some sections.",
    )
    perf_args(pf)
    pf.set_defaults(func=_cmd_perf)
