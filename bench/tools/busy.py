"""Busy loops that keep CPUs loaded while something is measured or soaked (`bench perf --realtime-burners`, the soak
scripts/soak.py, the lockstep-under-load test): each a shell loop in its own session, optionally pinned to CPUs, and
killed by its PID when the block ends, whatever ends it. One definition, so that "two busy loops" means the same
load in every figure the project reports."""

from __future__ import annotations

import contextlib
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator, Sequence

LOOP = "while :; do :; done"


@contextlib.contextmanager
def busy_loops(n: int, cpus: Sequence[int] | None = None, sigterm_exits: bool = False) -> Iterator[list[int]]:
    """`n` busy loops (on `cpus` through taskset when given and taskset is there); their PIDs. `sigterm_exits`: a
    SIGTERM to this process ends the block as SystemExit(143), so that the loops are killed then too (a command
    line's main; not in a pytest worker, whose signals are pytest's)."""
    pin = ["taskset", "-c", ",".join(str(c) for c in cpus)] if cpus and shutil.which("taskset") else []
    old = signal.signal(signal.SIGTERM, lambda *_: sys.exit(143)) if sigterm_exits else None
    procs: list[subprocess.Popen[bytes]] = []
    try:
        for _ in range(n):
            procs.append(
                subprocess.Popen(
                    [*pin, "sh", "-c", LOOP],
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    start_new_session=True,
                )
            )
        yield [p.pid for p in procs]
    finally:
        for p in procs:
            p.kill()
            p.wait()
        if old is not None:
            signal.signal(signal.SIGTERM, old)
