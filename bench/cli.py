"""The `bench` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Collection
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.commands import Command


def build_parser(full: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The parser of every command, from the table (bench/commands.py); full: as there."""
    from bench.commands import build_parser as from_table

    return from_table(full)


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
        worker = sys.modules.get(f"{__package__}.view.worker_procs")  # prestart()'s, and every ViewWorker's
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


def _with_law(command: Command | None, argv: list[str]) -> tuple[list[str], int]:
    """`--law DIR` of a command that takes it (its row says so; bench/law.py): built, then BENCH_BUILD_DIR points the
    bench at its build; argv without it, and 0 or the exit status of a law that does not build."""
    import os

    if command is None or not command.law:
        return argv, 0
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
    from bench.commands import find

    command = find(argv[0]) if argv else None
    helping = bool({"-h", "--help"} & set(argv))
    early = _lacking(command, None) if command is not None and not helping else None
    if early:  # before its --law is built (minutes for nothing)
        print(early, file=sys.stderr)
        return 2
    argv, rc = _with_law(command, argv)
    if rc:
        return rc
    if command is not None and command.viewer is not None and not helping and command.viewer(argv):
        from bench.view.worker_procs import prestart, roles_in_argv

        prestart(roles_in_argv(argv))  # the viewer and plot processes import rerun and pygal while we import the rest
    parser = build_parser(argv[:1])  # the chosen command's arguments only
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 64
    refusal = _lacking(find(args.command), args)
    if refusal:
        print(refusal, file=sys.stderr)
        return 2
    rc = int(args.func(args))
    if rc == 130:  # the command's own "interrupted": 143 when it was a SIGTERM
        from bench import stop

        rc = stop.exit_status()
    return rc


def _lacking(command: Command | None, args: argparse.Namespace | None) -> str | None:
    """The refusal of a command that cannot run without an extra it lacks (bench/extras.py; a run without [view]
    only has no run.rrd): its own extras, and with its parsed arguments those its options need."""
    from bench.commands import needs
    from bench.extras import lacking, missing_extra

    for extra in needs(command, args) if command is not None else ():
        module = lacking(extra)
        if module is not None:
            return missing_extra(extra, f"bench {command.name}", f"no module {module!r}")
    return None


if __name__ == "__main__":
    sys.exit(main())
