"""`bench replay LOG` says what the log is: cut short, with lines that are no frame, with frames of
another kind only, or no file at all; it names the run from the log and lists only what it wrote."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest
from bench_cli import bench_cli

from bench.paths import REPO

STEP = REPO / "scenarios" / "you2019_step.toml"


@pytest.fixture(scope="module")
def log_text(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    out = tmp_path_factory.mktemp("run") / "run"
    bench_cli("run", STEP, "--bus", "direct", "--out", out, "--no-viewer", expect=0)
    return (out / "bus.log").read_bytes()


def replay(tmp_path: Path, body: bytes, name: str = "bus.log") -> tuple[subprocess.CompletedProcess[str], Path]:
    d = tmp_path / "logs"
    d.mkdir(exist_ok=True)
    (d / name).write_bytes(body)
    return bench_cli("replay", d / name, "--no-viewer"), d / "replay"


def test_a_log_cut_mid_line_is_said_truncated(tmp_path: Path, log_text: bytes) -> None:
    cut_at = len(log_text) * 2 // 3
    cut_at = log_text.index(b" ", log_text.index(b"\n", cut_at) + 1) + 4  # inside the next line's channel/frame
    body = log_text[:cut_at]
    line = body.count(b"\n") + 1
    res, out = replay(tmp_path, body)
    assert res.returncode != 0  # the run the log records is not all there
    said = res.stdout + res.stderr
    assert "TRUNCATED" in said and f"line {line}" in said, said
    assert re.search(rf"status: FRAMES_LOST at period \d+: .*truncated .*line {line}", res.stdout), res.stdout
    log = json.loads((out / "summary.json").read_text())["log"]
    assert log["truncated_line"] == line and log["truncated_line_dropped"] is True
    assert log["unparsable_lines"] == 0 and log["frames_skipped"] == 0


def test_garbage_lines_are_unparsable_not_skipped_frames(tmp_path: Path, log_text: bytes) -> None:
    lines = log_text.splitlines(keepends=True)
    body = b"".join([*lines[:5], b"hello world\n", *lines[5:9], b"\x00\x01 not a frame\n", *lines[9:]])
    res, out = replay(tmp_path, body)
    assert res.returncode == 0, res.stderr
    assert "0 frames skipped" in res.stdout and "2 unparsable lines" in res.stdout, res.stdout
    assert "first at line 6" in res.stdout and "TRUNCATED" not in res.stdout
    log = json.loads((out / "summary.json").read_text())["log"]
    assert (log["unparsable_lines"], log["first_unparsable_line"], log["frames_skipped"]) == (2, 6, 0)
    assert log["truncated_line"] is None


def test_an_extended_id_only_log_says_what_it_holds(tmp_path: Path) -> None:
    n = 25
    body = b"".join(b"(1700000000.%06d) can0 18FF%04X#0102030405060708\n" % (i, i) for i in range(n))
    res, out = replay(tmp_path, body)
    assert res.returncode == 2
    assert f"{n} extended-ID" in res.stderr and "no 11-bit CANopen frame" in res.stderr, res.stderr
    assert not out.exists()


def test_a_directory_is_said_a_directory(tmp_path: Path) -> None:
    res = bench_cli("replay", tmp_path, "--no-viewer", expect=2)
    assert "is a directory" in res.stderr and "no such file" not in res.stderr, res.stderr


def test_replay_is_named_from_the_log_and_lists_what_it_wrote(tmp_path: Path, log_text: bytes) -> None:
    res, out = replay(tmp_path, log_text, name="motor_a.log")
    assert res.returncode == 0, res.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"] == "motor_a.log"
    listed = res.stdout.rsplit("results in", 1)[1].split(":", 1)[1].strip()
    names = [n.strip() for n in listed.split(",")]
    assert "bus.log" not in names
    for n in names:
        assert "*" in n or "plots" in n or (out / n).is_file(), n


def test_a_claim_runs_log_replays_to_the_trace_it_decoded(tmp_path: Path) -> None:
    """`bench reproduce` decodes each run once, as it runs (its traces.npy, from which the run's recording and
    figure are made): the CAN log it keeps beside them must replay to that trace and summary, bit for bit. A
    claim run in direct mode writes its log with the candump writer while it runs (bench/claims run_raw)."""
    import numpy as np

    from bench import claims
    from bench.claims import run_raw
    from bench.claims.you2019 import base
    from bench.run.pipeline import replay_log

    old = claims.RUN_ROOT
    claims.RUN_ROOT = tmp_path / "runs"
    claims.RUN_ROOT.mkdir()
    try:
        run = run_raw(base("you2019-replay-truth"), "direct")
    finally:
        claims.RUN_ROOT = old
        claims.RUNS_USED.clear()
    assert run.out is not None
    kept = np.load(run.out / "traces.npy")
    res = replay_log(run.out / "bus.log", keep_trace=True)
    assert res.trace is not None and len(kept) == res.summary["periods"] > 0
    assert set(kept.dtype.names or ()) == set(res.trace)
    for name in kept.dtype.names or ():
        np.testing.assert_array_equal(kept[name], res.trace[name].astype(kept[name].dtype), err_msg=name)
        np.testing.assert_array_equal(kept[name], run.tr[name].astype(kept[name].dtype), err_msg=name)
    summary = json.loads((run.out / "summary.json").read_text())
    for key in ("status", "periods", "steps", "identified", "plant", "controller", "counters", "bus_stats"):
        assert summary[key] == res.summary[key], key
