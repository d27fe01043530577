"""How bench commands stop and what they listen on, as a user (or a supervisor) sees it: Ctrl-C and
SIGTERM end `--serve` with nothing left behind and the ports free; an interrupt during start-up is one
line and exit 130; a run that does not use its viewer processes does not wait for them; a closed
stdout ends a command quietly; a sweep's Ctrl-C is one line; the served viewer and the sweep's
dashboard listen on this machine only unless asked; SIGTERM to `bench vm` ends its QEMU.

Bounds are generous (a loaded machine); no duration is asserted."""

from __future__ import annotations

import ipaddress
import os
import re
import signal
import socket
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from bench_cli import bench_cli
from stop_util import Bench, descendants, listening, session, wait_gone

from bench.paths import REPO

STEP = str(REPO / "scenarios" / "you2019_step.toml")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def port_free(port: int) -> bool:
    """Nobody listens on `port`, on any address (a bind to every interface succeeds)."""
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("0.0.0.0", port))  # noqa: S104 - probing every interface
        except OSError:
            return False
    return True


def loopback(addr: str) -> bool:
    return ipaddress.ip_address(addr).is_loopback


def serve_run(out: Path, web: int, grpc: int, *more: str) -> Bench:
    return Bench("run", STEP, "--bus", "direct", "--out", str(out), "--serve", "--web-port", str(web),
                 "--grpc-port", str(grpc), "--no-viewer", *more)  # fmt: skip


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_serve_listens_on_this_machine_and_a_signal_to_the_bench_ends_it(tmp_path: Path, sig: signal.Signals) -> None:
    web, grpc = free_port(), free_port()
    b = serve_run(tmp_path / "a", web, grpc)
    try:
        assert b.wait_for("until Ctrl-C", 180) and b.wait_for("results in", 180), b.text()  # results written
        mine = listening(session(b.pid))
        assert {p for _, p in mine} >= {web, grpc}, (mine, b.text())
        assert all(loopback(a) for a, _ in mine), f"listening beyond this machine: {mine}"
        assert re.search(rf"listening on 127\.0\.0\.1:{web} \(web\), 127\.0\.0\.1:{grpc} \(gRPC\)", b.text())
        os.kill(b.pid, sig)  # the bench alone, as `kill PID` does (not the terminal's process group)
        rc = b.finish(120)
        assert rc == 0, f"{sig.name}: still serving or failed ({rc}):\n{b.text()}"  # the run's verdict
        assert not wait_gone(session(b.pid), 60), f"left behind: {session(b.pid)}"
        assert port_free(web) and port_free(grpc), listening(port=web) + listening(port=grpc)
        assert "Traceback" not in b.text(), b.text()
    finally:
        b.kill()
    # the ports are free for the next run; on every interface when asked
    again = serve_run(tmp_path / "b", web, grpc, "--serve-for", "30", "--serve-bind", "0.0.0.0")
    try:
        assert again.wait_for("for 30 s", 180) and again.wait_for("results in", 180), again.text()
        assert ("0.0.0.0", web) in listening(session(again.pid)), listening(session(again.pid))
        assert "other machines can watch" in again.text()
        os.kill(again.pid, signal.SIGTERM)
        assert again.finish(120) == 0, again.text()
    finally:
        again.kill()


def _children(pid: int, within_s: float) -> dict[int, str]:
    deadline = time.monotonic() + within_s
    while not (kids := descendants(pid)) and time.monotonic() < deadline:
        time.sleep(0.01)
    return kids


def test_ctrl_c_while_the_run_starts_is_one_line_and_exit_130(tmp_path: Path) -> None:
    out = tmp_path / "r"
    b = Bench("run", STEP, "--bus", "direct", "--out", str(out), "--no-viewer")
    try:
        # The viewer processes start first thing in main(), before the bench's own imports (~1 s): a
        # Ctrl-C now lands in those imports.
        assert _children(b.pid, 60), b.text()
        os.kill(b.pid, signal.SIGINT)
        rc = b.finish(120)
        assert rc == 130, f"exit {rc}:\n{b.text()}"
        assert "Traceback" not in b.text() and "KeyboardInterrupt" not in b.text(), b.text()
        assert "interrupted" in "".join(b.err), b.text()
        assert not out.exists() and not out.with_name("r.partial").exists(), list(tmp_path.iterdir())
        assert not wait_gone(session(b.pid), 60), f"left behind: {session(b.pid)}"
    finally:
        b.kill()


SLOW_IMPORT = "import time\ntime.sleep(600)  # a viewer process still importing (the VM: minutes)\n"


@pytest.fixture
def slow_views(tmp_path: Path) -> dict[str, str]:
    """An environment in which the viewer processes' imports (rerun, matplotlib) never end."""
    shim = tmp_path / "shim"
    for mod in ("rerun", "matplotlib"):
        (shim / mod).mkdir(parents=True)
        (shim / mod / "__init__.py").write_text(SLOW_IMPORT)
    path = os.pathsep.join([str(shim), str(REPO), os.environ.get("PYTHONPATH", "")])
    return {**os.environ, "PYTHONPATH": path}


def test_a_run_that_fails_before_its_outputs_does_not_wait_for_its_viewer_processes(
    tmp_path: Path, slow_views: dict[str, str]
) -> None:
    b = Bench("run", STEP, "--bus", "direct", "--out", str(tmp_path / "r"), "--set", "nosuch.key=1", env=slow_views)
    try:
        rc = b.finish(120)  # the viewer processes hold the output pipes while they live
        assert rc == 2, f"exit {rc} (None: still running or its output still open):\n{b.text()}"
        assert not wait_gone(session(b.pid), 30), f"left behind: {session(b.pid)}"
    finally:
        b.kill()


def test_a_run_that_stopped_early_does_not_wait_for_viewer_processes_still_starting(
    tmp_path: Path, slow_views: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from bench.view.worker import ViewWorker

    monkeypatch.setenv("PYTHONPATH", slow_views["PYTHONPATH"])
    view = ViewWorker("stopped", tmp_path)
    result = SimpleNamespace(
        summary={"stopped": {"status": "node_lost", "node": "drive"}, "steps": [], "Ts_s": 1e-4},
        step_windows=[],
        envelopes=None,
    )
    files: list[list[str]] = []
    t = threading.Thread(target=lambda: (view.finish(result, "stopped"), files.append(view.finish_wait())))
    t.daemon = True
    t.start()
    t.join(timeout=120)
    try:
        assert not t.is_alive(), "waiting for the viewer processes' imports"
        assert files == [[]] and view.skipped
        assert view.rerun.proc.poll() is not None and view.plots.proc.poll() is not None
        assert not (tmp_path / "run.rrd").exists()
    finally:
        view.rerun.proc.kill()
        view.plots.proc.kill()


def test_a_closed_stdout_ends_a_command_quietly() -> None:
    r, w = os.pipe()
    os.close(r)  # the reader is gone (`bench plan --json | head -1` once head has its line)
    try:
        res = bench_cli("plan", "--json", stdout=w, timeout=120)
    finally:
        os.close(w)
    assert res.returncode == 141, res.stderr
    assert res.stderr == "", res.stderr


def test_a_sweep_listens_on_this_machine_and_its_ctrl_c_is_one_line(tmp_path: Path) -> None:
    out = tmp_path / "sw"
    # 10,001 points (~25 s at ~400 points/s here): still running when the Ctrl-C comes, 3 s after the first points
    grid = "controller.L_hat_ratio=0.5:1.5:0.0001"
    b = Bench("sweep", STEP, "--grid", grid, "--workers", "2", "--out", str(out))
    try:
        assert b.wait_for("points to run", 240), b.text()
        dash = re.search(r"Dask dashboard http://[^:/]+:(\d+)/", b.text())
        assert dash, b.text()
        assert "--dashboard-address" in b.text()
        mine = listening(session(b.pid))
        assert int(dash.group(1)) in {p for _, p in mine}, (mine, b.text())
        assert all(loopback(a) for a, _ in mine), f"listening beyond this machine: {mine}"
        time.sleep(3)  # points running on the workers
        os.killpg(b.pid, signal.SIGINT)  # the terminal's Ctrl-C: the whole process group
        rc = b.finish(240)
        assert rc == 130, f"exit {rc}:\n{b.text()}"
        after = b.text().split("points to run", 1)[1]
        assert "Traceback" not in after and "KeyboardInterrupt" not in after and "WARNING" not in after, after
        said = [ln for ln in after.splitlines() if ln.startswith("bench sweep:")]
        assert len(said) == 1 and "interrupted" in said[0] and "--resume" in said[0], after
        assert str(out) in said[0]
        assert not wait_gone(session(b.pid), 60), f"left behind: {session(b.pid)}"
    finally:
        b.kill()


def test_sigterm_to_bench_vm_ends_its_qemu(tmp_path: Path) -> None:
    b = Bench("vm", "--", "sleep", "600")
    qemu: dict[int, str] = {}
    started: dict[int, str] = {}
    try:
        deadline = time.monotonic() + 240
        while not qemu and time.monotonic() < deadline and b.proc.poll() is None:
            qemu = {p: c for p, c in descendants(b.pid).items() if c.startswith("qemu")}
            time.sleep(0.5)
        assert qemu, f"no QEMU started:\n{b.text()}"
        started = descendants(b.pid)
        time.sleep(5)  # the VM booting
        os.kill(b.pid, signal.SIGTERM)
        rc = b.finish(120)
        assert rc == 143, f"exit {rc}:\n{b.text()[-3000:]}"
        assert not wait_gone(set(started), 60), f"left behind: {started}"
    finally:
        seen = {**started, **qemu}
        for p in set(descendants(b.pid)) | set(seen):  # vng runs in a session of its own
            try:  # only a process still the one seen (a PID freed by its exit may be another's now)
                if p in seen and Path(f"/proc/{p}/comm").read_text().strip() != seen[p]:
                    continue
                os.kill(p, signal.SIGKILL)
            except (ProcessLookupError, OSError):
                pass
        b.kill()
