"""The plant's CPU kept for the plant (issue 40): the keep-awake thread of plant_pacing.c (plant_node --keep-awake
and the direct mode's real time), and bench/run/bus/cpus.py, which moves the run's other processes and the bench's
own threads off the plant's CPU for a real-time run over this host's SocketCAN and back after."""

from __future__ import annotations

import ctypes
import os
import subprocess
import threading
import time
from pathlib import Path

import pytest

from bench.paths import BIN, BUILD
from bench.run.bus.cpus import PlantCpu, plant_cpu

TWO_CPUS = pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs a process that may use 2 CPUs")


def _threads_named(name: str) -> list[int]:
    out = []
    for t in os.listdir("/proc/self/task"):
        comm = Path(f"/proc/self/task/{t}/comm")
        if comm.exists() and comm.read_text().strip() == name:
            out.append(int(t))
    return out


@TWO_CPUS
def test_the_keep_awake_thread_idles_on_the_plants_cpu_and_goes_when_stopped() -> None:
    lib = ctypes.CDLL(str(BUILD / "libhil.so"))
    cpu = plant_cpu()
    assert cpu == min(os.sched_getaffinity(0))
    assert lib.plant_pacing_awake_start(-1) == 0  # no CPU: nothing started
    assert _threads_named("hil-awake") == []
    try:
        assert lib.plant_pacing_awake_start(cpu) == 1
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:  # it names, pins and lowers itself when it starts
            tids = _threads_named("hil-awake")
            if tids and os.sched_getscheduler(tids[0]) == os.SCHED_IDLE and os.sched_getaffinity(tids[0]) == {cpu}:
                break
            time.sleep(0.01)
        assert len(tids) == 1, tids
        assert os.sched_getscheduler(tids[0]) == os.SCHED_IDLE  # the lowest class: anything else preempts it
        assert os.sched_getaffinity(tids[0]) == {cpu}
        assert lib.plant_pacing_awake_start(cpu) == 1  # one at most
        assert len(_threads_named("hil-awake")) == 1
    finally:
        lib.plant_pacing_awake_stop()
    assert _threads_named("hil-awake") == []


def test_plant_node_offers_keep_awake_and_refuses_what_it_does_not_know() -> None:
    node = BIN / "plant_node"
    out = subprocess.run([str(node), "--help"], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0 and "--keep-awake" in out.stdout
    bad = subprocess.run([str(node), "--keep-awake", "--awake"], capture_output=True, text=True, timeout=30)
    assert bad.returncode == 64 and "unknown option '--awake'" in bad.stderr and "--keep-awake" in bad.stderr


@TWO_CPUS
def test_the_runs_processes_and_the_benchs_threads_leave_the_plants_cpu_and_come_back() -> None:
    cpu = plant_cpu()
    assert cpu is not None
    all_cpus = os.sched_getaffinity(0)
    child = subprocess.Popen(["sleep", "60"])
    stop = threading.Event()
    started_before = threading.Thread(target=stop.wait, name="before")
    started_before.start()
    keep = PlantCpu(cpu)
    try:
        keep.leave(child.pid)
        keep.reserve()
        assert cpu not in os.sched_getaffinity(child.pid)
        assert cpu not in os.sched_getaffinity(0)  # this thread
        assert cpu not in os.sched_getaffinity(started_before.native_id)  # a thread started before
        during = threading.Thread(target=stop.wait, name="during")
        during.start()  # inherits the reduced set
        assert cpu not in os.sched_getaffinity(during.native_id)
        pinned = subprocess.Popen(["taskset", "-c", str(cpu), "sleep", "60"])
        time.sleep(0.2)
        keep.leave(pinned.pid)  # a task with that CPU alone stays (plant_node's pacing is such a one)
        assert os.sched_getaffinity(pinned.pid) == {cpu}
        pinned.kill()
        pinned.wait()
        keep.release()
        assert os.sched_getaffinity(child.pid) == all_cpus
        assert os.sched_getaffinity(0) == all_cpus
        assert os.sched_getaffinity(started_before.native_id) == all_cpus
        assert os.sched_getaffinity(during.native_id) == all_cpus  # started during the run: the main set
    finally:
        os.sched_setaffinity(0, all_cpus)
        stop.set()
        child.kill()
        child.wait()


@TWO_CPUS
def test_isolate_moves_the_benchs_child_processes_but_the_spared_and_release_puts_them_back() -> None:
    cpu = plant_cpu()
    assert cpu is not None
    all_cpus = os.sched_getaffinity(0)
    worker = subprocess.Popen(["sleep", "60"])  # as the viewer worker: a child of the bench
    plant = subprocess.Popen(["sleep", "60"])  # as plant_node: spared
    keep = PlantCpu(cpu)
    try:
        keep.isolate(spare=frozenset({plant.pid}))
        assert cpu not in os.sched_getaffinity(worker.pid)
        assert os.sched_getaffinity(plant.pid) == all_cpus
        assert os.sched_getaffinity(0) == all_cpus  # this process's own threads are the C side's (or reserve's)
        assert "tasks moved off CPU" in keep.summary()
        keep.release()
        assert os.sched_getaffinity(worker.pid) == all_cpus
    finally:
        keep.release()
        for p in (worker, plant):
            p.kill()
            p.wait()


def test_the_unbound_workqueues_leave_the_plants_cpu_and_their_mask_comes_back(tmp_path: Path) -> None:
    mask = tmp_path / "cpumask"  # stands for /sys/devices/virtual/workqueue/cpumask (hex, as the kernel writes it)
    mask.write_text("00000003\n")
    keep = PlantCpu(0)
    keep.wq_mask = mask
    keep._workqueues_off()
    assert mask.read_text() == "2" and "the unbound workqueues too" in keep.summary()
    keep.release()
    assert mask.read_text() == "00000003"
    mask.write_text("1\n")  # only the plant's CPU: nowhere else to go, left alone
    keep._workqueues_off()
    assert mask.read_text() == "1\n" and keep.wq_was is None
    keep.wq_mask = tmp_path / "missing"  # an old kernel: nothing to do
    keep._workqueues_off()
    assert keep.wq_was is None
