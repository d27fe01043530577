"""The bench's side of the two helper processes of bench/view/worker.py: starting them (`prestart()`, first
thing in `bench run`), the pipe to each (`_Proc`: pickled messages in, written by a thread, JSON replies out),
and stopping the ones no run took (`discard()`)."""

from __future__ import annotations

import json
import os
import pickle
import queue
import signal
import subprocess
import sys
import threading
from typing import Any

ROLES = ("rerun", "plots")
_STARTED: dict[str, _Proc] = {}


class _Proc:
    """One helper process: pickled messages in (written by a thread, so the run never waits for it;
    the queue is bounded, so memory stays bounded if it falls behind), JSON replies out."""

    def __init__(self, role: str) -> None:
        from bench.stop import spawn_ignoring_sigint

        r, w = os.pipe()
        self.role = role
        argv = [sys.executable, "-m", "bench.view.worker", role, str(w)]
        self.proc = spawn_ignoring_sigint(lambda: subprocess.Popen(argv, stdin=subprocess.PIPE, pass_fds=(w,)))
        os.close(w)
        self._replies = os.fdopen(r, "rb")
        self._first: dict[str, Any] | None = None  # its first reply (ready, or the reason it is not)
        self._queue: queue.Queue[tuple[Any, ...] | None] = queue.Queue(maxsize=8)
        self.error: BaseException | None = None
        self._writer = threading.Thread(target=self._write_loop, daemon=True, name=f"bench-{role}-writer")
        self._writer.start()

    def _write_loop(self) -> None:
        assert self.proc.stdin is not None
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})  # the main thread's (bench/stop.py)
        while True:
            msg = self._queue.get()
            if msg is None:
                break
            try:
                pickle.dump(msg, self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
                self.proc.stdin.flush()
            except (BrokenPipeError, OSError) as exc:
                self.error = exc
                break
        try:
            self.proc.stdin.close()
        except OSError:
            pass

    def send(self, *msg: Any) -> None:
        if self.error is not None:
            self.recv()  # raises with the process's own reason
            raise RuntimeError(f"the {self.role} process stopped reading")
        self._queue.put(msg)

    def close_input(self) -> None:
        self._queue.put(None)
        self._writer.join()

    def ready_now(self) -> bool:
        """Whether its first reply (ready) has come, without waiting for it."""
        import select

        if self._first is None and select.select([self._replies.fileno()], [], [], 0)[0]:
            try:
                self._first = self.recv()
            except RuntimeError as exc:
                self._first = {"error": str(exc)}
        return self._first is not None and not self._first.get("error")

    def first(self) -> dict[str, Any]:
        """Its first reply (waits for it)."""
        if self._first is None:
            self._first = self.recv()
        elif self._first.get("error"):
            raise RuntimeError(self._first["error"])
        return self._first

    def recv(self) -> dict[str, Any]:
        line = self._replies.readline()
        if not line:
            code = self.proc.wait()
            raise RuntimeError(f"the {self.role} process ended (status {code}); see its message above")
        msg = json.loads(line)
        if msg.get("error"):
            raise RuntimeError(msg["error"])
        return msg  # type: ignore[no-any-return]

    def kill(self, grace_s: float = 10.0) -> None:
        """Stop it: SIGTERM (it stops what it started: the web viewer's server), SIGKILL after `grace_s` (the
        server then ends by its PR_SET_PDEATHSIG, bench/view/serve.py)."""
        try:
            self._queue.put_nowait(None)
        except queue.Full:
            pass
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=grace_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def prestart() -> None:
    """Start the helper processes now, so that their imports run while the bench imports its own."""
    for role in ROLES:
        if role not in _STARTED:
            _STARTED[role] = _Proc(role)


def discard() -> None:
    """Stop the started helper processes no run took (a run that failed before its outputs, a command
    that did not need them): at once, so that nobody waits for their imports."""
    while _STARTED:
        _STARTED.popitem()[1].kill(grace_s=2.0)


def _take(role: str) -> _Proc:
    return _STARTED.pop(role, None) or _Proc(role)
