"""Start and stop the C node processes (plant_node, drive_node, co_testnode) cleanly."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path
from types import TracebackType
from typing import Any

from bench.paths import binary


class NodeProcess:
    """A C CANopen node process; terminated (SIGTERM, then SIGKILL) on exit, whatever happens."""

    def __init__(self, name: str, args: list[str], log: Path | None = None, box: Any = None) -> None:
        self.name = name
        self.argv = [str(binary(name)), *args]
        self.log = log
        self.box = box  # a CAN box lease (bench/run/bus/box/lease.py): the process runs in the box's namespace
        self.proc: Any = None  # subprocess.Popen, or boxproc.BoxPopen (the same face)
        self._log_fh = None

    def start(self) -> NodeProcess:
        if self.box is not None:  # its output written by the guest into the lease's stage (shared)
            self.proc = self.box.popen(self.argv, None if self.log is None else self.box.stage / self.log.name)
            return self
        out = subprocess.DEVNULL
        if self.log is not None:
            self._log_fh = open(self.log, "wb")  # noqa: SIM115 - closed in stop()
            out = self._log_fh  # type: ignore[assignment]
        self.proc = subprocess.Popen(self.argv, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self, timeout_s: float = 5.0) -> int | None:
        if self.proc is None:
            return None
        return end_process(self.proc, self._log_fh, timeout_s, wake=True)

    def __enter__(self) -> NodeProcess:
        return self.start()

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.stop()


def end_process(proc: Any, log_fh: Any, timeout_s: float, wake: bool = False) -> int:
    """SIGTERM (and SIGCONT when `wake`: a frozen (SIGSTOP) process gets its SIGTERM at once), SIGKILL after
    `timeout_s`; closes its log file; returns its exit status."""
    if hasattr(proc, "end"):  # boxproc.BoxPopen: all of it in one request to the CAN box
        proc.end(timeout_s, wake)
    elif proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        if wake:
            proc.send_signal(signal.SIGCONT)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if log_fh:
        log_fh.close()
    return proc.returncode


def process_state(proc: Any) -> str | None:
    """The kernel's state letter of a running process (R, S, T when stopped ...), here or in the CAN box."""
    if proc is None or proc.pid is None:
        return None
    if hasattr(proc, "state"):  # boxproc.BoxPopen: asked of the guest
        return proc.state()  # type: ignore[no-any-return]
    try:  # /proc/PID/stat: "pid (comm) state ...", comm may hold spaces and parentheses
        return Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def in_vm() -> bool:
    return os.environ.get("BENCH_IN_VM") == "1"
