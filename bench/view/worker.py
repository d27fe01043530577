"""What only shows a run - the Rerun recording (and live viewer) and the PNG plots - in two
helper processes, so that it runs on the other core beside the loop, the decoding and the
files, and their imports (rerun ~0.5 s, matplotlib ~0.6 s) overlap with the run.

`prestart()` starts them first thing in `bench run` (before the bench's own imports); the
`ViewWorker` sink then sends the "rerun" process, over a pipe, its settings, the signal list
and every trace chunk as it is decoded; at the end the "plots" process gets what the plots
need (the summary, the step windows, the envelopes). Messages are pickled tuples; replies
come back as JSON lines on a pipe of their own (the processes' stdout and stderr stay the
user's).

    python -m bench.view.worker ROLE REPLY_FD     (started by prestart(); not a user command)
"""

from __future__ import annotations

import json
import os
import pickle
import queue
import signal
import subprocess
import sys
import threading
from pathlib import Path
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


class ViewWorker:
    """The bench's side: a Sink whose chunks go to the rerun process; `finish` hands the plots over."""

    def __init__(
        self,
        name: str,
        folder: Path,
        live: str = "none",
        live_decimate: int = 1,
        web_port: int = 9090,
        grpc_port: int = 9876,
        rrd: bool = True,
        serve_for: float | None = None,
        bind: str = "127.0.0.1",
    ) -> None:
        self.spec = {
            "name": name,
            "folder": str(folder),
            "live": live,
            "live_decimate": live_decimate,
            "web_port": web_port,
            "grpc_port": grpc_port,
            "rrd": rrd,
            "serve_for": serve_for,
            "bind": bind,
        }
        self.rerun = _take("rerun")
        self.plots = _take("plots")
        self.rerun.send("spec", self.spec)
        self.plots.send("spec", self.spec)
        self.live = live
        self.url: str | None = None
        self.skipped: str | None = None  # why the recording and the plots were not made

    def wait_ready(self) -> None:
        """Block until the rerun process has its viewer up (serving: the ports are taken, or the error is known)."""
        self.url = self.rerun.first().get("url")

    def begin(self, signals: list[Any], ctx: Any = None) -> None:
        self.rerun.send("begin", signals)

    def write(self, chunk: dict[str, Any]) -> None:
        self.rerun.send("chunk", chunk)

    def end(self, summary: dict[str, Any]) -> None:
        pass  # the plots need the step windows too: see finish()

    def finish(self, result: Any, title: str) -> None:
        """Hand over what the plots need; both processes finish while the caller writes its own files.

        A run that stopped early (a node lost, a stall) does not wait for processes still starting (their
        imports take minutes in the VM): they are stopped, and the run has no recording and no plots
        (`bench replay` of its bus.log makes them). When they are up, it gets them as any run."""
        if result.summary.get("stopped") and self.live != "serve":
            if not (self.rerun.ready_now() and self.plots.ready_now()):
                self.abort()
                Path(self.spec["folder"], "run.rrd").unlink(missing_ok=True)
                self.skipped = "the run stopped early and the viewer processes were still starting"
                print(
                    f"bench run: no run.rrd and no plots: {self.skipped} (bench replay of its bus.log makes them)",
                    file=sys.stderr,
                    flush=True,
                )
                return
        self.rerun.send("finish", {"summary": result.summary})
        self.plots.send(
            "finish",
            {"summary": result.summary, "windows": result.step_windows, "envelopes": result.envelopes, "title": title},
        )
        self.rerun.close_input()
        self.plots.close_input()

    def finish_wait(self) -> list[str]:
        """The files written (run.rrd and the PNGs), once both processes are done with them."""
        if self.skipped:
            return []
        self.wait_ready()
        files = list(self.rerun.recv().get("files", []))
        self.plots.first()  # ready
        files += list(self.plots.recv().get("files", []))
        return files

    def serve(self, seconds: float | None) -> None:
        """With a live viewer: the rerun process keeps serving until `seconds`, Ctrl-C or SIGTERM (to the
        terminal's process group, or to the bench alone: then the bench stops it); wait for it."""
        from bench.stop import deferred

        sys.stdout.flush()  # the results are said before the wait (a pipe buffers them otherwise)
        try:
            self.rerun.proc.wait()
        except KeyboardInterrupt:
            with deferred():  # a second signal must not leave the server behind
                self.rerun.kill()
        with deferred():
            self.plots.kill()

    def abort(self) -> None:
        from bench.stop import deferred

        with deferred():
            self.rerun.kill()
            self.plots.kill()


# ---------------------------------------------------------------------- the helper processes
def _rerun_role(spec: dict[str, Any], msgs: Any, reply: Any) -> int:
    from bench.view import serve
    from bench.view.rerun_sink import RerunSink

    folder = Path(spec["folder"])
    try:
        sink = RerunSink(
            spec["name"],
            folder / "run.rrd" if spec["rrd"] else None,
            live=spec["live"],
            live_decimate=spec["live_decimate"],
            web_port=spec["web_port"],
            grpc_port=spec["grpc_port"],
            bind=spec.get("bind", serve.DEFAULT_BIND),
        )
    except Exception as exc:  # noqa: BLE001 - the bench reports it
        reply(error=str(exc))
        return 2
    reply(ready=True, url=sink.url)
    for kind, *payload in msgs:
        if kind == "begin":
            sink.begin(payload[0])
        elif kind == "chunk":
            sink.write(payload[0])
        elif kind == "finish":
            sink.end(payload[0]["summary"])
    reply(files=["run.rrd"] if spec["rrd"] else [])
    if spec["live"] == "serve":
        _serve_until(sink.url or "", spec.get("serve_for"), reply.fd)
        sink.close()
        serve.stop()  # the ports are free when this process ends
        os._exit(0)  # skip rerun's teardown (its stream's server is gone)
    elif spec["live"] == "none":
        os._exit(0)  # the recording is complete (end() flushed and closed it): skip rerun's slow teardown
    sink.close()
    return 0


def _without_rerun(spec: dict[str, Any], msgs: Any, reply: Any, why: str) -> int:
    """rerun-sdk is an extra (pyproject.toml [view]): without it a run has no run.rrd and no live viewer, said once;
    serving a viewer is refused."""
    from bench.extras import missing_extra

    if spec["live"] == "serve":
        reply(error=missing_extra("view", "--serve (the web viewer)", why))
        return 2
    print(f"bench: no run.rrd: {missing_extra('view', 'a Rerun recording', why)}", file=sys.stderr, flush=True)
    reply(ready=True, url=None)
    for _ in msgs:
        pass
    reply(files=[])
    return 0


def _serve_until(url: str, seconds: float | None, reply_fd: int) -> None:
    """Serve until `seconds` (None: no limit), Ctrl-C or SIGTERM, or the bench's end: the bench holds the
    read end of the reply pipe, so its write end here reports an error (POLLERR) once the bench is gone,
    however it ended (SIGKILL included)."""
    import select
    import signal
    import time

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    until = "until Ctrl-C" if seconds is None else f"for {seconds:g} s (Ctrl-C stops)"
    print(f"rerun: serving the web viewer at {url} {until}", flush=True)
    gone = select.poll()
    gone.register(reply_fd, 0)  # POLLERR and POLLHUP are always reported
    deadline = None if seconds is None else time.monotonic() + seconds
    try:
        while True:
            left = 1.0 if deadline is None else min(1.0, deadline - time.monotonic())
            if left <= 0:
                return
            if gone.poll(left * 1000):
                print("rerun: the bench ended; stopped serving", flush=True)
                return
    except KeyboardInterrupt:
        print("rerun: stopped serving", flush=True)


def _plots_role(spec: dict[str, Any], msgs: Any, reply: Any) -> int:
    from bench.view import plots

    reply(ready=True)
    folder = Path(spec["folder"])
    files: list[str] = []
    for kind, *payload in msgs:
        if kind == "finish":
            p = payload[0]
            steps = plots.step_plots(folder, p["windows"], p["summary"]["steps"], p["title"])
            ov = plots.overview_plot(folder, p["envelopes"], p["title"], p["summary"]["Ts_s"])
            files += [x.name for x in steps] + ([ov.name] if ov else [])
    reply(files=files)
    os._exit(0)  # nothing left to tidy


def main(role: str, reply_fd: int) -> int:
    import signal

    # Ctrl-C is the bench's to handle (it stops these processes); only serving listens to it (see
    # _serve_until). SIGTERM (the bench stopping this process) unwinds, stopping what it started.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked by the bench while it started us

    def terminate(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, terminate)
    try:
        return _main(role, reply_fd)
    except KeyboardInterrupt:
        serve = sys.modules.get("bench.view.serve")  # only what was started (a plain install has no rerun)
        if serve is not None:
            serve.stop()
        os._exit(130)


def _main(role: str, reply_fd: int) -> int:
    replies = os.fdopen(reply_fd, "w")
    timing = os.environ.get("BENCH_TIMING") == "1"
    import time

    t0 = time.monotonic()

    def reply(**msg: Any) -> None:
        if timing:
            print(f"[{role} +{time.monotonic() - t0:.3f} s] {list(msg)}", file=sys.stderr, flush=True)
        replies.write(json.dumps(msg) + "\n")
        replies.flush()

    reply.fd = reply_fd  # type: ignore[attr-defined]
    # Import what the role needs at once, while the bench starts up.
    without = None  # the extra whose package is not installed: the role does without it
    if role == "rerun":
        try:
            from bench.view import rerun_sink  # noqa: F401
        except ImportError as exc:
            import importlib.util

            if importlib.util.find_spec("rerun") is not None:
                raise  # rerun is there and broken: its own error, not "install the extra"
            without = str(exc)
    else:
        from bench.view import plots  # noqa: F401
    stdin = sys.stdin.buffer

    def messages() -> Any:
        while True:
            try:
                yield pickle.load(stdin)
            except EOFError:
                return

    msgs = messages()
    first = next(msgs, None)
    if first is None or first[0] != "spec":  # the bench did not need us
        return 0
    if without is not None:
        return _without_rerun(first[1], msgs, reply, without)
    try:
        return (_rerun_role if role == "rerun" else _plots_role)(first[1], msgs, reply)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001
        reply(error=f"{role} process: {exc}")
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
