"""The plant's CPU kept for the plant during a real-time run over SocketCAN (issue 40, docs/REALTIME.md).

plant_node paces itself on the first CPU this process may use (plant_pacing_default_cpu: the bench starts it with
the bench's own affinity) and, with --keep-awake, keeps that CPU out of its halt. What else the run starts here
(drive_node, the fault gateway, candump) and every thread of the bench's own Python (decoding, writing, the live
view) leave that CPU for the run and come back after, as the direct mode's threads do (bench/direct/hil_realtime.c,
reserve_cpu): on a kernel without PREEMPT_RT a task inside a system call or a page fault is not preempted, whatever
the plant's priority. The same for what is not the bench's but may be moved: the bench's child processes (the
viewer worker and its Rerun threads) and the kernel's unbound threads (DAMON's kdamond, ...), which an ftrace of the
plant's CPU caught holding it for 50-250 us (docs/REALTIME.md): the kernel places them on a CPU that runs only a
SCHED_IDLE thread as on an idle one. The unbound workqueues' kworkers refuse a thread's affinity: their CPUs are
the workqueues' cpumask (/sys/devices/virtual/workqueue/cpumask), set without the plant's CPU for the run and put
back after, where it may be written (root). Per-CPU kernel threads stay (a tuned host: isolcpus); moving a kernel
thread needs CAP_SYS_NICE, and without it they stay, counted.
The standard library's os.sched_setaffinity moves one task (a thread); a process's threads are moved one by one,
from /proc/PID/task, as `tuna --isolate` does."""

from __future__ import annotations

import os
import threading
from pathlib import Path


def plant_cpu() -> int | None:
    """The CPU plant_node's pacing takes: the first of this process's when it has two or more, else None."""
    cpus = sorted(os.sched_getaffinity(0))
    return cpus[0] if len(cpus) >= 2 else None


def _tids(pid: int) -> list[int]:
    try:
        return [int(t) for t in os.listdir(f"/proc/{pid}/task")]
    except OSError:
        return []


PF_KTHREAD = 0x00200000  # /proc/PID/stat's flags: a kernel thread
WQ_CPUMASK = Path("/sys/devices/virtual/workqueue/cpumask")  # the unbound workqueues' CPUs (hex)


def _mask(cpus: set[int]) -> str:
    return format(sum(1 << c for c in cpus), "x")


def _cpus(mask: str) -> set[int]:
    bits = int(mask.replace(",", "").strip() or "0", 16)
    return {c for c in range(bits.bit_length()) if bits >> c & 1}


def _stat(pid: int) -> tuple[int, int] | None:
    """(ppid, flags) of a process, from /proc/PID/stat (its name may hold spaces and parentheses)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2 :].split()
    return int(fields[1]), int(fields[6])


def _processes() -> dict[int, tuple[int, int]]:
    out = {}
    for name in os.listdir("/proc"):
        if name.isdigit() and (st := _stat(int(name))) is not None:
            out[int(name)] = st
    return out


class PlantCpu:
    """Tasks moved off the plant's CPU (leave, reserve, isolate) and put back where they were (release)."""

    def __init__(self, cpu: int) -> None:
        self.cpu = cpu
        self.moved: dict[int, set[int]] = {}
        self.refused = 0  # kernel threads on the plant's CPU that could not be moved
        self.wq_was: str | None = None  # the workqueues' cpumask before the run, when it was changed
        self.wq_mask = WQ_CPUMASK

    def isolate(self, spare: frozenset[int] = frozenset()) -> None:
        """The bench's child processes (all their threads) but those in `spare` (plant_node) and the kernel's movable
        threads off the plant's CPU."""
        procs = _processes()
        me, children = os.getpid(), set()
        grew = True
        while grew:
            grew = False
            for pid, (ppid, _flags) in procs.items():
                if pid not in children and (ppid == me or ppid in children):
                    children.add(pid)
                    grew = True
        for pid in children - spare:
            self.leave(pid)
        for pid, (_ppid, flags) in procs.items():
            if flags & PF_KTHREAD:
                try:
                    was = os.sched_getaffinity(pid)
                    if self.cpu in was and len(was) >= 2:
                        os.sched_setaffinity(pid, was - {self.cpu})
                        self.moved.setdefault(pid, was)
                except OSError:  # a per-CPU thread, a kworker, or no CAP_SYS_NICE
                    self.refused += 1
        self._workqueues_off()

    def _workqueues_off(self) -> None:
        try:
            was = self.wq_mask.read_text().strip()
            cpus = _cpus(was)
            if self.cpu in cpus and len(cpus) >= 2:
                self.wq_mask.write_text(_mask(cpus - {self.cpu}))
                self.wq_was = was
        except (OSError, ValueError):  # no such file (an old kernel), or not root
            self.wq_was = None

    def summary(self) -> str:
        wq = ", the unbound workqueues too" if self.wq_was is not None else ""
        return f"{len(self.moved)} tasks moved off CPU {self.cpu}{wq}" + (
            f", {self.refused} kernel threads that may run there could not be" if self.refused else ""
        )

    def leave(self, pid: int) -> None:
        """Every thread of process `pid` off the plant's CPU (one that has no other CPU stays)."""
        for tid in _tids(pid):
            try:
                was = os.sched_getaffinity(tid)
                if self.cpu in was and len(was) >= 2:
                    os.sched_setaffinity(tid, was - {self.cpu})
                    self.moved.setdefault(tid, was)
            except OSError:  # gone meanwhile, or not ours to move
                continue

    def reserve(self) -> None:
        """The bench's own threads: those started later inherit the reduced set from their starter."""
        self.leave(os.getpid())

    def release(self) -> None:
        """Back where they were; a thread of this process started during the run gets the set this thread had."""
        mine = self.moved.get(threading.get_native_id())
        for tid, was in self.moved.items():
            try:
                os.sched_setaffinity(tid, was)
            except OSError:
                continue
        if mine is not None:
            for tid in _tids(os.getpid()):
                if tid in self.moved:
                    continue
                try:
                    if self.cpu not in os.sched_getaffinity(tid):
                        os.sched_setaffinity(tid, mine)
                except OSError:
                    continue
        self.moved.clear()
        if self.wq_was is not None:
            try:
                self.wq_mask.write_text(self.wq_was)
            except OSError:
                pass
            self.wq_was = None
