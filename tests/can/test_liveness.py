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
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli
from bench_proc import pids, start_long_run
from can_site import Site

from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.verdict.summary import EXIT_CODES
from bench.scenario import load
from bench.tools.busy import busy_loops

STEP = REPO / "scenarios" / "you2019_step.toml"
TUNE = REPO / "tests" / "scenarios" / "parity.toml"
NODES = ("build/bin/plant_node", "build/bin/drive_node", "candump -L", "cangen")
HEARTBEAT_TIMEOUT_S = RunOptions().heartbeat_timeout_ms / 1000


def _no_process_left(site: Site) -> None:
    time.sleep(0.5)
    for name in NODES:
        assert not site.pids(name), f"{name} still running"
        assert not pids(name), f"{name} still running here"


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        if k != "t_s":
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


# ---------------------------------------------------------------------------------------- load


def test_lockstep_under_cpu_load_is_bit_identical(vcan0: str, tmp_path: Path) -> None:
    """(In the CAN box the busy loops are this machine's: they take the CPUs from the box's QEMU, whose guest
    runs the nodes, the recorder and the bridge.)"""
    sc = load(TUNE, ["scenario.periods=3000"])
    direct = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    quiet = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "quiet"), keep_trace=True)
    # Busy loops at the nodes' priority, twice as many as there are CPUs: the nodes, the master and the
    # recorder get a third of a CPU each, the loop runs several times slower; nothing else may change.
    with busy_loops(2 * (os.cpu_count() or 1)):
        loaded = run_scenario(sc, RunOptions(bus=vcan0, out=tmp_path / "loaded"), keep_trace=True)
    for name, res in (("quiet", quiet), ("loaded", loaded)):
        s = res.summary
        # what a failure needs to be explained (it once failed under load with its message lost): the first
        # cause and its period, the stop, the EMCYs, the lost frames by kind, the run's folder
        why = (name, s["status"], s["status_first_period"], s["stopped"], s["emcy"][:5], str(tmp_path / name))
        assert res.status == "ok", why
        assert s["bus_stats"]["lost_frames"] == 0, (why, {k: v for k, v in s["bus_stats"].items() if "missing" in k})
        assert res.counters["plant_missed_commands"] == 0 and res.counters["plant_late_commands"] == 0, why
    assert direct.trace is not None and quiet.trace is not None and loaded.trace is not None
    _same(loaded.trace, quiet.trace)
    _same(loaded.trace, direct.trace)


# ---------------------------------------------------------------------------------------- liveness


def _start_long_run(site: Site, out: Path) -> subprocess.Popen[str]:
    proc = start_long_run(out, "--bus", "vcan0")  # on this machine's vcan0, or in a slot of the CAN box
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not (site.pids("build/bin/plant_node") and site.pids("build/bin/drive_node")):
        time.sleep(0.2)
    time.sleep(4.0)  # configured, and the loop running
    assert proc.poll() is None, proc.communicate()
    return proc


# A frozen node is named by its silence (through the CAN box under two busy loops the master once heard it
# 2.3-2.6 s after the freeze, over the bound of consumer time + 1 s: docs/VM.md, "Known limits of the bridge").
@pytest.mark.parametrize(
    "node,how",
    [
        ("drive", signal.SIGKILL),
        ("plant", signal.SIGKILL),
        ("drive", signal.SIGSTOP),
    ],
)
def test_a_lost_node_is_named_at_once(site: Site, tmp_path: Path, node: str, how: signal.Signals) -> None:
    out = tmp_path / f"{node}-{how.name}"
    proc = _start_long_run(site, out)
    node_pids = site.pids(f"build/bin/{node}_node")
    assert len(node_pids) == 1
    site.kill(node_pids[0], how)
    # the node is killed or frozen by now (in the CAN box: during the control request, ~5-500 ms on a loaded host)
    t_kill = time.time()
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
    _no_process_left(site)


# ---------------------------------------------------------------------------------------- foreign frames


def _cangen(site: Site, slot: int | None, *args: str) -> Any:
    """cangen on the run's vcan0: this machine's, or the run's slot of the CAN box (Site.run_slot)."""
    return site.start_in_run(slot, ["cangen", "vcan0", *args])


@contextmanager
def _flood_during_the_run(site: Site, *args: str) -> Iterator[None]:
    """cangen on the bus of the run this process starts in the block: at once on this machine's vcan0; in the
    CAN box as soon as the run holds its slot (the run's bus is its slot's vcan0), before its nodes start."""
    gens: list[Any] = []
    if not site.in_box:
        gens.append(_cangen(site, None, *args))
    else:
        watcher = threading.Thread(target=lambda: gens.append(_cangen(site, site.run_slot(os.getpid()), *args)))
        watcher.start()
    try:
        yield
    finally:
        if site.in_box:
            watcher.join()
        assert gens, "the flood never started"
        for g in gens:
            g.kill()
            g.wait()


@pytest.mark.parametrize(
    "flood",
    [
        ("-I", "080", "-L", "0", "-g", "2"),  # fake SYNCs, no counter
        ("-I", "080", "-L", "1", "-D", "r", "-g", "2"),  # fake SYNCs with a random counter
        ("-I", "r", "-L", "r", "-D", "r", "-g", "0.2"),  # random identifiers, lengths, data
    ],
)
def test_foreign_frames_never_pass_for_a_clean_run(site: Site, tmp_path: Path, flood: tuple[str, ...]) -> None:
    sc = load(TUNE, ["scenario.periods=3000"])
    try:
        with _flood_during_the_run(site, *flood):
            res = run_scenario(sc, RunOptions(bus=site.iface, out=tmp_path / "run"), keep_trace=True)
    except Exception as exc:  # noqa: BLE001 - a clear failure is allowed, a crash of our decoding is not
        assert "unpack" not in str(exc) and "index" not in str(exc), exc
        return
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
    # No foreign SYNC made a period. A run the liveness stopped ends early: a random frame on a node's heartbeat
    # identifier says the node left operational (CiA 301 7.2.8.3.2.4; a CI run in the box stopped at 1,351 of
    # 3,000 periods), and the verdict still names the interference first.
    if res.status in ("ok", "interference") and not res.summary.get("stopped"):
        assert res.summary["periods"] == 3000, res.summary
    _no_process_left(site)


# In the CAN box the end of a run takes longer (the master's last reads over SLCAN, candump's log copied out): the
# flood after the loop was once recorded for 40 s there (36,000 random frames in one run), and some of them, on
# the loop's identifiers with the loop's lengths, were taken for the loop's (status interference).
def test_a_flood_after_the_loop_changes_nothing(site: Site, tmp_path: Path) -> None:
    sc = load(TUNE, ["scenario.periods=3000"])
    gens: list[Any] = []

    def progress(done: int, total: int) -> None:
        if done == total and not gens:  # the loop's last period is in: flood from now on
            slot = site.run_slot(os.getpid(), timeout_s=5) if site.in_box else None
            gens.append(_cangen(site, slot, "-I", "r", "-L", "r", "-D", "r", "-g", "0.1"))
            gens.append(_cangen(site, slot, "-I", "080", "-L", "1", "-D", "r", "-g", "0.5"))

    try:
        res = run_scenario(sc, RunOptions(bus=site.iface, out=tmp_path / "run"), keep_trace=True, progress=progress)
    finally:
        for g in gens:
            g.kill()
            g.wait()
    assert gens, "the flood never started"
    ref = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    bs = res.summary["bus_stats"]
    assert res.status == "ok", (res.status, bs)
    assert res.summary["periods"] == 3000 and bs["lost_frames"] == 0
    # the flood was recorded: its random identifiers are foreign frames, counted after the loop and, from the
    # master's NMT Stop on, in the teardown (in the CAN box the flood may begin only after that Stop)
    assert bs["foreign_frames"]["frames"] > 0 and bs["after_loop_frames"] + res.summary["teardown"]["frames"] > 2
    assert ref.trace is not None and res.trace is not None
    _same(res.trace, ref.trace)
    _no_process_left(site)


# ---------------------------------------------------------------------------------------- bad buses


def test_a_bus_that_does_not_exist_is_named_before_anything_starts(site: Site, tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = bench_cli("run", STEP, "--bus", "nonexistent0", "--out", out, "--no-viewer", timeout=120, expect=2)
    # the buses there are: this machine's (named with their state), or on a host without CAN those the box makes
    there = f"{site.iface} (up)" if not site.in_box else "virtual buses (vcan0, vcan1, ...)"
    assert "nonexistent0" in res.stderr and there in res.stderr, res.stderr
    assert list(tmp_path.iterdir()) == []
    _no_process_left(site)
