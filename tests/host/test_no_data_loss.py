"""Nothing the user owns is lost: a non-empty --out is refused untouched, and a run whose loop
completed keeps its results when Ctrl-C comes while they are written."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.run import outputs as outputs_mod

STEP = REPO / "scenarios" / "you2019_step.toml"


def _user_folder(tmp_path: Path) -> Path:
    d = tmp_path / "mine"
    (d / "sub").mkdir(parents=True)
    (d / "notes.txt").write_text("my notes")
    (d / "sub" / "data.bin").write_bytes(b"\x00\x01")
    return d


def _untouched(d: Path) -> None:
    assert (d / "notes.txt").read_text() == "my notes"
    assert (d / "sub" / "data.bin").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in d.rglob("*")) == ["data.bin", "notes.txt", "sub"]


@pytest.mark.parametrize(
    "cmd", [["run", str(STEP), "--bus", "direct", "--no-viewer"], ["reproduce", "--paper", "000", "--bus", "direct"]]
)
def test_a_non_empty_out_is_refused_and_untouched(tmp_path: Path, cmd: list[str]) -> None:
    d = _user_folder(tmp_path)
    res = bench_cli(*cmd, "--out", d, timeout=120, expect=2)
    assert str(d) in res.stderr and "empty" in res.stderr
    _untouched(d)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]  # nothing written beside it either


def _run_with_sigints(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, presses: int) -> tuple[int, Path]:
    """`bench run` in this process, with `presses` Ctrl-C (SIGINT to itself) as the results are written."""
    from bench.cli import main

    real = outputs_mod.Outputs.finish

    def finish(self: Any, result: Any) -> None:
        for _ in range(presses):
            os.kill(os.getpid(), signal.SIGINT)
        real(self, result)

    monkeypatch.setattr(outputs_mod.Outputs, "finish", finish)
    monkeypatch.chdir(REPO)
    out = tmp_path / "run"
    rc = main(["run", str(STEP), "--bus", "direct", "--out", str(out), "--no-viewer"])
    return rc, out


def test_one_ctrl_c_while_writing_waits_for_the_results(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    rc, out = _run_with_sigints(tmp_path, monkeypatch, 1)
    assert rc == 0
    for name in ("summary.json", "traces.npy", "bus.log", "run.rrd", "overview.svg"):
        assert (out / name).stat().st_size > 0, name
    assert not list(tmp_path.glob("*.failed*")) and not list(tmp_path.glob("*.partial"))
    assert "finishing its results" in capfd.readouterr().err


def test_two_ctrl_c_while_writing_keep_the_complete_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    rc, out = _run_with_sigints(tmp_path, monkeypatch, 2)
    assert rc == 130
    for name in ("summary.json", "traces.npy", "bus.log"):  # the run's data, whole
        assert (out / name).stat().st_size > 0, name
    import numpy as np

    assert len(np.load(out / "traces.npy")) == 200
    assert not list(tmp_path.glob("*.failed*")) and not list(tmp_path.glob("*.partial"))
    assert "kept in" in capfd.readouterr().err


def test_a_refused_value_names_the_limit_and_leaves_nothing(tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--no-viewer", "--out", out, "--set", "controller.pi_bandwidth_Hz=50000",
        timeout=120, expect=2,
    )  # fmt: skip
    assert "pi_bandwidth_Hz = 50000" in res.stderr and "1/(6 Ts) = 3030.3" in res.stderr, res.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_bus_the_host_cannot_have_is_refused_before_anything_starts(tmp_path: Path) -> None:
    from bench.canbus import probe_af_can

    out = tmp_path / "run"
    res = bench_cli("run", STEP, "--bus", "nonexistent0", "--no-viewer", "--out", out, timeout=120, expect=2)
    assert "nonexistent0" in res.stderr
    if not probe_af_can().af_can:  # this host: the VM supplies virtual buses only, and says so
        assert "vcan0, vcan1" in res.stderr
    assert list(tmp_path.iterdir()) == []
