"""The `bench` command."""

from __future__ import annotations

import argparse
import sys


def build_parser() -> argparse.ArgumentParser:
    from bench import cli_box, cli_motor, cli_runs, cli_tools

    p = argparse.ArgumentParser(
        prog="bench",
        description="Hardware-in-the-loop bench for PMSM deadbeat current control over CANopen "
        "(SocketCAN; a virtme-ng VM supplies vcan when the host kernel has no CAN).",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for add in (
        cli_tools.add_doctor,
        cli_tools.add_vm,
        cli_box.add_box,
        cli_tools.add_pingpong,
        cli_tools.add_plan,
        cli_runs.add_run,
        cli_runs.add_capture,
        cli_runs.add_replay,
        cli_tools.add_export,
        cli_runs.add_sweep,
        cli_runs.add_reproduce,
        cli_runs.add_faults,
        cli_tools.add_perf,
        cli_runs.add_demo,
        cli_motor.add_motor,
    ):
        add(sub)
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
    early = _lacking_before_law(argv)
    if early:
        print(early, file=sys.stderr)
        return 2
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
    refusal = _needs_extra(args)
    if refusal:
        print(refusal, file=sys.stderr)
        return 2
    rc = int(args.func(args))
    if rc == 130:  # the command's own "interrupted": 143 when it was a SIGTERM
        from bench import stop

        rc = stop.exit_status()
    return rc


# the commands that cannot do without an extra (bench/extras.py); a run without [view] only has no run.rrd
NEEDS_EXTRA = {"sweep": ("sweep",), "reproduce": ("view", "sweep"), "perf": ("view", "sweep")}


def _lacking_before_law(argv: list[str]) -> str | None:
    """A command that cannot run without an extra, refused before its --law is built (minutes for nothing)."""
    if not argv or argv[0] not in NEEDS_EXTRA or {"-h", "--help"} & set(argv):
        return None
    return _needs_extra(argparse.Namespace(command=argv[0]))


def _needs_extra(args: argparse.Namespace) -> str | None:
    from bench.extras import lacking, missing_extra

    needs = list(NEEDS_EXTRA.get(args.command, ()))
    if args.command in ("run", "replay", "demo") and getattr(args, "serve", False):
        needs.append("view")
    if args.command == "run" and getattr(args, "drive_profile", None) == "cia402":
        needs.append("view")  # its figure: matplotlib
    for extra in needs:
        module = lacking(extra)
        if module is not None:
            return missing_extra(extra, f"bench {args.command}", f"no module {module!r}")
    return None


def _cia402(argv: list[str]) -> bool:
    """`bench run --drive-profile cia402` draws its own plot: no viewer processes."""
    return "--drive-profile=cia402" in argv or any(
        a == "--drive-profile" and b == "cia402" for a, b in zip(argv, argv[1:], strict=False)
    )


if __name__ == "__main__":
    sys.exit(main())
