"""Faults over a real bus (vcan0, in the VM on hosts without CAN): the plant on vcan0, the drive on vcan1,
joined by the fault gateway process; the node processes and the gateway built with AddressSanitizer and
UndefinedBehaviorSanitizer (make sanitize). Each check passes as in direct mode, the period-exact faults
give the same traces as direct mode bit for bit, and no sanitizer reports anything."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import bench.claims as claims
from bench.faults.checks import run_checks
from bench.paths import REPO

SANITIZED = REPO / "build" / "sanitize" / "bin"
# faults at exact periods: the traces over vcan must equal direct mode's
SAME_AS_DIRECT = (  # the main ones (all run in direct mode in the host phase; each costs ~40 s in the VM)
    "drop-command",
    "duplicate-measurement",
    "non-finite-measurement",
    "measurement-timeout",
)
TIMED = ("freeze-drive", "kill-drive")  # a process stopped or killed by the gateway: its reaction, not bit identity
SANITIZER = re.compile(r"AddressSanitizer|LeakSanitizer|UndefinedBehaviorSanitizer|runtime error:")


@pytest.fixture
def sanitized(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    for name in ("plant_node", "drive_node", "fault_gateway"):
        assert (SANITIZED / name).exists(), f"{SANITIZED / name} is missing: make sanitize"
    monkeypatch.setenv("BENCH_BIN_DIR", str(SANITIZED))
    monkeypatch.setenv("ASAN_OPTIONS", "abort_on_error=1:detect_leaks=1")
    monkeypatch.setenv("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
    monkeypatch.setattr(claims, "RUN_ROOT", tmp_path)  # every run kept: the processes' output is checked
    return tmp_path


def _clean_output(root: Path) -> None:
    outs = list(root.glob("*/*.out"))
    assert any(p.name == "fault_gateway.out" for p in outs), sorted(p.name for p in outs)
    for p in outs:
        text = p.read_text(errors="replace")
        assert not SANITIZER.search(text), f"{p}: {text[-2000:]}"


@pytest.mark.parametrize("check", SAME_AS_DIRECT + TIMED)
def test_fault_check_over_vcan(vcan0: str, sanitized: Path, check: str) -> None:
    (c,) = run_checks(vcan0, [check])
    assert c.ok, (c.expectation, c.measured)
    _clean_output(sanitized)
    if check in SAME_AS_DIRECT:
        (d,) = run_checks("direct", [check])
        assert len(c.runs) == len(d.runs)
        for rv, rd in zip(c.runs, d.runs, strict=True):
            assert rv.tr.keys() == rd.tr.keys()
            for k in rv.tr:
                if k != "t_s":
                    np.testing.assert_array_equal(rv.tr[k], rd.tr[k], err_msg=f"{check}: {k}")
            fv, fd = rv.result.summary.get("faults"), rd.result.summary.get("faults")
            if fv is not None:  # the same actions at the same periods
                assert [f["action_periods"] for f in fv["injected"]] == [f["action_periods"] for f in fd["injected"]]
