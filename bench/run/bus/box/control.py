"""The CAN box's control channel, host side: one TCP connection to the QEMU chardev of the guest's /dev/hvc0
per request, under a lock file (several runs, shells and pytest workers share one box; the chardev takes one
client at a time). A request is one line `SEQ VERB ARG`, its answer a line `SEQ RC N` and the N lines of the
output (bench/run/bus/box/guest.py serves it). An answer to an older request (one that timed out) is skipped."""

from __future__ import annotations

import fcntl
import os
import random
import socket
import time
from pathlib import Path


class BoxError(RuntimeError):
    """The CAN box cannot do what was asked (not running, gone, a command in it failed): said in the message."""


class BoxGone(BoxError):
    """The box stopped answering: its QEMU is gone (killed, crashed) or it powered off."""


class Control:
    def __init__(self, port: int, lock_path: Path, host: str = "127.0.0.1") -> None:
        self.port = port
        self.host = host
        self.lock_path = lock_path

    def request(self, verb: str, arg: str = "-", timeout_s: float = 60.0) -> tuple[int, str]:
        """(status, output) of one request; BoxGone when the box does not answer within `timeout_s`."""
        seq = random.randrange(1, 1 << 31)
        line = f"{seq} {verb} {arg}\n".encode()
        with open(self.lock_path, "a+b") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                return self._exchange(seq, line, timeout_s)
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def _exchange(self, seq: int, line: bytes, timeout_s: float) -> tuple[int, str]:
        deadline = time.monotonic() + timeout_s
        try:
            sock = socket.create_connection((self.host, self.port), timeout=min(5.0, timeout_s))
        except OSError as exc:
            raise BoxGone(f"the CAN box's control channel (127.0.0.1:{self.port}) does not answer: {exc}") from None
        with sock:
            sock.sendall(line)
            buf = b""
            while True:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise BoxGone(f"the CAN box did not answer a request within {timeout_s:g} s")
                sock.settimeout(left)
                try:
                    chunk = sock.recv(65536)
                except TimeoutError:
                    continue
                except OSError as exc:
                    raise BoxGone(f"the CAN box's control channel broke: {exc}") from None
                if not chunk:
                    raise BoxGone("the CAN box closed its control channel (its QEMU ended)")
                buf += chunk
                got = _answer(buf, seq)
                if got is not None:
                    return got

    def sh(self, command: str, timeout_s: float = 60.0) -> tuple[int, str]:
        """Run a command line (one line) with bash in the guest: (status, output)."""
        if "\n" in command:
            raise ValueError("a box command is one line")
        return self.request("sh", command, timeout_s)

    def check(self, command: str, what: str, timeout_s: float = 60.0) -> str:
        """`sh`, and BoxError naming `what` when its status is not 0."""
        rc, out = self.sh(command, timeout_s)
        if rc != 0:
            raise BoxError(f"in the CAN box, {what} failed (status {rc}): {out.strip()[-800:]}")
        return out

    def ping(self, timeout_s: float = 5.0) -> float:
        """The guest's uptime in seconds (the box answers)."""
        rc, out = self.request("ping", "-", timeout_s)
        return float(out.strip() or 0.0)


def _answer(buf: bytes, seq: int) -> tuple[int, str] | None:
    """The answer to request `seq` once `buf` holds all of it (older answers before it are skipped)."""
    lines = buf.split(b"\n")
    i = 0
    while i < len(lines) - 1:
        head = lines[i].decode(errors="replace").split(" ")
        if len(head) == 3 and head[0].isdigit() and head[2].isdigit():
            n = int(head[2])
            if i + 1 + n > len(lines) - 1:
                return None  # the output is still coming
            if head[0] == str(seq):
                return int(head[1]), "\n".join(x.decode(errors="replace") for x in lines[i + 1 : i + 1 + n])
            i += 1 + n
        else:
            i += 1
    return None


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
