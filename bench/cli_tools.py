"""`bench` commands that look at the machine, the bus and the bench itself: doctor, vm, pingpong, plan, export, perf
(each its arguments and its handler; their rows of the command table, bench/commands.py, name them and say what
they are)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def cmd_doctor(args: argparse.Namespace) -> int:
    from bench.tools.doctor import report

    return report()


def cmd_vm(args: argparse.Namespace) -> int:
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


def vm_arguments(v: argparse.ArgumentParser) -> None:
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


def cmd_pingpong(args: argparse.Namespace) -> int:
    from bench.tools.pingpong import run_pingpong

    res = run_pingpong(args.iface, args.count)
    print(res.echo_output.strip())
    print(res.ping_output.strip())
    return 0 if res.bad == 0 and res.verified == res.frames else 1


def pingpong_arguments(pp: argparse.ArgumentParser) -> None:
    pp.add_argument("--iface", default="vcan0")
    pp.add_argument("--count", type=int, default=1000)


def cmd_plan(args: argparse.Namespace) -> int:
    from bench.tools.plan import format_plan, make_plan

    try:
        _plan_option_mix(args)
        if args.scenario is not None and args.from_log is not None:
            raise ValueError("--scenario and --from-log = both given: must be one (a scenario is run to make its log)")
        if args.scenario is not None:
            return _plan_from_scenario(args)
        if args.from_log is not None:
            return _plan_from_log(args)
        if args.overrides:
            raise ValueError("--set = given: must be used with --scenario")
        if args.latency_us or args.worst_case_stuffing:
            raise ValueError("--latency-us / --worst-case-stuffing = given: must be used with --from-log")
        ts = 55e-6 if args.ts is None else args.ts
        plan = make_plan(
            args.bitrate, ts, args.fd, args.data_bitrate, args.max_load, args.trace_pdos, args.trace_decimation,
            args.frames, args.period_mark,
        )  # fmt: skip
    except ValueError as exc:  # bad input: exit 2, as every command's; nothing written
        print(f"bench plan: {exc}", file=sys.stderr)
        return 2
    print(plan.to_json() if args.json else format_plan(plan))
    return 0


def _plan_option_mix(args: argparse.Namespace) -> None:
    """Options that mean nothing together are refused, never ignored."""
    if args.data_bitrate is not None and not args.fd:
        raise ValueError(f"--data-bitrate = {args.data_bitrate:g}: must be used with --fd (a classic bus has one rate)")
    if args.fd and args.data_bitrate is not None and args.data_bitrate < args.bitrate:
        raise ValueError(
            f"--data-bitrate = {args.data_bitrate:g}: must be >= --bitrate ({args.bitrate:g}; CAN FD switches up)"
        )
    frames_given = args.from_log is not None or args.scenario is not None
    if frames_given and (args.frames != "default" or args.period_mark != "sync"):
        raise ValueError(
            f"--frames = {args.frames}, --period-mark = {args.period_mark}: the frames of --from-log or --scenario are "
            "the run's own (with --scenario: --set frames.measurement=compact --set frames.period_mark=measurement)"
        )
    if args.period_mark == "measurement" and args.frames == "default":
        raise ValueError(
            "--period-mark = measurement: must be used with --frames compact or single_frame (the frame that marks it)"
        )
    if args.frames == "single_frame" and not args.fd:
        raise ValueError("--frames = single_frame: must be used with --fd (one 16-byte CAN FD frame)")
    if frames_given and (args.trace_pdos != 0 or args.trace_decimation != 1):
        raise ValueError(
            "--trace-pdos / --trace-decimation = given: the frames of --from-log or --scenario are the run's own "
            "(its trace PDOs included); use them without"
        )


def _latencies(given: list[str]) -> dict[str, float]:
    """--latency-us NODE=US (repeatable) as {node: seconds}."""
    out: dict[str, float] = {}
    for item in given:
        node, _, value = item.partition("=")
        try:
            us = float(value)
        except ValueError:
            us = float("nan")
        if node not in ("plant", "drive") or not (0 <= us <= 1e6):
            raise ValueError(f"--latency-us = {item}: must be NODE=US, NODE plant or drive, US in [0, 1e6]")
        out[node] = us * 1e-6
    return out


def _plan_from_scenario(args: argparse.Namespace) -> int:
    """The frames of the scenario's own PDO mapping (its trace PDOs, its events' SDO writes): a direct run of it
    (lockstep in this process's C library, a second for the 1 s scenario) into a folder removed afterwards, its
    bus.log simulated as --from-log's."""
    import subprocess
    import tempfile

    scenario = Path(args.scenario)
    if not scenario.is_file():
        raise ValueError(f"--scenario = {scenario}: must be a scenario file (no such file)")
    with tempfile.TemporaryDirectory(prefix="bench-plan-") as tmp:
        run = Path(tmp) / "run"
        sets = [a for kv in args.overrides for a in ("--set", kv)]
        cmd = [sys.executable, "-m", "bench.cli", "run", str(scenario), "--bus", "direct", "--no-viewer", *sets]
        res = subprocess.run([*cmd, "--out", str(run)], capture_output=True, text=True, timeout=3600)
        if not (run / "bus.log").is_file():
            raise ValueError(f"--scenario = {scenario}: its direct run wrote no bus.log: {res.stderr.strip()[-800:]}")
        print(f"bench plan: the frames of a direct run of {scenario} (status {res.returncode})", file=sys.stderr)
        args.from_log = run / "bus.log"
        return _plan_from_log(args)


def _plan_from_log(args: argparse.Namespace) -> int:
    from bench.tools.plan import make_plan
    from bench.tools.plan_log import format_log_plan, simulate
    from bench.tools.plan_periods import run_ts

    log = Path(args.from_log)
    if not log.is_file():
        raise ValueError(f"--from-log = {log}: must be a run's bus.log (no such file)")
    ts, ts_from = args.ts, "--ts"
    if ts is None:
        ts, ts_from = run_ts(log), f"{log.parent / 'summary.json'}"
    if ts is None:
        raise ValueError(f"--ts = none: must be given (no summary.json with Ts_s beside {log})")
    data_bitrate = args.data_bitrate if args.fd else None
    if args.fd and data_bitrate is None:
        raise ValueError("--data-bitrate = None: must be in (0, 12e6] bit/s with --fd")
    plan = simulate(
        log, args.bitrate, data_bitrate, ts, _latencies(args.latency_us or []), args.max_load,
        args.worst_case_stuffing, ts_from,
    )  # fmt: skip
    mark = "sync" if plan.mark == "SYNC" else "measurement"
    if (mark == "sync" or plan.frame_set != "default") and (args.fd or plan.frame_set != "single_frame"):
        plan.formula_s = make_plan(
            args.bitrate, ts, args.fd, data_bitrate, args.max_load, plan.extra_tpdos, 1, plan.frame_set, mark
        ).time_per_period_s
    print(plan.to_json() if args.json else format_log_plan(plan))
    return 0


def plan_arguments(pl: argparse.ArgumentParser) -> None:
    from bench.scenario.frames import MEASUREMENT_SETS, PERIOD_MARKS

    pl.add_argument("--bitrate", type=float, default=1e6, help="nominal bit rate, bit/s (default 1e6)")
    pl.add_argument("--fd", action="store_true", help="CAN FD with bit-rate switch")
    pl.add_argument("--data-bitrate", type=float, default=None, help="CAN FD data-phase bit rate, bit/s")
    pl.add_argument(
        "--ts",
        type=float,
        default=None,
        help="control period Ts, s (default 55e-6, You 2019; with --from-log: the run's summary.json Ts_s)",
    )
    pl.add_argument("--max-load", type=float, default=0.8, help="highest acceptable bus load (default 0.8)")
    pl.add_argument("--trace-pdos", type=int, default=0, help="live-trace PDOs added per period (default 0)")
    pl.add_argument("--trace-decimation", type=int, default=1, help="one trace PDO every N periods (default 1)")
    pl.add_argument(
        "--frames",
        choices=MEASUREMENT_SETS,
        default="default",
        help="the measurement's frame set (a scenario's [frames] measurement): default, the plant's TPDO1 {i_a_A, "
        "i_b_A} and TPDO2 {theta_m_rad, sync_counter, status, sample_index} as REAL32 values in two 8-byte frames; "
        "compact, one 8-byte frame {i_a_code, i_b_code, theta_code, sync_counter, status} of integer codes, exact "
        "for the plant's quantizing ADC and encoder; single_frame (with --fd), one 16-byte CAN FD frame of the "
        "default set's REAL32 values (docs/PHYSICAL_BUS.md)",
    )
    pl.add_argument(
        "--period-mark",
        choices=PERIOD_MARKS,
        default="sync",
        help="what marks a period (a scenario's [frames] period_mark): sync, the plant's SYNC (CiA 301); "
        "measurement (with --frames compact or single_frame), the one measurement frame with the SYNC counter "
        "inside: no SYNC frame on the bus",
    )
    pl.add_argument(
        "--from-log",
        metavar="RUN/bus.log",
        help="replay the frames a run sent onto a simulated physical bus at --bitrate (--fd: a classic run's "
        "frames as CAN FD frames with bit-rate switch at --data-bitrate; a CAN FD run's frames as it sent them): "
        "each frame's exact length from its identifier and payload (bit stuffing, CRC), arbitration by identifier, "
        "a period from each SYNC (or from the measurement frame that marks it): SYNC at its start, the plant's "
        "TPDOs when the SYNC has ended + the plant's latency, the drive's when the last measurement it consumes "
        "has ended + its latency, every other frame (SDO, heartbeat, EMCY) at the period start. Reports per period "
        "the bus time, whether the command ends before the next SYNC and the load: p50, p99, max, "
        "overruns. The frames before the first SYNC (configuration) and after the loop are left out",
    )
    pl.add_argument(
        "--scenario",
        metavar="FILE",
        help="the frames of this scenario's own PDO mapping (its trace PDOs, its events' SDO writes): the scenario "
        "runs in direct mode (no file kept) and its frames are simulated as with --from-log",
    )
    pl.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="with --scenario: override a scenario value, as bench run --set",
    )
    pl.add_argument(
        "--latency-us",
        action="append",
        metavar="NODE=US",
        help="with --from-log: a node's transmit latency, us, from the frame it reacts to until its frame is queued "
        "(NODE plant or drive; repeatable; default 0 for both: the bus alone)",
    )
    pl.add_argument(
        "--worst-case-stuffing",
        action="store_true",
        help="with --from-log: every frame at the worst case of bit stuffing (the formula's) instead of its exact bits",
    )
    pl.add_argument("--json", action="store_true", help="print one JSON object")


def cmd_export(args: argparse.Namespace) -> int:
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


def export_arguments(ex: argparse.ArgumentParser) -> None:
    ex.add_argument("log", type=Path, help="the log to read")
    ex.add_argument("dest", type=Path, help="the file to write (.log, .asc or .blf)")


def cmd_perf(args: argparse.Namespace) -> int:
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


def perf_arguments(pf: argparse.ArgumentParser) -> None:
    from bench.tools.perf import add_arguments

    add_arguments(pf)
