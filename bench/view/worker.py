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
        r, w = os.pipe()
        self.role = role
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "bench.view.worker", role, str(w)], stdin=subprocess.PIPE, pass_fds=(w,)
        )
        os.close(w)
        self._replies = os.fdopen(r, "rb")
        self._queue: queue.Queue[tuple[Any, ...] | None] = queue.Queue(maxsize=8)
        self.error: BaseException | None = None
        self._writer = threading.Thread(target=self._write_loop, daemon=True, name=f"bench-{role}-writer")
        self._writer.start()

    def _write_loop(self) -> None:
        assert self.proc.stdin is not None
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

    def recv(self) -> dict[str, Any]:
        line = self._replies.readline()
        if not line:
            code = self.proc.wait()
            raise RuntimeError(f"the {self.role} process ended (status {code}); see its message above")
        msg = json.loads(line)
        if msg.get("error"):
            raise RuntimeError(msg["error"])
        return msg  # type: ignore[no-any-return]

    def kill(self) -> None:
        try:
            self._queue.put_nowait(None)
        except queue.Full:
            pass
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def prestart() -> None:
    """Start the helper processes now, so that their imports run while the bench imports its own."""
    for role in ROLES:
        if role not in _STARTED:
            _STARTED[role] = _Proc(role)


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
        }
        self.rerun = _take("rerun")
        self.plots = _take("plots")
        self.rerun.send("spec", self.spec)
        self.plots.send("spec", self.spec)
        self.live = live
        self.url: str | None = None
        self._ready = False

    def wait_ready(self) -> None:
        """Block until the rerun process has its viewer up (serving: the ports are taken, or the error is known)."""
        if not self._ready:
            self.url = self.rerun.recv().get("url")
            self._ready = True

    def begin(self, signals: list[Any], ctx: Any = None) -> None:
        self.rerun.send("begin", signals)

    def write(self, chunk: dict[str, Any]) -> None:
        self.rerun.send("chunk", chunk)

    def end(self, summary: dict[str, Any]) -> None:
        pass  # the plots need the step windows too: see finish()

    def finish(self, result: Any, title: str) -> None:
        """Hand over what the plots need; both processes finish while the caller writes its own files."""
        self.rerun.send("finish", {"summary": result.summary})
        self.plots.send(
            "finish",
            {"summary": result.summary, "windows": result.step_windows, "envelopes": result.envelopes, "title": title},
        )
        self.rerun.close_input()
        self.plots.close_input()

    def finish_wait(self) -> list[str]:
        """The files written (run.rrd and the PNGs), once both processes are done with them."""
        self.wait_ready()
        files = list(self.rerun.recv().get("files", []))
        self.plots.recv()  # ready
        files += list(self.plots.recv().get("files", []))
        return files

    def serve(self, seconds: float | None) -> None:
        """With a live viewer: the rerun process keeps serving until Ctrl-C or `seconds`; wait for it."""
        try:
            self.rerun.proc.wait()
        except KeyboardInterrupt:
            self.rerun.proc.wait()
        self.plots.proc.wait()

    def abort(self) -> None:
        self.rerun.kill()
        self.plots.kill()


# ---------------------------------------------------------------------- the helper processes
def _rerun_role(spec: dict[str, Any], msgs: Any, reply: Any) -> int:
    from .rerun_sink import RerunSink

    folder = Path(spec["folder"])
    try:
        sink = RerunSink(
            spec["name"],
            folder / "run.rrd" if spec["rrd"] else None,
            live=spec["live"],
            live_decimate=spec["live_decimate"],
            web_port=spec["web_port"],
            grpc_port=spec["grpc_port"],
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
        import signal

        signal.signal(signal.SIGINT, signal.default_int_handler)  # Ctrl-C ends serving
        try:
            sink.serve_until(spec.get("serve_for"))
        except KeyboardInterrupt:
            pass
    elif spec["live"] == "none":
        os._exit(0)  # the recording is complete (end() flushed and closed it): skip rerun's slow teardown
    sink.close()
    return 0


def _plots_role(spec: dict[str, Any], msgs: Any, reply: Any) -> int:
    from . import plots

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

    # Ctrl-C is the bench's to handle (it stops these processes); only serving listens to it (see below).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    replies = os.fdopen(reply_fd, "w")
    timing = os.environ.get("BENCH_TIMING") == "1"
    import time

    t0 = time.monotonic()

    def reply(**msg: Any) -> None:
        if timing:
            print(f"[{role} +{time.monotonic() - t0:.3f} s] {list(msg)}", file=sys.stderr, flush=True)
        replies.write(json.dumps(msg) + "\n")
        replies.flush()

    # Import what the role needs at once, while the bench starts up.
    if role == "rerun":
        from . import rerun_sink  # noqa: F401
    else:
        from . import plots  # noqa: F401
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
    try:
        return (_rerun_role if role == "rerun" else _plots_role)(first[1], msgs, reply)
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # noqa: BLE001
        reply(error=f"{role} process: {exc}")
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
