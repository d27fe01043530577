"""A pytest session that boots the CAN box, as a CI log shows it and as a cancelled CI job ends it (issue 52 item 5;
docs/CI.md "The box in a CI log", "Cancelling a job"): a user's project with one vcan test, through the plugin in a
pytest subprocess (one process, and xdist's -n 2), sent SIGTERM while its run is in the box. The session says on
its terminal (not in the test's captured output) that it boots the box, why, and when it is up, and at its end
one line on the box; the cancelled session stops its run and the box it booted (no QEMU of it left), reports the
test skipped "cancelled by SIGTERM", and prints no traceback (xdist's workers once printed `OSError: cannot send
(already closed?)`). Each session boots a box of its own (~35-110 s here): two sessions, no more."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.run.bus.box import life
from bench.run.bus.vm import readiness

STEP = REPO / "scenarios" / "you2019_step.toml"
PROJECT = f"""
import pytest


@pytest.mark.hil(bus="vcan0")
def test_a_long_vcan_run(hil_run):
    hil_run({str(STEP)!r}, {{"scenario.periods": 500000}}).expect_status("ok")
"""
pytestmark = pytest.mark.skipif(
    not all(ok for _, ok, _ in readiness()), reason="the CAN box needs the VM (virtme-ng, QEMU): make setup"
)


def _box_qemus(keeper_pid: int) -> list[int]:
    """The QEMUs of the box whose keeper was `keeper_pid` (its process group), as tests/host/test_box.py finds them."""
    out = subprocess.run(["pgrep", "-f", "qemu-system-x86_64.*box.control"], capture_output=True, text=True).stdout
    found = []
    for pid in map(int, out.split()):
        try:
            if os.getpgid(pid) == keeper_pid:
                found.append(pid)
        except ProcessLookupError:
            pass
    return found


def _run_in_the_box(proc: subprocess.Popen[bytes], timeout_s: float = 900) -> int:
    """Waits until a run holds a slot of the box (the session booted it first); the box's keeper PID."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and proc.poll() is None:
        info = life.read_info()
        if info is not None and life.is_ready() and any(life.slot_held(s) for s in range(1, info.slots + 1)):
            return info.keeper_pid
        time.sleep(0.5)
    raise AssertionError(f"no run of the session took a slot of the box (session exit status {proc.poll()})")


@pytest.mark.parametrize("xdist", [[], ["-n", "2"]], ids=["one-process", "xdist"])
def test_a_session_says_its_box_and_a_sigterm_stops_the_box_it_booted(tmp_path: Path, xdist: list[str]) -> None:
    bench_cli("box", "down")  # this session boots the box (tests sharing the box run one after another: SERIAL)
    (tmp_path / "test_motor.py").write_text(PROJECT)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    env = {k: v for k, v in os.environ.items() if k != life.OWNER_ENV}
    env["BENCH_BOX"] = "1"  # the box also where the host's kernel could carry vcan0
    argv = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rs", *xdist, "--hil-out=runs", "test_motor.py"]
    with open(tmp_path / "out.txt", "wb") as out, open(tmp_path / "err.txt", "wb") as err:
        proc = subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=out, stderr=err, start_new_session=True)
        try:
            keeper = _run_in_the_box(proc)
            time.sleep(2)  # the run's nodes in the box
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=300)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
    stdout, stderr = (tmp_path / "out.txt").read_text(), (tmp_path / "err.txt").read_text()
    said = stdout + stderr
    assert proc.returncode == pytest.ExitCode.INTERRUPTED, said
    # the box in the log: its boot as it starts (why) and when it is up (in a worker: the start on the worker's
    # stderr, the end through its report), and the session's line at its end
    test = "test_motor.py::test_a_long_vcan_run"
    booting = re.search(r"^(\[gw\d\] )?hil: booting the CAN box for (\S+) \((.*?)\); ", said, re.MULTILINE)
    assert booting is not None and booting[2] == test, said
    assert booting[3] == "asked for (--box or BENCH_BOX=1)", said  # why the box (here: BENCH_BOX=1)
    worker = booting[1] or ""
    assert bool(worker) == bool(xdist) and (not worker or booting[0] in stderr), said
    assert f"{worker}hil: the CAN box is up: booted in " in stdout, said
    if not xdist:  # both lines through the terminal reporter, in their order
        assert stdout.index("hil: booting the CAN box") < stdout.index("hil: the CAN box is up"), said
    end = next((ln for ln in stdout.splitlines() if ln.startswith("hil: CAN box: ")), "")
    assert "booted once by this session (" in end and "; 1 run in it, slot " in end, said
    assert end.endswith("stopped at the session's end (this session booted it; the session was cancelled by SIGTERM)")
    # cancelled: the test skipped naming the signal, no traceback, the run stopped, the box and its QEMU gone
    assert f"SKIPPED [1] {test.split('::')[0]}:" in stdout and "cancelled by SIGTERM" in stdout, said
    assert "Traceback" not in said and "cannot send" not in said and "OSError" not in said, said
    assert life.status()["state"] == "down", said
    assert not _box_qemus(keeper), said
    left = subprocess.run(["pgrep", "-f", f"bench.cli run .*{tmp_path}"], capture_output=True, text=True).stdout
    assert not left.split(), left
