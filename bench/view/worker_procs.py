"""The bench's side of the two helper processes of bench/view/worker.py: starting them (`prestart()`, first
thing in `bench run`), the pipe to each (`_Proc`: pickled messages in, written by a thread, JSON replies out),
and stopping the ones no run took (`discard()`). A process that runs one run after another (`reuse()`: the
plugin's in-process runs, bench.api) keeps them for its next run (`give_back`): their imports, ~1 s of rerun and
matplotlib, are paid once, not per run."""

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
# Runs a kept process serves before it is replaced: rerun-sdk 0.41 keeps ~0.4 MiB of every recording stream it
# made, closed or not (1.05 MiB a run with the bench's blueprint: 117 -> 430 MiB over 300 runs), so a process that
# served this many gives way to a new one, started at once (its imports overlap with what the caller does next).
REUSE_RUNS = 25
_STARTED: dict[str, _Proc] = {}
_REUSE = {"on": False, "exit_hook": False}


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
        self.runs = 0  # the runs it served (give_back)
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


def live_of(serve: bool, no_viewer: bool) -> str:
    """The live viewer of a run: served (--serve), spawned (a display and no --no-viewer) or none."""
    if serve:
        return "serve"
    if not no_viewer and (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "spawn"
    return "none"


def roles_for(rrd: bool, plots: bool, live: str) -> tuple[str, ...]:
    """The helper processes a run needs: "rerun" for run.rrd or a live viewer, "plots" for the plots."""
    return tuple(r for r, on in (("rerun", rrd or live != "none"), ("plots", plots)) if on)


def roles_in_argv(argv: list[str]) -> tuple[str, ...]:
    """`roles_for` guessed from `bench run`'s arguments before they are parsed (prestart): an abbreviated option
    is missed, and then a process is started late (`_take`) or stopped unused (`discard`), never lacking."""
    live = live_of("--serve" in argv, "--no-viewer" in argv)
    return roles_for("--no-rrd" not in argv, "--no-plots" not in argv, live)


def prestart(roles: tuple[str, ...] = ROLES) -> None:
    """Start the helper processes now, so that their imports run while the bench imports its own."""
    for role in roles:
        if role not in _STARTED:
            _STARTED[role] = _Proc(role)


def discard() -> None:
    """Stop the started helper processes no run took (a run that failed before its outputs, a command
    that did not need them): at once, so that nobody waits for their imports."""
    while _STARTED:
        _STARTED.popitem()[1].kill(grace_s=2.0)


def reuse(on: bool = True) -> None:
    """From now on a run without a live viewer gives its helper processes back when done (`give_back`) and the next
    run takes them; they end with this process (its exit, or `discard()`)."""
    import atexit

    if on and not _REUSE["exit_hook"]:
        atexit.register(discard)
        _REUSE["exit_hook"] = True
    _REUSE["on"] = on


def reusing() -> bool:
    return _REUSE["on"]


def give_back(proc: _Proc) -> None:
    """A helper process done with its run, in good order: kept for the next run when reusing, else stopped."""
    proc.runs += 1
    if not _REUSE["on"] or proc.role in _STARTED:
        proc.kill(grace_s=2.0)
    elif proc.error is None and proc.proc.poll() is None and proc.runs < REUSE_RUNS:
        proc._first = None  # the next run's spec gets a "ready" of its own
        _STARTED[proc.role] = proc
    else:  # worn (REUSE_RUNS) or broken: a new one for the next run
        proc.kill(grace_s=2.0)
        _STARTED[proc.role] = _Proc(proc.role)


def _take(role: str) -> _Proc:
    while (proc := _STARTED.pop(role, None)) is not None:
        if proc.proc.poll() is None and proc.error is None:
            return proc
        proc.kill(grace_s=0.5)  # ended or broken since it was kept: reaped, not left running
    return _Proc(role)
