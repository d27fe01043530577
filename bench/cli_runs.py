"""`bench` commands that run the loop: run, capture (the VM half of a run), replay, sweep, reproduce, faults, demo
(each its parser and its handler; bench/cli.py puts them together)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def _law_option(p: argparse.ArgumentParser) -> None:
    """--law DIR, taken off the command line before parsing (_with_law); here for --help."""
    from bench.law import HELP

    p.add_argument("--law", type=Path, default=None, metavar="DIR", help=HELP)


def _motor_override(text: str) -> str:
    """--motor DIR as the override it is: motor.folder = "<DIR, absolute>" (a TOML string)."""
    import json

    return f"motor.folder={json.dumps(str(Path(text).expanduser().resolve()))}"


def _motor_option(p: argparse.ArgumentParser) -> None:
    """--motor DIR: the scenario's motor from a motor folder (the same as --set motor.folder=DIR)."""
    p.add_argument(
        "--motor",
        dest="overrides",
        action="append",
        type=_motor_override,
        metavar="DIR",
        help="your motor: a motor folder (motor.toml and a flux-map table psi_d(id, iq), psi_q(id, iq), CSV or "
        ".npz; docs/YOUR_MOTOR.md); the plant runs the flux-map model with it (= --set motor.folder=DIR; "
        "`bench motor check DIR` checks a folder, `bench motor example DIR` writes the example)",
    )


def _cmd_run(args: argparse.Namespace) -> int:
    if args.drive_profile == "cia402":
        from bench.cia402.command import run as run_cia402

        return run_cia402(args)
    from bench.run.command import run

    return run(args)


def add_run(sub: Any) -> None:
    from bench.run.command import add_arguments, exit_codes_help

    r = sub.add_parser(
        "run",
        help="run a scenario: configure by SDO, run, record every frame, summarize",
        description="Bring the bus up (host or VM), start the plant and drive processes, reset them "
        "by NMT, configure them by SDO from the EDS, run the scenario in lockstep (or, with "
        "--set scenario.timing=realtime, in real time on any bus, direct included: SYNC at absolute deadlines, the "
        "plant's and the bus's timing in summary.json), record every frame, and write summary.json, traces.npy, the "
        f"CAN log, SVG plots and a Rerun recording. The exit status is the run's verdict: {exit_codes_help()}. "
        "Example: bench run scenarios/you2019_step.toml --bus direct",
    )
    add_arguments(r)
    from bench.cia402.command import add_arguments as cia402_arguments

    cia402_arguments(r)
    _law_option(r)
    _motor_option(r)
    r.set_defaults(func=_cmd_run)


def _cmd_capture(args: argparse.Namespace) -> int:
    from bench.run.vm_run import capture_only

    return capture_only(args)


def add_capture(sub: Any) -> None:
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


def _cmd_replay(args: argparse.Namespace) -> int:
    from bench.replay import main as replay_main

    return replay_main(args)


def add_replay(sub: Any) -> None:
    from bench.replay import add_arguments as replay_args
    from bench.run.command import exit_codes_help

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


def _cmd_sweep(args: argparse.Namespace) -> int:
    from bench.sweep import main as sweep_main

    return sweep_main(args)


def add_sweep(sub: Any) -> None:
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
    _motor_option(sw)
    sw.set_defaults(func=_cmd_sweep)


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from bench.reproduce import main as reproduce_main

    return reproduce_main(args)


def add_reproduce(sub: Any) -> None:
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


def _cmd_faults(args: argparse.Namespace) -> int:
    from bench.faults.command import main as faults_main

    return faults_main(args)


def add_faults(sub: Any) -> None:
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


def _cmd_demo(args: argparse.Namespace) -> int:
    from bench.demo import main as demo_main

    return demo_main(args)


def add_demo(sub: Any) -> None:
    dm = sub.add_parser(
        "demo",
        help="the headline demo (the README's main job)",
        description="You 2019 motor with L_hat = 0.5 L, a current-step train, online tuning switched "
        "on halfway, over vcan0 (the CAN box if the host has no kernel CAN), recorded and shown in Rerun; ends with a "
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
