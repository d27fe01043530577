"""The CLI run as a user runs it (subprocess)."""

from __future__ import annotations

import subprocess
import sys

from bench.canbus import probe_af_can

BENCH = [sys.executable, "-m", "bench.cli"]


def run(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*BENCH, *args], capture_output=True, text=True, timeout=timeout)


def test_help_lists_commands() -> None:
    out = run("--help").stdout
    for cmd in ("doctor", "vm", "demo"):
        assert cmd in out


def test_doctor_reports_can_and_fallback() -> None:
    res = run("doctor")
    assert res.returncode == 0, res.stdout
    assert "kernel CAN (AF_CAN)" in res.stdout
    if not probe_af_can().af_can:
        assert "errno 97" in res.stdout
        assert "VM fallback" in res.stdout and "ready" in res.stdout
    for dist in ("python-can", "canopen", "rerun-sdk"):
        assert dist in res.stdout


def test_vm_without_command_is_a_usage_error() -> None:
    res = run("vm")
    assert res.returncode == 64
    assert "give the command" in res.stderr


def test_vm_returns_the_command_status() -> None:
    """`bench vm -- true` exits 0, `bench vm -- sh -c 'exit 3'` exits 3, with a real vcan0 inside."""
    ok = run(
        "vm",
        "--",
        "sh",
        "-c",
        "ip -d link show vcan0 | grep -q 'vcan' && cat /sys/class/net/vcan0/operstate",
        timeout=600,
    )
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad = run("vm", "--", "sh", "-c", "exit 3", timeout=600)
    assert bad.returncode == 3, bad.stdout + bad.stderr


def test_vm_does_not_wait_for_background_processes() -> None:
    """A command that leaves a process running in the guest still returns (the VM powers off)."""
    res = run("vm", "--", "sh", "-c", "sleep 100000 & exit 4", timeout=600)
    assert res.returncode == 4, res.stdout + res.stderr


def test_vm_timeout_is_enforced_without_output() -> None:
    res = run("vm", "--timeout", "40", "--", "sleep", "100000", timeout=600)
    assert res.returncode == 124, res.stdout + res.stderr
    assert "timed out" in res.stderr
