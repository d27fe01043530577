"""The test suite's one front door to the bench's command line, used as a user uses it: `python -m bench.cli ARGS`
(the module of the console script `bench`) in a child process of this interpreter (the bench of this environment,
whatever PATH holds, as the plugin's hil_run runs it), from the repository, with this process's environment.

    res = bench_cli("run", STEP, "--bus", "direct", "--out", out, expect=0)   # runs to its end, output captured
    proc = spawn_bench("run", STEP, "--bus", "vcan0", ...)                    # started, to act on while it runs

bench_cli: the command's CompletedProcess (text), stopped after `timeout` seconds (subprocess.TimeoutExpired);
with expect=N the test fails unless the command exited N, its message the command line, the exit status and the
end of its stdout and stderr. spawn_bench: a Popen (stdout and stderr piped, text, unless the call says otherwise),
its Ctrl-C the terminal's default (a CI runner may start the suite with SIGINT ignored, as a shell's background job
does, which a child inherits: a test of Ctrl-C would then test nothing). env: variables set on top of this
process's. A test that runs a scenario only to read its result uses the plugin's hil_run fixture instead."""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
from collections.abc import Mapping, Sequence
from typing import Any

from bench.paths import REPO

BENCH = (sys.executable, "-m", "bench.cli")
TIMEOUT_S = 600.0  # a bound for a command that hangs on a loaded machine, not a timing
SHOWN_CHARS = 3000  # of each output in a failure message: its end

Arg = str | os.PathLike[str]


def command(*args: Arg, under: Sequence[str] = ()) -> list[str]:
    """`python -m bench.cli ARGS` as an argv (paths as strings), after the command it runs `under` if any."""
    return [*under, *BENCH, *(os.fspath(a) for a in args)]


def _env(env: Mapping[str, str] | None) -> dict[str, str] | None:
    return None if env is None else {**os.environ, **env}


def said(res: subprocess.CompletedProcess[str], chars: int = SHOWN_CHARS) -> str:
    """A finished command for a failure message: its command line, exit status and the end of each output."""
    argv = [str(a) for a in res.args] if isinstance(res.args, list | tuple) else [str(res.args)]
    return (
        f"{shlex.join(argv)}\nexited {res.returncode}\n"
        f"--- stdout (its end) ---\n{(res.stdout or '')[-chars:]}\n"
        f"--- stderr (its end) ---\n{(res.stderr or '')[-chars:]}"
    )


def bench_cli(
    *args: Arg,
    timeout: float | None = TIMEOUT_S,
    cwd: Arg = REPO,
    env: Mapping[str, str] | None = None,
    expect: int | None = None,
    under: Sequence[str] = (),
    stdout: Any = subprocess.PIPE,
) -> subprocess.CompletedProcess[str]:
    """`bench ARGS` run to its end, its output captured; with `expect`, the test fails unless it exited so.
    under: a command the bench runs under (["prlimit", "--rtprio=0", "--"], ...); stdout: where its standard
    output goes instead of a pipe (a file descriptor: res.stdout is then None)."""
    __tracebackhide__ = True
    argv = command(*args, under=under)
    res = subprocess.run(
        argv, cwd=cwd, env=_env(env), stdout=stdout, stderr=subprocess.PIPE, text=True, timeout=timeout
    )
    if expect is not None and res.returncode != expect:
        raise AssertionError(f"expected exit status {expect}:\n{said(res)}")
    return res


def sigint_default() -> None:
    """In the child: Ctrl-C as a terminal's default."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def spawn_bench(
    *args: Arg, cwd: Arg = REPO, env: Mapping[str, str] | None = None, **popen: Any
) -> subprocess.Popen[Any]:
    """`bench ARGS` started and left running: its Popen (keyword arguments as subprocess.Popen's; by default its
    stdout and stderr piped, text), Ctrl-C its default."""
    popen.setdefault("stdout", subprocess.PIPE)
    popen.setdefault("stderr", subprocess.PIPE)
    popen.setdefault("text", True)
    return subprocess.Popen(command(*args), cwd=cwd, env=_env(env), preexec_fn=sigint_default, **popen)


def why(summary: Mapping[str, Any]) -> str:
    """What a run's summary.json says of its verdict, for an assertion's message: the status and where it began, why
    the loop stopped, the bus's loss and interference counts, and the links' counters (a frame lost by the recorder
    shows as frames on the link that the log lacks)."""
    stats = summary.get("bus_stats", {})
    keep = {
        k: v for k, v in stats.items() if any(w in k for w in ("lost", "late", "gap", "missing", "interf", "after"))
    }
    return (
        f"status {summary.get('status')} from period {summary.get('status_first_period')}; stopped: "
        f"{summary.get('stopped')}; flags {summary.get('status_flags')}; bus {keep}; links {summary.get('can_links')}"
    )
