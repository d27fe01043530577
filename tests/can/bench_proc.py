"""`bench run` as a user starts it, in a child process, for the CAN tests that act on a running loop
(kill or freeze a node, take a link down, Ctrl-C), and the processes such a run may leave behind."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from bench_cli import spawn_bench

from bench.paths import BIN, REPO

STEP = REPO / "scenarios" / "you2019_step.toml"
NODES = ("build/bin/plant_node", "build/bin/drive_node", "candump -L")


def start_long_run(out: Path, *bus_args: str) -> subprocess.Popen[str]:
    """`bench run` of You 2019's step scenario for 5 * 10^6 periods (longer than any test waits) on the
    buses given (e.g. "--bus", "vcan0"), results in `out`; its Ctrl-C the terminal's default (tests/bench_cli.py)."""
    return spawn_bench("run", STEP, *bus_args, "--out", out, "--no-viewer", "--set", "scenario.periods=5000000")


def pids(pattern: str) -> list[int]:
    """Processes whose command line contains `pattern` (pgrep -f); a node binary's (`build/bin/...`) of this
    checkout's build only (bench.paths.binary: its absolute path is the nodes' argv[0], BENCH_BIN_DIR's too): a
    second checkout on the same machine (a CI clone beside a soak) runs nodes of its own, not this run's leftovers."""
    if pattern.startswith("build/bin/"):
        pattern = str(Path(os.environ.get("BENCH_BIN_DIR") or BIN) / pattern.removeprefix("build/bin/"))
    res = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True)
    return [int(p) for p in res.stdout.split()]
