"""A process in the CAN box (bench/run/bus/box): started in a run's slot through the slot's launcher (or the old way
on a box booted by an older bench), with the part of subprocess.Popen's face the bench uses; ended alone or with the
run's other processes in one request (each request costs the guest tens of ms under TCG)."""

from __future__ import annotations

import shlex
import signal
import time
import uuid
from pathlib import Path
from typing import Protocol

from bench.run.bus.box.control import BoxGone, Control
from bench.run.bus.box.guest import LAUNCHER


class Slot(Protocol):
    """What a process needs of its run's share of the box (lease.Lease)."""

    ctl: Control
    ns: str

    def in_ns(self, argv: list[str]) -> str: ...


def await_file(test: str, ticks: int) -> str:
    """A guest command line that waits until `[ TEST ]` holds, at most `ticks` naps of 10 ms (a read of the
    agent's empty fifo: no fork, no exec)."""
    return f"for ((k = 0; k < {ticks}; k++)); do [ {test} ] && break; read -r -t 0.01 -u 4 _; done"


POLL_CACHE_S = 0.25  # a process's state asked of the guest at most this often (liveness looks every 0.1 s)


class BoxPopen:
    """A process in the box, with the part of subprocess.Popen's face the bench uses (pid, poll, wait,
    send_signal, terminate, kill, returncode). Its exit status is written by a waiting shell in the guest."""

    def __init__(
        self, lease: Slot, argv: list[str], log: Path | None, err: Path | None = None, in_slot: bool = True
    ) -> None:
        self.lease = lease
        self.tag = uuid.uuid4().hex[:10]
        self.returncode: int | None = None
        self.gone: str | None = None  # why, when the box ended under the process
        self._asked = 0.0
        self._state: tuple[float, str | None] = (0.0, None)
        d = "/run/box"
        out = shlex.quote(str(log)) if log is not None else "/dev/null"
        err_to = "&1" if err is None else shlex.quote(str(err))
        plain = " ".join(shlex.quote(a) for a in argv)

        def wrapped(run: str) -> str:  # a subshell waits for the process and writes its exit status
            return (
                f"( {run} >{out} 2>{err_to} </dev/null 6<&- & echo $! >{d}/{self.tag}.pid; wait $!; "
                f"echo $? >{d}/{self.tag}.exit ) >/dev/null 2>&1 </dev/null &"
            )

        # in the slot: through its launcher (guest._slot_lines) while it runs, else as a box booted by an older
        # bench does it (`ip netns exec`, `taskset`); outside it: a subshell of the agent's (a fork, no exec)
        start = wrapped(plain)
        if in_slot:
            f = f"{LAUNCHER}{lease.ns}"
            start = (
                f"if [ -p {f} ] && read -r lp <{f}.pid && [ /proc/$lp/fd/6 -ef {f} ]; then "
                f"printf '%s\\n' {shlex.quote(start)} 1<>{f}; else {wrapped(lease.in_ns(argv))} fi;"
            )
        cmd = f"{start} {await_file(f'-s {d}/{self.tag}.pid', 500)}; read -r p <{d}/{self.tag}.pid && echo $p"
        out_text = lease.ctl.check(cmd, f"starting {Path(argv[0]).name}")
        self.pid = int(out_text.strip().splitlines()[-1])
        self.args = argv

    @property
    def exit_file(self) -> str:
        """The guest's file its exit status is written to once it has ended (test it with `-s`: the shell creates
        it before it writes the status)."""
        return f"/run/box/{self.tag}.exit"

    def _exit_now(self) -> int | None:
        _, out = self.lease.ctl.sh(f"echo {self.exit_text()}")
        return self.ended_with(out)

    def ended_with(self, text: str) -> int | None:
        """The exit status a guest command line read from exit_file (empty or '-': still running), kept as
        returncode, so that no further request asks it."""
        text = text.strip()
        if not text or text == "-":
            return None
        code = int(text)
        self.returncode = -(code - 128) if code > 128 else code  # a shell's 128+N: killed by signal N (Popen: -N)
        return self.returncode

    def exit_text(self) -> str:
        """A guest command line's word that expands to the exit status once it ended, else '-'."""
        f = self.exit_file
        return f"$([ -s {f} ] && read -r x <{f} && echo $x || echo -)"

    def state_text(self) -> str:
        """A guest command line that sets `st` to its kernel state letter (/proc/PID/stat, builtins only; empty
        once it is gone) - `l` and `st` are set first, the agent runs under `set -u`."""
        return f"l=; st=; read -r l 2>/dev/null </proc/{self.pid}/stat; st=${{l##*) }}; st=${{st%% *}}"

    def poll(self, fresh: bool = False) -> int | None:
        """The exit status, None while it runs (asked of the guest at most every POLL_CACHE_S unless `fresh`)."""
        if self.returncode is not None:
            return self.returncode
        now = time.monotonic()
        if not fresh and now - self._asked < POLL_CACHE_S:
            return None
        self._asked = now
        try:
            self.returncode = self._exit_now()
        except BoxGone as exc:
            self.gone = str(exc)
            self.returncode = -signal.SIGKILL  # the box is gone, and the process with it
        return self.returncode

    def state(self) -> str | None:
        """The process's kernel state letter (/proc/PID/stat in the guest): T when stopped (asked at most every
        POLL_CACHE_S)."""
        now = time.monotonic()
        if now - self._state[0] < POLL_CACHE_S:
            return self._state[1]
        try:
            rc, out = self.lease.ctl.sh(f'read -r l </proc/{self.pid}/stat && echo "$l"')
            state = out.rsplit(")", 1)[1].split()[0] if rc == 0 else None
        except (IndexError, BoxGone):
            state = None
        self._state = (now, state)
        return state

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            try:
                self.lease.ctl.sh(f"kill -{int(sig)} {self.pid} 2>/dev/null; true")
            except BoxGone as exc:  # the box ended, and the process with it
                self.gone = str(exc)
                self.returncode = -signal.SIGKILL

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def end(self, timeout_s: float, wake: bool = False) -> int:
        """SIGTERM (and SIGCONT when `wake`), its exit awaited up to `timeout_s`, else SIGKILL: in one request
        (nodes.end_process; each request costs the guest tens of ms)."""
        end_all([self], timeout_s, wake)
        return self.returncode if self.returncode is not None else self.wait(timeout=30)

    def wait(self, timeout: float | None = None) -> int:
        """Its exit status, waited for in the guest (one request per 5 s, no polling from here)."""
        import subprocess

        deadline = None if timeout is None else time.monotonic() + timeout
        f = f"/run/box/{self.tag}.exit"
        while True:
            if self.returncode is not None:
                return self.returncode
            left = 5.0 if deadline is None else min(5.0, deadline - time.monotonic())
            if left <= 0:
                raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
            try:
                n = max(1, int(left * 100))
                self.lease.ctl.sh(await_file(f"-s {f}", n), timeout_s=left + 30)
            except BoxGone as exc:
                self.gone = str(exc)
                self.returncode = -signal.SIGKILL
            self.poll(fresh=True)


def end_all(procs: list[BoxPopen], timeout_s: float, wake: bool = False) -> None:
    """SIGTERM (and SIGCONT when `wake`: a frozen process gets its SIGTERM at once) to each of a lease's processes
    still running, their exits awaited up to `timeout_s` in all, SIGKILL to what is left, and every exit status,
    in one request (a run's nodes end together: Session.close)."""
    left = [p for p in procs if p.returncode is None]
    if not left:
        return
    pids = " ".join(str(p.pid) for p in left)
    cont = f"kill -18 {pids} 2>/dev/null; " if wake else ""
    ended = " -a ".join(f"-s {p.exit_file}" for p in left)
    killed = " ".join(
        f"[ -s {p.exit_file} ] || {{ kill -9 {p.pid} 2>/dev/null; {await_file(f'-s {p.exit_file}', 100)}; }};"
        for p in left
    )
    try:
        _, out = left[0].lease.ctl.sh(
            f"kill -15 {pids} 2>/dev/null; {cont}{await_file(ended, max(1, int(timeout_s * 100)))}; {killed} "
            f"echo {' '.join(p.exit_text() for p in left)}",
            timeout_s=timeout_s + 30,
        )
    except BoxGone as exc:
        for p in left:
            p.gone = str(exc)
            p.returncode = -signal.SIGKILL
        return
    words = out.split()[-len(left) :]
    for p, word in zip(left, words, strict=False):
        p.ended_with(word)
