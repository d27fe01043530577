"""What only shows a run - the Rerun recording (and live viewer) and the PNG plots - in a
second process, so that it runs on the other core beside the loop, the decoding and the
files, and its imports (rerun, matplotlib: ~1 s) overlap with the run.

The bench's process starts the worker first thing and sends it, over a pipe, the signal list,
every trace chunk as it is decoded, and at the end what the plots need (the summary, the step
windows, the envelopes). Messages are pickled tuples; arrays travel as numpy pickles.

    python -m bench.view.worker SPEC_JSON      (started by ViewWorker; not a user command)
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

from ..run.signals import SignalInfo


class ViewWorker:
    """The bench's side: a Sink whose chunks go to the worker process."""

    def __init__(self, name: str, folder: Path, live: str = "none", live_decimate: int = 1, web_port: int = 9090,
                 grpc_port: int = 9876, rrd: bool = True, serve_for: float | None = None) -> None:
        r, w = os.pipe()  # the worker's replies; its stdout and stderr stay the user's
        spec = {"name": name, "folder": str(folder), "live": live, "live_decimate": live_decimate,
                "web_port": web_port, "grpc_port": grpc_port, "rrd": rrd, "serve_for": serve_for, "reply_fd": w}
        self.proc = subprocess.Popen([sys.executable, "-m", "bench.view.worker", json.dumps(spec)],
                                     stdin=subprocess.PIPE, pass_fds=(w,))
        os.close(w)
        self._replies = os.fdopen(r, "rb")
        # A thread writes to the pipe, so the run never waits for the worker (its imports take ~1 s);
        # the queue is bounded (a few chunks), so memory stays bounded if the worker falls behind.
        self._queue: queue.Queue[tuple[Any, ...] | None] = queue.Queue(maxsize=8)
        self._error: BaseException | None = None
        self._writer = threading.Thread(target=self._write_loop, daemon=True, name="bench-view-writer")
        self._writer.start()
        self.live = live
        self.url: str | None = None
        self.files: list[str] = []
        self._ready = False

    def _recv(self) -> dict[str, Any]:
        line = self._replies.readline()
        if not line:
            code = self.proc.wait()
            raise RuntimeError(f"the viewer process ended (status {code}); see its message above")
        return json.loads(line)

    def wait_ready(self) -> None:
        """Block until the worker has its viewer up (serving: the ports are taken, or the error is known)."""
        if not self._ready:
            msg = self._recv()
            if msg.get("error"):
                raise RuntimeError(msg["error"])
            self.url = msg.get("url")
            self._ready = True

    def _write_loop(self) -> None:
        assert self.proc.stdin is not None
        while True:
            msg = self._queue.get()
            if msg is None:
                break
            try:
                pickle.dump(msg, self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            except (BrokenPipeError, OSError) as exc:
                self._error = exc
                break
        try:
            self.proc.stdin.close()
        except OSError:
            pass

    def _send(self, *msg: Any) -> None:
        if self._error is not None:
            self.wait_ready()  # raises with the worker's own reason
            raise RuntimeError("the viewer process stopped reading")
        self._queue.put(msg)

    def begin(self, signals: list[SignalInfo], ctx: Any = None) -> None:
        self._send("begin", signals)

    def write(self, chunk: dict[str, Any]) -> None:
        self._send("chunk", chunk)

    def end(self, summary: dict[str, Any]) -> None:
        pass  # the plots need the step windows too: see finish()

    def finish_wait(self) -> list[str]:
        """After the "finish" message: wait until the recording and the plots are written."""
        self._queue.put(None)
        self._writer.join()
        self.wait_ready()
        msg = self._recv()
        if msg.get("error"):
            raise RuntimeError(msg["error"])
        self.files = list(msg.get("files", []))
        return self.files

    def serve(self, seconds: float | None) -> None:
        """With a live viewer: the worker keeps serving until Ctrl-C or `seconds`; wait for it."""
        try:
            self.proc.wait()
        except KeyboardInterrupt:
            self.proc.wait()

    def abort(self) -> None:
        try:
            self._queue.put_nowait(None)
        except queue.Full:
            pass
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


_REPLIES: Any = None


def _reply(**msg: Any) -> None:
    _REPLIES.write(json.dumps(msg) + "\n")
    _REPLIES.flush()


def main(spec_json: str) -> int:
    global _REPLIES
    spec = json.loads(spec_json)
    _REPLIES = os.fdopen(spec["reply_fd"], "w")
    folder = Path(spec["folder"])
    try:
        from .rerun_sink import RerunSink

        sink = RerunSink(spec["name"], folder / "run.rrd" if spec["rrd"] else None, live=spec["live"],
                         live_decimate=spec["live_decimate"], web_port=spec["web_port"], grpc_port=spec["grpc_port"])
    except Exception as exc:  # noqa: BLE001 - the bench reports it
        _reply(error=str(exc))
        return 2
    _reply(ready=True, url=sink.url)
    from . import plots  # import while the run goes on

    stdin = sys.stdin.buffer
    files: list[str] = []
    try:
        while True:
            try:
                kind, *payload = pickle.load(stdin)
            except EOFError:
                break
            if kind == "begin":
                sink.begin(payload[0])
            elif kind == "chunk":
                sink.write(payload[0])
            elif kind == "finish":
                p = payload[0]
                sink.end(p["summary"])
                files = ["run.rrd"] if spec["rrd"] else []
                steps = plots.step_plots(folder, p["windows"], p["summary"]["steps"], p["title"])
                ov = plots.overview_plot(folder, p["envelopes"], p["title"], p["summary"]["Ts_s"])
                files += [x.name for x in steps] + ([ov.name] if ov else [])
    except Exception as exc:  # noqa: BLE001
        _reply(error=f"viewer process: {exc}")
        return 1
    _reply(files=files)
    _REPLIES.close()
    if spec["live"] == "serve":
        try:
            sink.serve_until(spec.get("serve_for"))
        except KeyboardInterrupt:
            pass
    sink.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
