"""A run's result can be trusted over a real bus (vcan0, in the VM on hosts without CAN):

- lockstep under deliberate CPU load gives traces bit-identical to an unloaded run and to direct mode;
- a node killed (SIGKILL) or frozen (SIGSTOP) mid-run is named within its heartbeat consumer time
  plus a second; the run stops with status node_lost (exit 8) and leaves no process;
- fake SYNCs and random frames during and after the loop crash nothing and never give a successful
  run with lost frames; a flood after the loop's last period changes nothing.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from bench_proc import pids, start_long_run

from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.verdict.summary import EXIT_CODES
from bench.scenario import load

# the test kills, freezes and floods the run's own nodes and bus from this process
# (kernel_can: the kernel's CAN in this process, inside the VM on a host without CAN)
pytestmark = pytest.mark.kernel_can

STEP = REPO / "scenarios" / "you2019_step.toml"
TUNE = REPO / "tests" / "scenarios" / "parity.toml"
NODES = ("build/bin/plant_node", "build/bin/drive_node", "candump -L", "cangen")
HEARTBEAT_TIMEOUT_S = RunOptions().heartbeat_timeout_ms / 1000


def _no_process_left() -> None:
    time.sleep(0.5)
    for name in NODES:
        assert not pids(name), f"{name} still running"


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        if k != "t_s":
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


# ---------------------------------------------------------------------------------------- load


def test_lockstep_under_cpu_load_is_bit_identical(vcan0: str, tmp_path: Path) -> None:
    sc = load(TUNE, ["scenario.periods=3000"])
    direct = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    quiet = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "quiet"), keep_trace=True)
    # Busy loops at the nodes' priority, twice as many as there are CPUs: the nodes, the master and the
    # recorder get a third of a CPU each, the loop runs several times slower; nothing else may change.
    hogs = [subprocess.Popen(["sh", "-c", "while :; do :; done"]) for _ in range(2 * (os.cpu_count() or 1))]
    try:
        loaded = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "loaded"), keep_trace=True)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    for res in (quiet, loaded):
        assert res.status == "ok", (res.summary["stopped"], res.summary["bus_stats"])
        assert res.summary["bus_stats"]["lost_frames"] == 0
        assert res.counters["plant_missed_commands"] == 0 and res.counters["plant_late_commands"] == 0
    assert direct.trace is not None and quiet.trace is not None and loaded.trace is not None
    _same(loaded.trace, quiet.trace)
    _same(loaded.trace, direct.trace)


# ---------------------------------------------------------------------------------------- liveness


def _start_long_run(out: Path) -> subprocess.Popen[str]:
    proc = start_long_run(out, "--bus", "vcan0")
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not (out.with_name(out.name + ".partial") / "candump.log").exists():
        time.sleep(0.2)
    time.sleep(4.0)  # configured, and the loop running
    assert proc.poll() is None, proc.communicate()
    return proc


@pytest.mark.parametrize("node,how", [("drive", signal.SIGKILL), ("plant", signal.SIGKILL), ("drive", signal.SIGSTOP)])
def test_a_lost_node_is_named_at_once(vcan0: str, tmp_path: Path, node: str, how: signal.Signals) -> None:
    out = tmp_path / f"{node}-{how.name}"
    proc = _start_long_run(out)
    node_pids = pids(f"build/bin/{node}_node")
    assert len(node_pids) == 1
    t_kill = time.time()
    os.kill(node_pids[0], how)
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == EXIT_CODES["node_lost"] == 8, stdout + stderr
    summary = json.loads((out / "summary.json").read_text())
    stopped = summary["stopped"]
    assert summary["status"] == "node_lost" and stopped["node"] == node
    # a killed node's process is seen to exit; a frozen one falls silent, which the bench and the other
    # node (EMCY 0x8130) notice at about the same time
    causes = {"process_exited"} if how == signal.SIGKILL else {"heartbeat_timeout", "emcy_8130"}
    assert stopped["cause"] in causes, stopped
    # named within the heartbeat consumer time plus a second
    assert stopped["detected_at_unix"] - t_kill < HEARTBEAT_TIMEOUT_S + 1.0, stopped
    assert f"the {node} (node 0x" in stdout and "NODE_LOST" in stdout, stdout
    assert 0 < summary["periods"] < 5_000_000
    _no_process_left()


# ---------------------------------------------------------------------------------------- foreign frames


def _cangen(*args: str) -> subprocess.Popen[bytes]:
    return subprocess.Popen(["cangen", "vcan0", *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


@pytest.mark.parametrize(
    "flood",
    [
        ("-I", "080", "-L", "0", "-g", "2"),  # fake SYNCs, no counter
        ("-I", "080", "-L", "1", "-D", "r", "-g", "2"),  # fake SYNCs with a random counter
        ("-I", "r", "-L", "r", "-D", "r", "-g", "0.2"),  # random identifiers, lengths, data
    ],
)
def test_foreign_frames_never_pass_for_a_clean_run(vcan0: str, tmp_path: Path, flood: tuple[str, ...]) -> None:
    sc = load(TUNE, ["scenario.periods=3000"])
    gen = _cangen(*flood)
    try:
        res = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "run"), keep_trace=True)
    except Exception as exc:  # noqa: BLE001 - a clear failure is allowed, a crash of our decoding is not
        assert "unpack" not in str(exc) and "index" not in str(exc), exc
        return
    finally:
        gen.kill()
        gen.wait()
    bs = res.summary["bus_stats"]
    assert res.status != "ok" or bs["lost_frames"] == 0
    if res.status == "ok":
        ref = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
        assert ref.trace is not None and res.trace is not None
        _same(res.trace, ref.trace)
    else:
        # Never a clean run. Random identifiers reach the nodes too, and a frame a node acts on can change the
        # physics so that the currents diverge before the decoder sees a second frame in a period (one CI run in
        # the VM ended "diverged" at a segment boundary; its log was lost with the guest): any status
        # but "ok" is a true verdict here; naming every such run "interference" is left open (issue 15).
        assert res.status in ("interference", "node_lost", "frames_lost", "diverged", "tripped", "non_finite"), (
            res.status,
            bs,
        )
    if res.status in ("ok", "interference"):
        assert res.summary["periods"] == 3000  # no foreign SYNC made a period
    _no_process_left()


def test_a_flood_after_the_loop_changes_nothing(vcan0: str, tmp_path: Path) -> None:
    sc = load(TUNE, ["scenario.periods=3000"])
    gens: list[subprocess.Popen[bytes]] = []

    def progress(done: int, total: int) -> None:
        if done == total and not gens:  # the loop's last period is in: flood from now on
            gens.append(_cangen("-I", "r", "-L", "r", "-D", "r", "-g", "0.1"))
            gens.append(_cangen("-I", "080", "-L", "1", "-D", "r", "-g", "0.5"))

    try:
        res = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "run"), keep_trace=True, progress=progress)
    finally:
        for g in gens:
            g.kill()
            g.wait()
    assert gens, "the flood never started"
    ref = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    bs = res.summary["bus_stats"]
    assert res.status == "ok", (res.status, bs)
    assert res.summary["periods"] == 3000 and bs["lost_frames"] == 0
    assert bs["after_loop_frames"] > 0
    assert ref.trace is not None and res.trace is not None
    _same(res.trace, ref.trace)
    _no_process_left()


# ---------------------------------------------------------------------------------------- bad buses


def test_a_bus_that_does_not_exist_is_named_before_anything_starts(vcan0: str, tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "bench.cli",
            "run",
            str(STEP),
            "--bus",
            "nonexistent0",
            "--out",
            str(out),
            "--no-viewer",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    assert res.returncode == 2, res.stderr
    assert "nonexistent0" in res.stderr and f"{vcan0} (up)" in res.stderr  # the buses that exist
    assert list(tmp_path.iterdir()) == []
    _no_process_left()
