"""Memory of repeated in-process runs (docs/BENCHMARKS.md, "Direct runs in the test's process"): N direct runs of
You 2019's step (200 periods) through bench.cli_in_process.run_here (hil_run's path), each run's folder removed, or
with --api through bench.api.run without files; this process's RSS and open files, and the kept viewer and plot
processes' RSS, after 10, 100, N/2 and N runs, and the median time of a run after the first.

    .venv/bin/python scripts/in_process_memory.py 300
    .venv/bin/python scripts/in_process_memory.py 1000 --api
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from bench.api import run
from bench.cli_in_process import run_here
from bench.paths import REPO
from bench.view import worker_procs


def rss_mib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS"):
            return int(line.split()[1]) // 1024
    return -1


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", type=int, nargs="?", default=300, help="how many runs (default 300)")
    p.add_argument("--api", action="store_true", help="bench.api.run without files instead of hil_run's path")
    args = p.parse_args()
    n = args.runs
    if n < 1:
        p.error(f"runs = {n}: at least 1")
    folder = Path(tempfile.mkdtemp(prefix="in-process-memory-"))
    step = REPO / "scenarios" / "you2019_step.toml"
    t0 = time.perf_counter()
    took: list[float] = []
    try:
        for i in range(n):
            t_run = time.perf_counter()
            if args.api:
                if run(step, {"scenario.periods": 200}).exit_code != 0:
                    print("a run's status was not ok")
                    return 1
            else:
                out = folder / f"r{i}"
                ran = run_here(
                    [str(step), "--bus", "direct", "--no-viewer", "--out", str(out), "--set", "scenario.periods=200"]
                )
                if ran.exit_code != 0:
                    print(ran.stderr)
                    return 1
                shutil.rmtree(out)
            took.append(time.perf_counter() - t_run)
            if i + 1 in (10, 100, n // 2, n):
                kept = {k: rss_mib(q.proc.pid) for k, q in worker_procs._STARTED.items()}
                print(
                    f"after {i + 1} runs: this process {rss_mib(os.getpid())} MiB, "
                    f"{len(os.listdir('/proc/self/fd'))} open files; kept processes {kept} MiB; "
                    f"{time.perf_counter() - t0:.1f} s; a run after the first: median "
                    f"{1e3 * statistics.median(took[1:] or took):.1f} ms",
                    flush=True,
                )
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
