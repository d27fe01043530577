"""The helper processes' side of bench/view/worker.py: what runs in the "rerun" process (the Rerun recording
and live viewer, serving it until its end) and in the "plots" process (the PNG plots), reading the bench's
pickled messages on stdin and replying with JSON lines on the reply pipe. `main` is their entry point
(`python -m bench.view.worker ROLE REPLY_FD`)."""

from __future__ import annotations

import json
import os
import pickle
import sys
from pathlib import Path
from typing import Any


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
            break
    if spec.get("keep") and spec["live"] == "none":
        sink.close()  # before the reply: nothing of this run is said after it (the next run's replies follow)
    reply(files=["run.rrd"] if spec["rrd"] else [], live=sink.live_stats())
    if spec["live"] == "serve":
        _serve_until(sink.url or "", spec.get("serve_for"), reply.fd)
        sink.close()
        serve.stop()  # the ports are free when this process ends
        os._exit(0)  # skip rerun's teardown (its stream's server is gone)
    elif spec["live"] == "none" and not spec.get("keep"):
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
    for kind, *_ in msgs:
        if kind == "finish":
            break
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
            break
    reply(files=files)
    if not spec.get("keep"):
        os._exit(0)  # nothing left to tidy
    return 0


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
    while True:  # one run, or with "keep" in its spec one after another (worker_procs.reuse)
        first = next(msgs, None)
        if first is None or first[0] != "spec":  # the bench did not need us (again)
            if timing:
                print(f"[{role} +{time.monotonic() - t0:.3f} s] end of input", file=sys.stderr, flush=True)
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(0)  # a kept process's end: its recordings are closed, rerun's teardown is skipped
        rc = _one_run(role, first[1], msgs, reply, without)
        if rc or not first[1].get("keep"):
            return rc


def _one_run(role: str, spec: dict[str, Any], msgs: Any, reply: Any, without: str | None) -> int:
    if without is not None:
        return _without_rerun(spec, msgs, reply, without)
    try:
        return (_rerun_role if role == "rerun" else _plots_role)(spec, msgs, reply)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001
        reply(error=f"{role} process: {exc}")
        return 1
