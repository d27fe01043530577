"""`bench run SCENARIO --drive-profile cia402`: the bench as the CiA 402 master of any drive.

Exit status: 0 done and the drive seen SWITCH ON DISABLED at the end; 1 drive fault, refusal,
silence, or a drive not seen disabled at the end; 2 bad input (nothing touched, nothing written);
130 SIGINT; 143 SIGTERM.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bench.cia402 import NO_LOCKSTEP, cia402_bus
from bench.cia402.outcome import Interrupted, summary_text
from bench.cia402.plan import PlanError, Segment, choose_cycle, ignored_keys, targets
from bench.eds import eds_path
from bench.paths import lost_in_vm
from bench.scenario import Scenario, ScenarioError, load

HELP = (
    "--drive-profile cia402: the bench is the CiA 402 master of a drive it did not build (no plant node, "
    f"{NO_LOCKSTEP}). It sets the controlword to 0, NMT pre-operational, reads 0x6075/0x6076/0x6502 (CST "
    "must be supported)/0x1005/0x1019/0x6072, uses the drive's PDO mapping of controlword + target torque "
    "and statusword or maps them itself (RPDO {0x6040, 0x6071}, TPDO {0x6041, 0x6061, 0x6077, 0x6078} and "
    "{0x6064, 0x606C} on SYNC), selects mode 10 (CST), makes the drive watch the bench's heartbeat (node "
    "0x7F, 100 ms; a free 0x1016 entry, 500 ms), starts SYNC and the RPDO as CAN_BCM periodic tasks, NMT "
    "start, walks the drive to OPERATION ENABLED and plays the scenario's references.iq_ref_A as target "
    "torque (per mille = iq_ref / rated current x 1000; one scenario period = one cycle). On every way out "
    "(end, fault, Ctrl-C, SIGTERM) controlword 0 by RPDO and SDO, the statusword read back, the 0x1016 "
    "entry cleared, the tasks stopped, NMT pre-operational. Writes bus.log, trace.csv, overview.png, "
    "summary.json. Exit 0 done and drive disabled; 1 fault/refusal/silence/not disabled; 2 bad input; "
    "130 SIGINT; 143 SIGTERM"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--drive-profile",
        choices=("hil", "cia402"),
        default="hil",
        help="'hil' (default): the project's plant and drive nodes in lockstep. " + HELP,
    )
    p.add_argument(
        "--drive-eds",
        type=Path,
        default=None,
        help="with --drive-profile cia402: the drive's EDS (default protocols/eds/drive.eds)",
    )
    p.add_argument(
        "--cycle-ms",
        type=float,
        default=None,
        help="with --drive-profile cia402: the SYNC cycle, 1 .. 1000 ms (default: the shortest of 1, 2, 5, "
        "10 ms whose bus load at --bitrate, worst-case stuffing, is <= 80 %%)",
    )


def _out(args: argparse.Namespace, sc: Scenario) -> Path:
    return args.out or Path("runs") / f"{sc.name}-cia402-{time.strftime('%Y%m%d-%H%M%S')}"


def validate(args: argparse.Namespace) -> tuple[Scenario, float, float, list[Segment], Path, Path]:
    """Everything checked before the drive is touched; ScenarioError/PlanError = exit 2."""
    from bench.cia402.master import BENCH_ID

    if not 1 <= args.drive_id <= 127:
        raise PlanError(f"--drive-id = {args.drive_id}: a node-ID is 1 .. 127")
    if args.drive_id == BENCH_ID:
        raise PlanError(f"--drive-id 0x{BENCH_ID:02X} is the bench's own heartbeat node-ID")
    if cia402_bus(args).in_process:
        raise PlanError("--drive-profile cia402 needs a CAN bus (--bus vcan0, can0, ...)")
    lockstep_only = {
        "--drive-bus": args.drive_bus is not None,
        "--drive mcu": args.drive == "mcu",
        "--serve": bool(args.serve),
        "--fd": bool(args.fd),
    }
    given = [k for k, v in lockstep_only.items() if v]
    if given:
        raise PlanError(
            f"{', '.join(given)}: options of the project's plant and drive nodes in lockstep, not of "
            "--drive-profile cia402 (the bench and the drive share one classic CAN bus)"
        )
    eds = args.drive_eds or eds_path("drive")
    if not eds.is_file():
        raise PlanError(f"--drive-eds {eds}: no such file")
    sc = load(args.scenario, args.overrides)
    cycle_s, load_ = choose_cycle(args.bitrate or 1_000_000, args.cycle_ms)
    import canopen

    od = canopen.import_od(str(eds), node_id=args.drive_id)
    missing = [f"0x{i:04X}" for i in (0x6040, 0x6041, 0x6060, 0x6071, 0x6075, 0x6502) if i not in od]
    if missing:
        raise PlanError(f"--drive-eds {eds}: no {', '.join(missing)}: not a CiA 402 torque drive")
    rated = int(od[0x6075].default or 0) if 0x6075 in od else 0
    max_pm = int(od[0x6072].default) if 0x6072 in od and od[0x6072].default is not None else None
    segs = targets(sc, rated, max_pm)
    out = _out(args, sc)
    if (lost := lost_in_vm(out)) is not None:
        raise PlanError(f"--out {lost}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise PlanError(f"{out} exists and is not an empty folder; choose another --out")
    return sc, cycle_s, load_, segs, eds, out


def run(args: argparse.Namespace) -> int:
    try:
        sc, cycle_s, load_, segs, eds, out = validate(args)
    except (ScenarioError, PlanError) as exc:
        print(f"bench run: {exc}", file=sys.stderr)
        return 2
    from bench.canbus import probe_af_can

    if cia402_bus(args).kernel_can and not probe_af_can().af_can:
        print(
            "bench run: this machine has no SocketCAN (AF_CAN): the CiA 402 master reaches a drive on a "
            "bus through a python-can interface (--interface slcan --bus socket://127.0.0.1:PORT, a CAN box slot's "
            "tap as `bench box status` prints it; pcan, kvaser ... for an adapter), or runs where the bus is "
            f"(bench vm -- .venv/bin/bench run {' '.join(sys.argv[2:])})",
            file=sys.stderr,
        )
        return 2
    from bench.cia402.session import Session

    return Session(args, sc, cycle_s, load_, segs, eds, out).run()


__all__ = ["HELP", "Interrupted", "add_arguments", "ignored_keys", "run", "summary_text", "validate"]
