"""Progress of a run on stderr (bench/run/progress.py): lines without a terminal, a rate that only counts
time that passed, a final line; direct runs show it too."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.run import progress
from bench.run.progress import Progress

RATE = re.compile(r"\(([\d,]+)/s|, ([\d,]+) periods/s")


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def rates(text: str) -> list[float]:
    return [float((a or b).replace(",", "")) for a, b in RATE.findall(text)]


def test_first_update_after_a_boot_gives_no_impossible_rate(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A VM boots (20 s of nothing), then the first update brings 300000 periods at once: no rate from
    that instant; later rates count the periods after it over the time after it; a final line."""
    clock = Clock()
    monkeypatch.setattr(progress.time, "monotonic", clock)
    bar = Progress(1_000_000, "run (VM)", every_s=5.0)
    clock.t += 20.0
    bar.update(300_000)
    first_t, first_n = clock.t, bar.n
    for _ in range(6):
        clock.t += 5.0
        bar.update(100_000)
    bar.close()
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) >= 3, err
    bound = (bar.n - first_n) / (clock.t - first_t)  # the true rate after the first update
    assert rates(err) and all(r <= bound * 1.001 for r in rates(err)), (err, bound)
    assert f"{bar.n}/{bar.total}" in lines[-1] and "done" in lines[-1] and "s" in lines[-1]


def test_close_says_the_end_once_and_nothing_without_progress(capsys: pytest.CaptureFixture[str]) -> None:
    bar = Progress(10, "x")
    bar.close()
    assert capsys.readouterr().err == ""
    bar = Progress(10, "x")
    bar.update(10)
    bar.close()
    bar.close()
    err = capsys.readouterr().err
    assert err.count("10/10") == 1


def test_trace_chunks_move_the_bar() -> None:
    """The run's trace chunks move the active bar within a segment (direct runs had no progress)."""
    sink = progress.ProgressSink()
    bar = Progress(1000, "run")
    sink.bar = bar
    for start in range(0, 1000, 250):
        sink.write({"period": np.arange(start, start + 250)})
        assert bar.n == start + 250
    bar.close()


def test_a_direct_run_without_a_terminal_ends_with_a_progress_line(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["run", str(REPO / "scenarios" / "you2019_step.toml"), "--bus", "direct", "--out", str(out), "--no-viewer"]
    res = bench_cli(*args, expect=0)
    assert re.search(r"run: 200/200 periods done in [\d.]+ s", res.stderr), res.stderr


def test_the_can_test_phase_shows_each_test_as_it_ends(tmp_path: Path) -> None:
    """scripts/run_tests.sh's CAN phase (20 minutes in the VM) printed nothing with -q: its pytest options
    give a line per test as it ends, and the summary line .ci/run greps is still there."""
    script = (REPO / "scripts" / "run_tests.sh").read_text()
    calls = [c for c in script.replace("\\\n", " ").splitlines() if "-m pytest tests/can" in c]
    assert len(calls) >= 2 and all('"${CAN_PYTEST_OPTS[@]}"' in c and " -q" not in c for c in calls), calls
    opts = subprocess.run(
        [
            "bash",
            "-c",
            f"{next(ln for ln in script.splitlines() if ln.startswith('CAN_PYTEST_OPTS='))}; "
            'printf "%s\\n" "${CAN_PYTEST_OPTS[@]}"',
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    (tmp_path / "test_two.py").write_text("def test_alpha():\n    pass\n\n\ndef test_beta():\n    pass\n")
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "test_two.py", *opts],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert res.returncode == 0, res.stdout
    lines = res.stdout.splitlines()
    for name in ("test_alpha", "test_beta"):
        assert any(name in ln and "PASSED" in ln for ln in lines), res.stdout
    grep = re.search(r"grep -E '([^']+)'", (REPO / ".ci" / "run").read_text())
    assert grep is not None
    assert any(re.search(grep.group(1), ln) and "2 passed" in ln for ln in lines), res.stdout
