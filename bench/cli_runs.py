"""`bench` commands that run the loop: run, capture (the VM half of a run), replay, sweep, reproduce, faults, demo:
each its arguments and its handler (most of them the command's own package's, imported when the command is
chosen), and what its options add to the extras it needs; their rows of the command table (bench/commands.py)
name them and say what they are."""

from __future__ import annotations

import argparse
from pathlib import Path


def _cia402(argv: list[str]) -> bool:
    """`bench run --drive-profile cia402` draws its own plot: no viewer processes."""
    return "--drive-profile=cia402" in argv or any(
        a == "--drive-profile" and b == "cia402" for a, b in zip(argv, argv[1:], strict=False)
    )


def run_shows_viewer(argv: list[str]) -> bool:
    return not _cia402(argv)


def serve_needs(args: argparse.Namespace) -> tuple[str, ...]:
    """--serve: the Rerun web viewer, of the [view] extra."""
    return ("view",) if getattr(args, "serve", False) else ()


def run_needs(args: argparse.Namespace) -> tuple[str, ...]:
    """As serve_needs, and the CiA 402 master's figure: matplotlib, of the [view] extra."""
    return serve_needs(args) + (("view",) if getattr(args, "drive_profile", None) == "cia402" else ())


def run_arguments(r: argparse.ArgumentParser) -> None:
    from bench.cia402.command import add_arguments as cia402_arguments
    from bench.run.command import add_arguments

    add_arguments(r)
    cia402_arguments(r)


def cmd_run(args: argparse.Namespace) -> int:
    if args.drive_profile == "cia402":
        from bench.cia402.command import run as run_cia402

        return run_cia402(args)
    from bench.run.command import run

    return run(args)


def capture_arguments(c: argparse.ArgumentParser) -> None:
    from bench.eds import add_node_id_arguments

    c.add_argument("scenario", type=Path)
    c.add_argument("--set", dest="overrides", action="append", default=[])
    c.add_argument("--bus", default="vcan0")
    c.add_argument("--drive-bus", default=None)
    c.add_argument("--drive", choices=("node", "mcu"), default="node")
    c.add_argument("--drive-tty", default=None)
    c.add_argument("--bitrate", type=int, default=None)
    c.add_argument("--out", type=Path, required=True)
    add_node_id_arguments(c)


def cmd_capture(args: argparse.Namespace) -> int:
    from bench.run.vm_run import capture_only

    return capture_only(args)


def replay_arguments(rp: argparse.ArgumentParser) -> None:
    from bench.replay import add_arguments

    add_arguments(rp)


def cmd_replay(args: argparse.Namespace) -> int:
    from bench.replay import main

    return main(args)


def sweep_arguments(sw: argparse.ArgumentParser) -> None:
    from bench.sweep import add_arguments

    add_arguments(sw)


def cmd_sweep(args: argparse.Namespace) -> int:
    from bench.sweep import main

    return main(args)


def reproduce_arguments(rep: argparse.ArgumentParser) -> None:
    from bench.reproduce import add_arguments

    add_arguments(rep)


def cmd_reproduce(args: argparse.Namespace) -> int:
    from bench.reproduce import main

    return main(args)


def faults_arguments(fl: argparse.ArgumentParser) -> None:
    from bench.faults.command import add_arguments

    add_arguments(fl)


def cmd_faults(args: argparse.Namespace) -> int:
    from bench.faults.command import main

    return main(args)


def demo_arguments(dm: argparse.ArgumentParser) -> None:
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


def cmd_demo(args: argparse.Namespace) -> int:
    from bench.demo import main

    return main(args)


def port_check_arguments(p: argparse.ArgumentParser) -> None:
    from bench.port_check import arguments

    arguments(p)


def cmd_port_check(args: argparse.Namespace) -> int:
    from bench.port_check import cmd_port_check

    return cmd_port_check(args)
