"""`bench run` in the calling process: the same parser, checks, run and files as the command, its output captured.

A process that runs many scenarios (a pytest session through the plugin's hil_run, a study in a notebook) pays
the bench's imports, the EDS parsing and the C library's load once, and keeps the viewer and plot processes for the
next run (bench/view/worker_procs.py `reuse`), instead of a new `bench run` process per run (~1.3 s for a loop of
milliseconds). Only the direct bus runs here: a bus run has processes of its own (nodes, candump, the CAN box) and
goes through `bench run` as before.

What the in-process run cannot do that a process can: be stopped by a timeout (hil_run's timeout= runs in a process
of its own), survive a crash of the C library (the caller's process ends with it: under pytest-xdist the worker is
the isolation, pytest's faulthandler names the test; the plugin's --hil-isolate runs each in a process), and run in
another build (a law's: BENCH_BUILD_DIR is read when bench.paths is first imported)."""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.view.deferred import DeferredView


@dataclass
class Ran:
    """A `bench run` in this process: its exit status and what it printed (its files are in its --out)."""

    exit_code: int
    stdout: str
    stderr: str
    view: DeferredView | None = None  # with view_later: the recording and plots, not drawn yet


def same_build(build: Path | None = None) -> bool:
    """Whether this process's bench (bench.paths, fixed at its first import) is the build a run asks for: `build`, or
    BENCH_BUILD_DIR's, or the repository's."""
    import bench.paths

    wanted = str(build) if build is not None else os.environ.get("BENCH_BUILD_DIR")
    return bench.paths.BUILD == Path(wanted or bench.paths.REPO / "build").resolve()


@lru_cache(maxsize=1)
def _parser() -> argparse.ArgumentParser:
    """`bench run`'s parser, built once (argparse's help texts cost ~0.1 s a build): a parser parses again and again."""
    from bench.cli import build_parser

    return build_parser(["run"])


def parse_run(argv: list[str]) -> argparse.Namespace | int:
    """`bench run ARGV` parsed, or argparse's exit status (its message on sys.stderr)."""
    try:
        args = _parser().parse_args(["run", *argv])
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    args.overrides = list(args.overrides or [])  # not the parser's default list, shared by every parse
    return args


def runs_here(argv: list[str]) -> bool:
    """Whether `bench run ARGV` can run in this process: arguments that parse, a bus whose kind runs in process (the
    direct bus), no --law (its build is another: the command builds it and starts afresh), this process's build."""
    from bench.run.bus.buses import bus_of_args

    with contextlib.redirect_stderr(io.StringIO()):  # a refusal is the process's to say (hil_run shows it)
        args = parse_run(argv)
    if isinstance(args, int) or getattr(args, "law", None) is not None:
        return False
    return bus_of_args(args).in_process and same_build()


def run_here(argv: list[str], view_later: bool = False) -> Ran:
    """`bench run ARGV` (ARGV without "run") in this process, as the command runs it (the extras it lacks refused,
    then its handler, bench/cli_runs.py); bad arguments are exit status 2 with argparse's message, as from the
    command. A Ctrl-C is the caller's: the run stops (its folder NAME.failed, or complete if its loop was), then
    KeyboardInterrupt is raised here."""
    from bench.cli import _lacking
    from bench.commands import find
    from bench.view.worker import reuse

    reuse()
    out, err = io.StringIO(), io.StringIO()
    views: list[DeferredView] = []
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        args = parse_run(argv)
        if isinstance(args, int):
            code = args
        elif (refusal := _lacking(find("run"), args)) is not None:
            print(refusal, file=sys.stderr)
            code = 2
        else:
            args.in_caller = True  # bench/run/command.py: a Ctrl-C while the results are written is the caller's
            if view_later:  # the recording and plots drawn later, or never (bench/view/deferred.py)
                args.view_later = views
            code = int(args.func(args))
    if code == 130:
        said = err.getvalue().strip().splitlines()
        raise KeyboardInterrupt(f"bench run interrupted: {said[-1] if said else 'no message'}")
    return Ran(code, out.getvalue(), err.getvalue(), views[0] if views else None)
