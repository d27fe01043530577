"""The `bench` commands as one table: a row per command (its name, the line `bench --help` shows, its description,
its arguments, its handler, the options the bench adds to it, the extras it needs, whether it shows a run in the
viewer), in the order `bench --help` lists them. The parser is built from the table; a new command is a row here
and a module with its arguments and its handler (bench/cli_*.py, or the command's own package). The rows name
functions of modules that import nothing heavy at the top: a command's own imports happen when it is chosen."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench import cli_box, cli_motor, cli_runs, cli_tools


@dataclass(frozen=True)
class Command:
    name: str
    help: str | None  # the line `bench --help` shows; None: an internal command, not listed
    handler: Callable[[argparse.Namespace], int]  # its exit status
    arguments: Callable[[argparse.ArgumentParser], None] | None = None
    description: str | Callable[[], str] | None = None  # a callable: computed when the command is built
    raw_description: bool = False  # the description's line breaks kept (examples)
    law: bool = False  # takes --law DIR (bench/law.py: built and used before the command is parsed)
    motor: bool = False  # takes --motor DIR (= --set motor.folder=DIR)
    needs: tuple[str, ...] = ()  # the extras (bench/extras.py) it cannot do without, refused before --law builds
    needs_for: Callable[[argparse.Namespace], tuple[str, ...]] | None = None  # the extras its options need
    viewer: Callable[[list[str]], bool] | None = None  # with these arguments it shows a run in Rerun


def _exit_codes() -> str:
    from bench.run.command import exit_codes_help

    return exit_codes_help()


COMMANDS: tuple[Command, ...] = (
    Command(
        "doctor",
        help="report kernel CAN, vcan0, VM fallback and tool versions",
        description="One screen: what the bench found, each problem with the command that fixes it. "
        "Exit 0 when CAN work can run (on the host or in the VM).",
        handler=cli_tools.cmd_doctor,
    ),
    Command(
        "vm",
        help="run a command inside the micro-VM with a real vcan0",
        description="Boot Debian's stock kernel under QEMU (virtme-ng), bring up vcan0, run CMD in the "
        "current directory (the repository and the current directory are shared "
        "read-write) and return CMD's exit status. Example: bench vm -- candump -n 1 vcan0",
        arguments=cli_tools.vm_arguments,
        handler=cli_tools.cmd_vm,
    ),
    Command(
        "box",
        help="the CAN box: one VM that carries vcan buses where the host's kernel has no CAN (up, status, down)",
        description="The CAN box: on a host whose kernel has no SocketCAN (or cannot make vcan links), runs over "
        "vcan use one VM booted once (~15-60 s) instead of one per run. The VM holds only what needs the "
        "kernel (the vcan links, the C node processes, candump, the fault gateway); the bench's Python stays "
        "on the host and reaches each run's bus over SLCAN, which python-can speaks. `bench run --bus vcan0` "
        "starts a box itself when none is up; the box powers off after --idle-timeout seconds unused. "
        "Exit status of status: 0 up, 3 down.",
        arguments=cli_box.box_arguments,
        handler=cli_box.cmd_box,
    ),
    Command(
        "pingpong",
        help="C ping-pong between two processes on a CAN interface (needs SocketCAN)",
        description="Start an echo and a ping C process on IFACE, verify every answer, print "
        "round-trip statistics. Run it through `bench vm --` on hosts without CAN.",
        arguments=cli_tools.pingpong_arguments,
        handler=cli_tools.cmd_pingpong,
    ),
    Command(
        "plan",
        help="will the PDO set fit a real-time period on this bus? (--from-log: the frames a run sent)",
        description="Bits per control period of the configured PDO set (from the EDS files) with "
        "worst-case bit stuffing, bus load, whether Ts fits in real time, the fastest "
        "period that does, and what to change. Example: bench plan --bitrate 1000000 "
        "--ts 55e-6. With --from-log RUN/bus.log: the frames the run sent, replayed onto a simulated "
        "physical bus (each frame's exact stuffed length, arbitration by identifier, each node's "
        "transmit latency): per period the bus time, whether the command ends before the next SYNC, "
        "the load; p50, p99, max and the periods that overrun. Example: bench plan --from-log "
        "RUN/bus.log --fd --data-bitrate 5e6 --latency-us drive=5",
        arguments=cli_tools.plan_arguments,
        handler=cli_tools.cmd_plan,
    ),
    Command(
        "run",
        help="run a scenario: configure by SDO, run, record every frame, summarize",
        description=lambda: (
            "Bring the bus up (host or VM), start the plant and drive processes, reset them "
            "by NMT, configure them by SDO from the EDS, run the scenario in lockstep (or, with "
            "--set scenario.timing=realtime, in real time on any bus, direct included: SYNC at absolute deadlines, "
            "the plant's and the bus's timing in summary.json), record every frame, and write summary.json, "
            "traces.npy, the CAN log, SVG plots and a Rerun recording. The exit status is the run's verdict: "
            f"{_exit_codes()}. "
            "Example: bench run scenarios/you2019_step.toml --bus direct"
        ),
        arguments=cli_runs.run_arguments,
        handler=cli_runs.cmd_run,
        law=True,
        motor=True,
        needs_for=cli_runs.run_needs,
        viewer=cli_runs.run_shows_viewer,
    ),
    # internal (the VM half of a run over a VM's bus): no `help`, so argparse lists no entry for it (a
    # help=argparse.SUPPRESS still lists "capture ==SUPPRESS==" in the command listing before Python 3.14)
    Command("capture", help=None, arguments=cli_runs.capture_arguments, handler=cli_runs.cmd_capture),
    Command(
        "replay",
        help="decode a CAN log (candump/ASC/BLF, any bus) into traces and views",
        description=lambda: (
            "Decode any log python-can reads (candump .log, .asc, .blf) into traces.npy, "
            "summary.json, SVG plots and a Rerun recording, as the run did: the PDO layout, "
            "the plant's parameters and every setting come from the SDO traffic in the log "
            "(the EDS defaults when it has none, said so). The exit status is the verdict, "
            f"as for bench run: {_exit_codes()}."
        ),
        arguments=cli_runs.replay_arguments,
        handler=cli_runs.cmd_replay,
        law=True,
        needs_for=cli_runs.serve_needs,
    ),
    Command(
        "port-check",
        help="a current law prototyped in Python against its C port: where they part, per signal",
        description="Runs the scenario twice in direct mode, once with the Python prototype (--py-law, a class "
        "with the C interface's face) and once with the registered law it stands in for (its C port; a law folder "
        "with --law DIR), and compares every trace column period by period: the largest difference and the first "
        "period they part beyond --tolerance (default 0: bit for bit). A prototype that computes in float32 and a "
        "port that does the same operations agree bit for bit (docs/YOUR_CONTROLLER.md 'Prototype in Python "
        "first'). Exit 0: they agree; 1: they part; 2: bad input. Example: bench port-check "
        "examples/scenarios/complex_vector_pi_step.toml --law examples/laws/complex_vector_pi "
        "--py-law examples/laws/complex_vector_pi/prototype.py:ComplexVectorPI",
        arguments=cli_runs.port_check_arguments,
        handler=cli_runs.cmd_port_check,
        law=True,
    ),
    Command(
        "export",
        help="convert a CAN log (candump .log, .asc, .blf) to another format",
        description="Convert a CAN log: .asc (Vector ASCII) and .blf (Vector binary) with "
        "python-can's writers, .log (candump) with the bench's C writer. Example: "
        "bench export runs/x/bus.log runs/x/bus.blf",
        arguments=cli_tools.export_arguments,
        handler=cli_tools.cmd_export,
    ),
    Command(
        "sweep",
        help="robustness studies (grids, Monte Carlo, boundary search) in direct mode, on Dask",
        raw_description=True,
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
        arguments=cli_runs.sweep_arguments,
        handler=cli_runs.cmd_sweep,
        law=True,
        motor=True,
        needs=("sweep",),
    ),
    Command(
        "reproduce",
        help="run every claim of the three papers and write a report",
        description="Runs, over vcan by default, a scenario for each quantitative claim of You 2019, "
        "Yao 2020 and Zhao 2022, and writes report.md, report.html and report.json with "
        "the paper's value, the bench's value, the tolerance and a verdict per claim.",
        arguments=cli_runs.reproduce_arguments,
        handler=cli_runs.cmd_reproduce,
        needs=("view", "sweep"),
    ),
    Command(
        "faults",
        help="inject each fault kind into the loop and judge the nodes' reactions (safe states, held "
        "commands, EMCYs, reaction times)",
        description="Runs the fault checks: each injects one fault (a dropped, delayed, duplicated, corrupted or "
        "reordered frame; a lost heartbeat; a frozen, killed or reset node) into the You 2019 loop, runs "
        "the same scenario without it, and judges the reaction against what a real drive and inverter "
        "must do (docs/FAULTS.md). Exit 0 when every check passes. To inject faults into your own "
        "scenario, give it [[faults]] tables and use bench run.",
        arguments=cli_runs.faults_arguments,
        handler=cli_runs.cmd_faults,
        law=True,
    ),
    Command(
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
        arguments=cli_tools.perf_arguments,
        handler=cli_tools.cmd_perf,
        needs=("view", "sweep"),
    ),
    Command(
        "demo",
        help="the headline demo (the README's main job)",
        description="You 2019 motor with L_hat = 0.5 L, a current-step train, online tuning switched "
        "on halfway, over vcan0 (the CAN box if the host has no kernel CAN), recorded and shown in Rerun; ends with a "
        "before/after table and the paths of the results.",
        arguments=cli_runs.demo_arguments,
        handler=cli_runs.cmd_demo,
        needs_for=cli_runs.serve_needs,
        viewer=lambda argv: True,
    ),
    Command(
        "motor",
        help="check a motor folder (flux map from design data), write the example one, build a source FMU",
        description="A motor folder is motor.toml (name, source, pole pairs, R and its temperature model, "
        "mechanics) and a flux-map table psi_d(id, iq), psi_q(id, iq) as CSV or .npz (docs/YOUR_MOTOR.md). "
        'Select it in a scenario with [motor] folder = "DIR" or on the command line with '
        "`bench run SCENARIO --motor DIR`: the plant then runs the flux-map model.",
        arguments=cli_motor.motor_arguments,
        handler=cli_motor.cmd_motor,
    ),
)


def find(name: str) -> Command | None:
    return next((c for c in COMMANDS if c.name == name), None)


def build_parser(full: Collection[str] | None = None) -> argparse.ArgumentParser:
    """`bench`'s parser from the table. full: the commands whose arguments are added (None: every one); the others
    get their entry only (`bench --help` then imports no command's module: the listing is the rows' help)."""
    p = argparse.ArgumentParser(
        prog="bench",
        description="Hardware-in-the-loop bench for PMSM deadbeat current control over CANopen "
        "(SocketCAN; a virtme-ng VM supplies vcan when the host kernel has no CAN).",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for c in COMMANDS:
        _add(sub, c, full is None or c.name in full)
    return p


def _add(sub: Any, c: Command, full: bool) -> None:
    kw: dict[str, Any] = {} if c.help is None else {"help": c.help}
    if full and c.description is not None:
        kw["description"] = c.description if isinstance(c.description, str) else c.description()
    if c.raw_description:
        kw["formatter_class"] = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(c.name, **kw)
    p.set_defaults(func=c.handler)
    if not full:
        return
    if c.arguments is not None:
        c.arguments(p)
    if c.law:
        _law_option(p)
    if c.motor:
        _motor_option(p)


def needs(c: Command, args: argparse.Namespace | None) -> list[str]:
    """The extras command c needs: its own, and (given its parsed arguments) those its options need."""
    return [*c.needs, *(c.needs_for(args) if args is not None and c.needs_for is not None else ())]


def _law_option(p: argparse.ArgumentParser) -> None:
    """--law DIR, taken off the command line before parsing (bench/cli.py); here for --help."""
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
