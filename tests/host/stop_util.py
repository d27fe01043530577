"""What a stopped command leaves behind, read from /proc: the processes of a session, the listening
sockets of a set of processes, and a bench command started in a session of its own."""

from __future__ import annotations

import os
import subprocess
import threading
import time
from pathlib import Path

from bench_cli import Arg, spawn_bench


def _stat(pid: int) -> list[str] | None:
    try:
        raw = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return raw[raw.rindex(")") + 2 :].split()  # state ppid pgrp session ...


def session(sid: int) -> list[int]:
    """The live (not zombie) processes of session `sid`."""
    found = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            st = _stat(int(d))
            if st and int(st[3]) == sid and st[0] != "Z":
                found.append(int(d))
    return found


def descendants(pid: int) -> dict[int, str]:
    """The live descendants of `pid`: {pid: comm}."""
    children: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            st = _stat(int(d))
            if st and st[0] != "Z":
                children.setdefault(int(st[1]), []).append(int(d))
    out: dict[int, str] = {}
    todo = list(children.get(pid, []))
    while todo:
        p = todo.pop()
        try:
            out[p] = Path(f"/proc/{p}/comm").read_text().strip()
        except OSError:
            continue
        todo += children.get(p, [])
    return out


def wait_gone(pids: list[int] | set[int], within_s: float = 60.0) -> list[int]:
    """The ones of `pids` still alive after up to `within_s` (a bound, not a timing)."""
    deadline = time.monotonic() + within_s
    while True:
        left = [p for p in pids if (st := _stat(p)) is not None and st[0] != "Z"]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.3)


def _hex_addr(h: str) -> str:
    """/proc/net/tcp's address (host byte order words, hex) -> text."""
    import ipaddress

    raw = bytes.fromhex(h)
    words = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
    return str(ipaddress.ip_address(words))


def listening(pids: list[int] | None = None, port: int | None = None) -> list[tuple[str, int]]:
    """(address, port) of the listening TCP sockets of `pids` (all processes when None), or on `port`."""
    inodes: set[str] | None = None
    if pids is not None:
        inodes = set()
        for p in pids:
            try:
                for fd in os.listdir(f"/proc/{p}/fd"):
                    link = os.readlink(f"/proc/{p}/fd/{fd}")
                    if link.startswith("socket:["):
                        inodes.add(link[8:-1])
            except OSError:
                continue
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            f = line.split()
            if f[3] != "0A":  # LISTEN
                continue
            addr, hport = f[1].rsplit(":", 1)
            if (inodes is None or f[9] in inodes) and (port is None or int(hport, 16) == port):
                found.append((_hex_addr(addr), int(hport, 16)))
    return found


class Bench:
    """`bench ARGS` (tests/bench_cli.py: Ctrl-C its default) in a session of its own; its output (stdout and
    stderr) read by a thread."""

    def __init__(self, *args: Arg, env: dict[str, str] | None = None) -> None:
        self.proc = spawn_bench(*args, env=env, start_new_session=True)
        self.out: list[str] = []
        self.err: list[str] = []
        self._threads = [
            threading.Thread(target=self._read, args=(self.proc.stdout, self.out), daemon=True),
            threading.Thread(target=self._read, args=(self.proc.stderr, self.err), daemon=True),
        ]
        for t in self._threads:
            t.start()

    @staticmethod
    def _read(stream, into: list[str]) -> None:  # type: ignore[no-untyped-def]
        for line in stream:
            into.append(line)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def text(self) -> str:
        return "".join(self.out) + "".join(self.err)

    def wait_for(self, what: str, within_s: float = 120.0) -> bool:
        """Whether `what` shows in its output within `within_s` (False at once if it ended)."""
        deadline = time.monotonic() + within_s
        while what not in self.text():
            if time.monotonic() > deadline or self.proc.poll() is not None:
                return what in self.text()
            time.sleep(0.1)
        return True

    def finish(self, within_s: float = 120.0) -> int | None:
        """Its exit status once it ended and its output is read (None: still running after `within_s`)."""
        try:
            rc = self.proc.wait(timeout=within_s)
        except subprocess.TimeoutExpired:
            return None
        for t in self._threads:
            t.join(timeout=within_s)
        return rc

    def kill(self) -> None:
        """Test clean-up: the whole session, whatever is left of it."""
        import signal

        for p in session(self.proc.pid):
            try:
                os.kill(p, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
