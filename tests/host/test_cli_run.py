"""`bench run` and `bench replay` as a user runs them (subprocess), in direct mode (`bench sweep`: test_sweep.py)."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from bench_cli import bench_cli, spawn_bench

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner

STEP = REPO / "scenarios" / "you2019_step.toml"


def test_run_direct_writes_every_result(tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = bench_cli("run", STEP, "--bus", "direct", "--out", out, "--no-viewer", expect=0)
    for name in ("summary.json", "traces.npy", "bus.log", "run.rrd", "overview.svg"):
        assert (out / name).stat().st_size > 0, name
    assert list(out.glob("step_*.svg"))
    assert not list(out.glob("*.json"))[1:], "one JSON file: summary.json (the log carries the rest)"
    summary = json.loads((out / "summary.json").read_text())
    step = summary["steps"][0]
    assert step["periods_to_settle"] == 2 and step["overshoot_A"] < 1e-4
    assert summary["bus_stats"]["lost_frames"] == 0 and summary["status"] == "ok"
    tr = np.load(out / "traces.npy")
    assert len(tr) == summary["periods"] == 200 and abs(tr["iq_A"][-1] - 1.0) < 1e-3
    assert "iq" in res.stdout and "results in" in res.stdout
    # the log is a real candump log python-can reads back with every frame
    import can

    assert len(list(can.LogReader(str(out / "bus.log")))) == summary["bus_stats"]["frames"]


@pytest.mark.parametrize("flags", [["--no-rrd"], ["--no-plots"], ["--no-rrd", "--no-plots"]])
def test_run_without_the_recording_or_the_plots(tmp_path: Path, flags: list[str]) -> None:
    """--no-rrd / --no-plots: the same run, its data bit for bit, without what was left out (named so in the
    summary); with both no helper process starts (bench/view/worker_procs.roles_for)."""
    full, lean = tmp_path / "full", tmp_path / "lean"
    bench_cli("run", STEP, "--bus", "direct", "--out", full, "--no-viewer", expect=0)
    bench_cli("run", STEP, "--bus", "direct", "--out", lean, "--no-viewer", *flags, expect=0)
    for name in ("traces.npy", "bus.log"):
        assert (lean / name).read_bytes() == (full / name).read_bytes(), name
    files = json.loads((lean / "summary.json").read_text())["files"]
    assert (files["recording"] is None) == ("--no-rrd" in flags) == (not (lean / "run.rrd").exists()), files
    assert (files["plots"] == []) == ("--no-plots" in flags) == (not list(lean.glob("*.svg"))), files


def test_which_helper_processes_a_run_starts() -> None:
    from bench.view.worker_procs import roles_for, roles_in_argv

    assert roles_for(True, True, "none") == ("rerun", "plots")
    assert roles_for(False, False, "none") == ()
    assert roles_for(False, False, "serve") == ("rerun",)  # the live view needs it, without a file
    assert roles_for(False, True, "spawn") == ("rerun", "plots")
    assert roles_in_argv(["run", "s.toml", "--no-rrd", "--no-plots", "--no-viewer"]) == ()
    assert roles_in_argv(["run", "s.toml", "--no-rrd", "--serve"]) == ("rerun", "plots")


def test_set_overrides_change_the_run(hil_run: HilRunner) -> None:
    run = hil_run(STEP, {"controller.L_hat_ratio": 1.2}, bus="direct")
    assert run.exit_code == 0, run.stderr
    step = run.summary["steps"][0]
    assert step["overshoot_pct"] > 10.0  # L_hat = 1.2 L overshoots (You 2019 Fig. 14)


@pytest.mark.parametrize(
    "content, needle",
    [
        ("[scenario]\nname='x'\nperiods=10\n[controller]\nfoo=1\n", "unknown key 'controller.foo'"),
        ("[scenario]\nname='x'\nperiods=10\n[motor]\nR_ohm=5000\n", "motor.R_ohm = 5000 is out of range: allowed"),
        ("[scenario]\nname='x'\nperiods=10\n[drive]\nmod_limit='square'\n", "expected one of none, hexagon, circle"),
        ("[scenario]\nname='x'\nperiods=0\n", "scenario.periods = 0"),
        ("[scenario\nname='x'\n", "not valid TOML"),
        (
            "[scenario]\nname='x'\nperiods=10\n[[events]]\nat_period=50\nreferences={iq_ref_A=1.0}\n",
            "events[0].at_period = 50: expected an integer in 0 .. 9",
        ),
    ],
)
def test_bad_scenario_is_refused_before_anything_starts(tmp_path: Path, content: str, needle: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(content)
    out = tmp_path / "out"
    res = bench_cli("run", path, "--bus", "direct", "--out", out, expect=2)
    assert str(path) in res.stderr and needle in res.stderr, res.stderr
    assert not out.exists() and not list(tmp_path.glob("out.*"))


def test_bad_override_names_the_key(tmp_path: Path) -> None:
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--out", tmp_path / "o", "--set", "controller.L_hat_ratio=500", expect=2
    )
    assert "controller.L_hat_ratio" in res.stderr and "0.01 .. 100" in res.stderr


def test_replay_of_an_asc_log_gives_the_same_traces(tmp_path: Path) -> None:
    out = tmp_path / "run"
    bench_cli("run", STEP, "--bus", "direct", "--out", out, "--no-viewer", "--log-format", "asc", expect=0)
    bench_cli("replay", out / "bus.asc", "--no-viewer", expect=0)
    a, b = np.load(out / "traces.npy"), np.load(out / "replay" / "traces.npy")
    for key in ("i_a_A", "i_b_A", "v_alpha_V", "v_beta_V", "iq_ref_A", "K1_hat_V_A"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_replay_refuses_a_file_that_is_not_a_log(tmp_path: Path) -> None:
    bogus = tmp_path / "x.log"
    bogus.write_text("hello\n")
    res = bench_cli("replay", bogus, "--no-viewer", expect=2)
    assert "x.log" in res.stderr
    assert not (tmp_path / "replay").exists()  # bad input: nothing written


def test_sigint_mid_run_stops_cleanly(tmp_path: Path) -> None:
    """Ctrl-C during a long direct run: exit 130, no result folder pretending to be complete. The signal
    goes once the loop is recording (its bus.log growing), whatever the machine's load made of start-up,
    and to a process whose Ctrl-C is the terminal's default (a CI runner may start the suite with SIGINT
    ignored, as a shell's background job does: the child would inherit that)."""
    out = tmp_path / "long"
    proc = spawn_bench(
        "run", STEP, "--bus", "direct", "--out", out, "--no-viewer", "--set", "scenario.periods=20000000"
    )
    try:
        log = tmp_path / "long.partial" / "bus.log"
        deadline = time.monotonic() + 600  # a bound for a loaded machine's start-up, not a timing
        while proc.poll() is None and time.monotonic() < deadline and not (log.exists() and log.stat().st_size):
            time.sleep(0.1)
        assert proc.poll() is None and log.exists(), "the run never started recording"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err, err
    assert not out.exists()
    assert (tmp_path / "long.failed").exists()


def test_trace_table_selects_the_traced_signals(tmp_path: Path) -> None:
    path = tmp_path / "trace.toml"
    path.write_text(
        STEP.read_text() + '\n[trace]\npdo3 = ["Drive status.iq_ref_active_A", "Drive status.speed_rad_s"]\n'
    )
    out = tmp_path / "run"
    bench_cli("run", path, "--bus", "direct", "--out", out, "--no-viewer", expect=0)
    tr = np.load(out / "traces.npy")
    assert tr["drive_iq_ref_active_A"][-2] == 1.0 and "det_A2" not in tr.dtype.names  # last: sent at the next SYNC
    bad = tmp_path / "bad.toml"
    bad.write_text(
        STEP.read_text() + '\n[trace]\npdo3 = ["Controller.Ts_s", "Drive status.iq_A", "Drive status.id_A"]\n'
    )
    res = bench_cli("run", bad, "--bus", "direct", "--out", tmp_path / "b", expect=2)
    assert "trace.pdo3" in res.stderr


def test_replay_of_a_runs_own_log_gives_the_runs_summary(hil_run: HilRunner, tmp_path: Path) -> None:
    """The log carries the layout, the settings and the statuses: replay = run, with no file beside it."""
    demo = REPO / "scenarios" / "demo_you2019_tuning.toml"  # tuning switched on mid-run, identification
    run = hil_run(demo, bus="direct")
    assert run.exit_code == 0, run.stderr
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / "bus.log").write_bytes(run.bus_log.read_bytes())  # nothing else beside it
    bench_cli("replay", alone / "bus.log", "--no-viewer", expect=0)
    a = run.summary
    b = json.loads((alone / "replay" / "summary.json").read_text())
    for key in (
        "status",
        "periods",
        "Ts_s",
        "steps",
        "identified",
        "plant",
        "controller",
        "counters",
        "settings",
        "bus_stats",
    ):
        assert a[key] == b[key], key
    assert any(s["tuning_on"] for s in a["steps"]) and not all(s["tuning_on"] for s in a["steps"])
    assert a["identified"]["K1_bar_V_A"] is not None
    ta, tb = run.traces, np.load(alone / "replay" / "traces.npy")
    assert ta.dtype == tb.dtype
    for name in ta.dtype.names:
        np.testing.assert_array_equal(ta[name], tb[name], err_msg=name)


@pytest.mark.parametrize("cmd", ["run", "cia402", "faults", "reproduce", "replay", "sweep"])
def test_out_inside_the_vm_but_not_shared_is_refused(tmp_path: Path, cmd: str) -> None:
    """Inside `bench vm` a folder the VM does not share with the host (its /tmp) is lost when it stops:
    refused before anything runs (exit 2, the folder and the shared ones named), nothing written."""
    shared, private = tmp_path / "shared", tmp_path / "vm-own" / "out"
    shared.mkdir()
    (shared / "bus.log").write_text("(1.000000) vcan0 080#\n")
    argv = {
        "run": ["run", str(STEP), "--bus", "direct", "--no-viewer"],
        "cia402": ["run", str(STEP), "--bus", "vcan0", "--drive-profile", "cia402"],
        "faults": ["faults", "--only", "drop-command"],
        "reproduce": ["reproduce", "--paper", "000", "--bus", "direct"],
        "replay": ["replay", str(shared / "bus.log")],
        "sweep": ["sweep", str(STEP), "--grid", "controller.L_hat_ratio=0.5,1.0"],
    }[cmd]
    env = {"BENCH_IN_VM": "1", "BENCH_VM_SHARED": f"{REPO}{os.pathsep}{shared}"}
    res = bench_cli(*argv, "--out", private, env=env, expect=2)
    assert f"{private} is inside the VM's own file system" in res.stderr and str(shared) in res.stderr, res.stderr
    assert not (tmp_path / "vm-own").exists()


def test_a_scenario_found_only_among_the_bench_own_is_named(tmp_path: Path) -> None:
    """A relative scenario path this folder lacks runs the bench's bundled scenario of that name, and says so; a
    user's own file of that name is used without a word."""
    rel = "scenarios/you2019_step.toml"
    argv = ["run", rel, "--bus", "direct", "--no-viewer", "--set", "scenario.periods=40"]
    res = bench_cli(*argv, "--out", tmp_path / "a", cwd=tmp_path, expect=0)
    assert f"{rel} is not in {tmp_path}: using the bench's own {REPO / rel}" in res.stderr
    assert res.stderr.count("using the bench's own") == 1
    own = tmp_path / rel
    own.parent.mkdir()
    own.write_text(STEP.read_text().replace('name = "you2019-step"', 'name = "mine"'))
    res = bench_cli(*argv, "--out", tmp_path / "b", cwd=tmp_path, expect=0)
    assert "using the bench's own" not in res.stderr
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["scenario"] == "mine"
