"""The CLI run as a user runs it (subprocess)."""

from __future__ import annotations

import re
import sys

import pytest
from bench_cli import bench_cli

from bench.canbus import probe_af_can


def test_help_lists_commands() -> None:
    out = bench_cli("--help").stdout
    for cmd in ("doctor", "vm", "demo"):
        assert cmd in out


def test_doctor_reports_can_and_fallback() -> None:
    res = bench_cli("doctor", expect=0)
    assert "kernel CAN (AF_CAN)" in res.stdout
    if not probe_af_can().af_can:
        assert "errno 97" in res.stdout
        assert "VM fallback" in res.stdout
        assert re.search(r"CAN box: (down|up|booting|stopping)", res.stdout), res.stdout  # the box's state
    for dist in ("python-can", "canopen", "rerun-sdk"):
        assert dist in res.stdout


def test_vm_without_command_is_a_usage_error() -> None:
    res = bench_cli("vm", expect=64)
    assert "give the command" in res.stderr


def test_vm_returns_the_command_status() -> None:
    """`bench vm -- true` exits 0, `bench vm -- sh -c 'exit 3'` exits 3, with a real vcan0 inside."""
    bench_cli(
        "vm",
        "--",
        "sh",
        "-c",
        "ip -d link show vcan0 | grep -q 'vcan' && cat /sys/class/net/vcan0/operstate",
        timeout=600,
        expect=0,
    )
    bench_cli("vm", "--", "sh", "-c", "exit 3", timeout=600, expect=3)


def test_vm_does_not_wait_for_background_processes() -> None:
    """A command that leaves a process running in the guest still returns (the VM powers off)."""
    bench_cli("vm", "--", "sh", "-c", "sleep 100000 & exit 4", timeout=600, expect=4)


def test_vm_timeout_is_enforced_without_output() -> None:
    res = bench_cli("vm", "--timeout", "40", "--", "sleep", "100000", timeout=600, expect=124)
    assert "timed out" in res.stderr


def test_help_lists_no_hidden_command() -> None:
    """The internal `capture` is not listed (a help=SUPPRESS leaked as "capture ==SUPPRESS==")."""
    out = bench_cli("--help").stdout
    assert "SUPPRESS" not in out and "capture" not in out, out


def test_run_help_lists_every_exit_code_of_the_verdict_table() -> None:
    """bench run/replay --help: every status with its exit code, from summary.EXIT_CODES (8, 9 were missing)."""
    import re

    from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET

    for cmd in ("run", "replay"):
        text = " ".join(bench_cli(cmd, "--help").stdout.split())  # argparse wraps lines anywhere
        for status, code in EXIT_CODES.items():
            assert re.search(rf"\b{code} {status}\b", text), (cmd, status, code)
        assert f"{EXIT_EXPECTATION_NOT_MET} expected status not reached" in text


def test_docs_name_only_commands_that_exist() -> None:
    """Every `bench COMMAND` the README and docs show in code exists (the README named a `bench check`)."""
    import re

    from bench.cli import build_parser
    from bench.paths import REPO

    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    commands = set(sub.choices)  # type: ignore[attr-defined]
    bad = []
    for doc in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for code in re.findall(r"`([^`\n]+)`", doc.read_text()):
            for m in re.finditer(r"(?:^|[\s/])bench ([a-z][a-z-]*)", code):
                if m.group(1) not in commands:
                    bad.append(f"{doc.name}: `{code}`")
    assert not bad, bad


def test_the_readme_lists_every_exit_code() -> None:
    """README's "Exit status" paragraph, the one hand-written copy (bench run --help is generated from EXIT_CODES):
    every code of the table, and no other."""
    import re

    from bench.paths import REPO
    from bench.run.command import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INTERRUPTED
    from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET

    text = (REPO / "README.md").read_text()
    para = text[text.index("**Exit status**") :].split("\n\n")[0]
    listed = {int(n) for n in re.findall(r"(?:^|[\s,;:(])(\d{1,3}) (?=[a-z])", para)}
    codes = {*EXIT_CODES.values(), EXIT_EXPECTATION_NOT_MET, EXIT_FAILURE, EXIT_BAD_INPUT, EXIT_INTERRUPTED}
    assert listed == codes


def test_doctor_tells_a_pip_user_pip_and_a_clone_make_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    from bench.tools import doctor

    monkeypatch.setattr(doctor, "INSTALLED", True)  # a pip-installed package: no Makefile to run
    hint = doctor._install_hint("rerun-sdk")
    assert f'{sys.executable} -m pip install "rerun-sdk"' == hint and "make" not in hint
    monkeypatch.setattr(doctor, "INSTALLED", False)
    assert doctor._install_hint("rerun-sdk").startswith("make setup")
