"""The served web viewer (`--serve`): the rerun CLI of the installed rerun-sdk, `rerun --serve-web
--bind ADDR`, hosts the gRPC server and the web viewer on ADDR (127.0.0.1 by default: only this
machine can watch; `--serve-bind 0.0.0.0` for the lab network), and the bench's live stream connects
to it as a gRPC client.

Why a process: rerun-sdk 0.41's Python `serve_web_viewer()` has no bind address and listens on
every interface (rerun issue #5882); the CLI's `--bind` sets both servers' address. The server
process is the sink's child; it dies with it (Linux: PR_SET_PDEATHSIG), at `stop()` and at exit.

Serving happens once per process: the first serve-mode sink starts the server, later ones stream to
it when they ask for the same ports and address, and are refused with a clear error otherwise.
"""

from __future__ import annotations

import atexit
import ipaddress
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import rerun as rr

APPLICATION_ID = "pmsm-hil-bench"
DEFAULT_BIND = "127.0.0.1"
START_S = 60.0  # the server binary is large: its first start on a loaded machine takes seconds

# The command-line options that set the ports, named in the errors. A CLI may override them.
PORT_OPTIONS = {"web": "--web-port", "grpc": "--grpc-port", "bind": "--serve-bind"}


class ServeError(RuntimeError):
    """The web viewer cannot be served as asked (a port in use, or this process already serves elsewhere)."""


def check_bind(bind: str) -> str:
    """An IP address to listen on (IPv4 or IPv6), as given; ValueError otherwise."""
    try:
        return str(ipaddress.ip_address(bind))
    except ValueError:
        raise ValueError(f"{PORT_OPTIONS['bind']} {bind}: give an IP address (127.0.0.1, 0.0.0.0, ::)") from None


def _connect_host(bind: str) -> str:
    """Where this machine reaches a server listening on `bind`."""
    ip = ipaddress.ip_address(bind)
    if ip.is_unspecified:
        return "127.0.0.1" if ip.version == 4 else "::1"
    return bind


def _url_host(bind: str) -> str:
    """The host name a browser uses: localhost for loopback, this machine's name for every interface."""
    ip = ipaddress.ip_address(bind)
    if ip.is_loopback:
        return "localhost"
    if ip.is_unspecified:
        return socket.gethostname()
    return f"[{bind}]" if ip.version == 6 else bind


def web_url(web_port: int, grpc_port: int, bind: str = DEFAULT_BIND) -> str:
    host = _url_host(bind)
    proxy = f"rerun+http://{host}:{grpc_port}/proxy"
    return f"http://{host}:{web_port}/?url={urllib.parse.quote(proxy, safe=':/[]')}"


def _family(host: str) -> socket.AddressFamily:
    return socket.AF_INET6 if ipaddress.ip_address(host).version == 6 else socket.AF_INET


def port_free(port: int, bind: str = DEFAULT_BIND) -> bool:
    """Whether a listener can bind bind:port, as the server would (SO_REUSEADDR)."""
    with socket.socket(_family(bind), socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((bind, port))
        except OSError:
            return False
    return True


def listening(port: int, within_s: float, host: str = "127.0.0.1", alive: Any = None) -> bool:
    """Whether host:port accepts a connection within `within_s` (False at once when `alive()` turns False)."""
    deadline = time.monotonic() + within_s
    while True:
        try:
            with socket.create_connection((host, port), timeout=0.2):
                return True
        except OSError:
            if time.monotonic() >= deadline or (alive is not None and not alive()):
                return False
            time.sleep(0.05)


def port_in_use(what: str, port: int) -> ServeError:
    label = {"web": "web viewer (HTTP)", "grpc": "gRPC"}[what]
    return ServeError(
        f"rerun: {label} port {port} is already in use (another bench or viewer still serving?); "
        f"choose another with {PORT_OPTIONS[what]} (RerunSink {what}_port=)"
    )


def _server_binary() -> str:
    """The rerun CLI binary of the installed rerun-sdk (rerun_cli/rerun; the `rerun` script beside the
    interpreter only runs it in a child of its own, which a stop would leave behind)."""
    import importlib.util

    spec = importlib.util.find_spec("rerun_cli")
    for d in (spec.submodule_search_locations or []) if spec else []:
        exe = Path(d) / ("rerun.exe" if sys.platform == "win32" else "rerun")
        if exe.exists():
            return str(exe)
    raise ServeError("rerun: the rerun CLI of rerun-sdk (rerun_cli/rerun) is not installed; reinstall rerun-sdk")


def _die_with_parent() -> None:  # in the child, before exec: SIGTERM when the parent thread dies
    import ctypes

    ctypes.CDLL(None, use_errno=True).prctl(1, 15)  # PR_SET_PDEATHSIG, SIGTERM


@dataclass
class Served:
    web_port: int
    grpc_port: int
    bind: str
    url: str
    server: subprocess.Popen[bytes]
    owner: rr.RecordingStream  # the stream of the first sink (kept for the process lifetime)

    @property
    def where(self) -> str:
        return f"{self.bind}:{self.web_port} (web), {self.bind}:{self.grpc_port} (gRPC)"


_SERVED: Served | None = None


def served() -> Served | None:
    return _SERVED


def _start(web_port: int, grpc_port: int, bind: str, memory_limit: str) -> subprocess.Popen[bytes]:
    log = tempfile.TemporaryFile()  # noqa: SIM115 - the server's chatter; shown when it fails
    argv = [_server_binary(), "--serve-web", "--bind", bind, "--web-viewer-port", str(web_port), "--port"]
    argv += [str(grpc_port), "--server-memory-limit", memory_limit]
    proc = subprocess.Popen(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=log,
        stderr=subprocess.STDOUT,
        preexec_fn=_die_with_parent if sys.platform == "linux" else None,  # noqa: PLW1509 - one syscall
    )
    proc.log = log  # type: ignore[attr-defined]
    host = _connect_host(bind)
    up = all(listening(p, START_S, host, alive=lambda: proc.poll() is None) for p in (grpc_port, web_port))
    if not up:
        code = proc.poll()
        _terminate(proc)
        for what, port in (("grpc", grpc_port), ("web", web_port)):
            if not port_free(port, bind):  # taken meanwhile
                raise port_in_use(what, port)
        log.seek(0)
        tail = [ln for ln in log.read().decode(errors="replace").splitlines() if ln.strip()][-3:]
        why = f"it ended with status {code}" if code is not None else f"not listening after {START_S:.0f} s"
        raise ServeError(f"rerun: the web viewer server did not start ({why}): {' | '.join(tail)}")
    return proc


def _terminate(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def serve(
    name: str, web_port: int, grpc_port: int, memory_limit: str, bind: str = DEFAULT_BIND
) -> tuple[rr.RecordingStream, Served]:
    """A live recording stream to this process's server (started on first use), and the server."""
    global _SERVED
    bind = check_bind(bind)
    if _SERVED is not None:
        if (_SERVED.web_port, _SERVED.grpc_port, _SERVED.bind) != (web_port, grpc_port, bind):
            raise ServeError(
                f"rerun: this process already serves the web viewer at {_SERVED.url} "
                f"(web port {_SERVED.web_port}, gRPC port {_SERVED.grpc_port}, on {_SERVED.bind}); it serves once "
                f"per process, so it cannot also serve on web port {web_port}, gRPC port {grpc_port}, on {bind}"
            )
        return stream(name, grpc_port, bind), _SERVED
    if web_port == grpc_port:
        raise ServeError(
            f"rerun: the web viewer and the gRPC server need two ports, both were given {web_port}; "
            f"change {PORT_OPTIONS['web']} or {PORT_OPTIONS['grpc']}"
        )
    for what, port in (("grpc", grpc_port), ("web", web_port)):
        if not port_free(port, bind):
            raise port_in_use(what, port)
    proc = _start(web_port, grpc_port, bind, memory_limit)
    atexit.register(stop)
    owner = stream(name, grpc_port, bind)
    _SERVED = Served(web_port, grpc_port, bind, web_url(web_port, grpc_port, bind), proc, owner)
    return owner, _SERVED


def stream(name: str, grpc_port: int, bind: str) -> rr.RecordingStream:
    live = rr.RecordingStream(APPLICATION_ID, recording_id=name)
    host = _connect_host(bind)
    live.connect_grpc(f"rerun+http://{f'[{host}]' if ':' in host else host}:{grpc_port}/proxy")
    return live


def stop() -> None:
    """Stop serving: the server process ends and its ports are free. Idempotent."""
    global _SERVED
    s, _SERVED = _SERVED, None
    if s is not None:
        try:
            s.owner.disconnect()  # before the server goes: rerun's exit would flush to a closed port
        except Exception:  # noqa: BLE001, S110 - stopping anyway
            pass
        _terminate(s.server)
