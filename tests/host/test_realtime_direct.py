"""Real time on the host without kernel CAN (issue 29): `bench run --bus direct` with scenario.timing = realtime
runs the plant and the drive on threads of their own, the plant paced as plant_node paces itself. Bounds, never
timings: a period no machine can hold must be reported as overruns (the named status, a non-zero exit unless
expected); a run at a period this machine usually holds must equal lockstep bit for bit up to the first period
the plant flags as missed (on a busy machine there may be one: the run says which)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
from bench_cli import bench_cli
from law_util import zero_law_as

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner
from bench.run.verdict.summary import EXIT_CODES

STEP = REPO / "scenarios" / "you2019_step.toml"
PLANT_STATUS_MISSED = 4  # Measurement.status bit 2 (plant.eds BitNames)


def _run(out: Path, *sets: str) -> tuple[subprocess.CompletedProcess[str], dict[str, Any]]:
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--out", out, "--no-viewer", *(a for s in sets for a in ("--set", s))
    )
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    return res, summary


def test_a_period_no_machine_holds_is_reported_as_overruns(tmp_path: Path) -> None:
    # 2 us: no Linux thread wakes, runs a CANopen SYNC and gets the drive's answer every 2 us
    res, s = _run(tmp_path / "short", "scenario.timing=realtime", "drive.Ts_s=2e-6", "scenario.periods=2000")
    assert res.returncode == EXIT_CODES["realtime_overrun"], res.stdout + res.stderr
    assert s["status"] == "realtime_overrun"
    plant = s["realtime"]["plant"]
    assert plant["periods"] >= 2000
    assert plant["overruns"] + plant["sync_overruns"] > 0
    assert plant["sync_lateness_max_us"] >= plant["sync_lateness_p99_us"] >= plant["sync_lateness_p50_us"] >= 0
    assert "overrun" in res.stdout.lower()
    assert "bench run: real time: " in res.stdout  # what it got of SCHED_FIFO / mlockall, in one line
    # expected by the scenario: the same run passes
    res2, s2 = _run(
        tmp_path / "expected",
        "scenario.timing=realtime",
        "drive.Ts_s=2e-6",
        "scenario.periods=2000",
        'scenario.expect=["realtime_overrun"]',
    )
    assert s2["status"] == "realtime_overrun"
    assert res2.returncode == 0, res2.stdout + res2.stderr


def test_real_time_equals_lockstep_up_to_the_first_flagged_period(hil_run: HilRunner) -> None:
    lockstep = hil_run(STEP, ["drive.Ts_s=100e-6"], bus="direct", name="lockstep")
    realtime = hil_run(STEP, ["drive.Ts_s=100e-6", "scenario.timing=realtime"], bus="direct", name="realtime")
    s_r = realtime.summary
    assert lockstep.exit_code == 0, lockstep.stdout + lockstep.stderr
    assert "realtime" not in lockstep.summary  # lockstep summaries are unchanged
    a, b = lockstep.traces, realtime.traces
    assert len(a) == len(b) == 200
    flagged = np.flatnonzero(np.nan_to_num(b["status"]).astype(np.int64) & PLANT_STATUS_MISSED)
    plant = s_r["realtime"]["plant"]
    print(f"real time at 100 us: status {s_r['status']}, overruns {plant['overruns']}, flagged periods {flagged}")
    if plant["overruns"] == 0 and plant["sync_overruns"] == 0:
        assert s_r["status"] == "ok" and realtime.exit_code == 0, realtime.stdout
        assert len(flagged) == 0
    else:
        assert s_r["status"] == "realtime_overrun" and realtime.exit_code != 0
        # a missed command is an overrun flagged in the next sample; a command that came after its deadline but
        # before the (late) SYNC is an overrun too, applied as in lockstep: no flag, the same traces
        assert len(flagged) <= plant["overruns"]
    # the sample after a period whose command was missed says so (its status bit); that period's command, and
    # the drive's trace of the period before (its synchronous TPDOs are one period behind), are the first that
    # may differ
    end = max(0, int(flagged[0]) - 2) if len(flagged) else len(a)
    for name in a.dtype.names:
        assert np.array_equal(a[name][:end], b[name][:end], equal_nan=True), name
    assert plant["periods"] == 200 and plant["commands_timed"] <= 200


def test_without_permission_for_sched_fifo_or_mlockall_one_line_says_so_and_the_run_goes_on(tmp_path: Path) -> None:
    # no CAP_SYS_NICE / CAP_IPC_LOCK (as an ordinary user), real-time priority 0 and 64 KiB of lockable memory
    drop = ["prlimit", "--rtprio=0", "--memlock=65536", "--", "setpriv"]
    drop += ["--bounding-set=-sys_nice,-ipc_lock", "--inh-caps=-sys_nice,-ipc_lock", "--"]
    out = tmp_path / "run"
    args = ["run", str(STEP), "--bus", "direct", "--out", str(out), "--no-viewer"]
    args += ["--set", "scenario.timing=realtime", "--set", "drive.Ts_s=100e-6"]
    res = bench_cli(*args, under=drop)
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("bench run: real time: ")]
    assert len(lines) == 1, res.stdout + res.stderr
    assert "SCHED_FIFO not permitted" in lines[0] and "mlockall not permitted" in lines[0]
    assert "sudo prlimit --pid $$ --rtprio=99 --memlock=unlimited" in lines[0]
    s = json.loads((out / "summary.json").read_text())  # the run went on
    assert s["realtime"]["plant"]["periods"] == 200
    assert res.returncode in (0, EXIT_CODES["realtime_overrun"]), res.stdout + res.stderr


def test_each_overrun_is_named_by_its_cause_beside_the_hosts_floor(tmp_path: Path) -> None:
    # a period no thread can hold: the plant's own SYNCs are late (the cause `plant_late`), and the host's floor,
    # probed before the run, already says that the period cannot be held
    res, s = _run(tmp_path / "short", "scenario.timing=realtime", "drive.Ts_s=2e-6", "scenario.periods=2000")
    rt = s["realtime"]
    causes = rt["bus"]["overrun_causes"]
    assert set(causes) == {"plant_late", "drive_late", "drive_missing", "bus_late"}
    assert causes["plant_late"] > 0, causes
    floor = rt["floor"]
    assert floor["period_us"] == 2.0 and floor["periods"] >= 1000
    assert floor["max_us"] >= floor["p99_us"] >= floor["p50_us"] >= 0
    assert (
        "bench run: the host's floor at Ts = 2 us" in res.stdout
        and "WARNING: this host cannot hold Ts = 2 us" in res.stdout
    )
    assert f"plant_late {causes['plant_late']}" in res.stdout
    # a drive frozen for 300 periods of 100 us: its commands are missing (the cause `drive_missing`), not the plant's
    scenario = tmp_path / "frozen.toml"
    scenario.write_text(
        STEP.read_text() + '\n[[faults]]\nkind = "freeze"\nnode = "drive"\nat_period = 100\nperiods = 300\n'
    )
    args = ["run", str(scenario), "--bus", "direct", "--out", str(tmp_path / "frozen"), "--no-viewer"]
    for kv in ("scenario.timing=realtime", "drive.Ts_s=100e-6", "scenario.periods=600"):
        args += ["--set", kv]
    res = bench_cli(*args)
    s = json.loads((tmp_path / "frozen" / "summary.json").read_text())
    causes = s["realtime"]["bus"]["overrun_causes"]
    assert causes["drive_missing"] >= 150, (causes, res.stdout)  # most of the frozen periods
    assert causes["drive_missing"] > causes["plant_late"], causes
    assert f"drive_missing {causes['drive_missing']}" in res.stdout


def test_a_law_slower_than_the_period_is_named_the_drives_overrun_not_the_plants(tmp_path: Path) -> None:
    # the tests' zero law with a step of 2 * 10^6 volatile additions (milliseconds on any machine) at Ts = 100 us:
    # the drive misses its commands; the plant, which waits for its clock and its frames only, keeps its SYNCs
    law = zero_law_as(tmp_path / "slow_law", "slow_law")
    src = law / "zero_law.c"
    step = "((zero_law_state_t *)state)->steps++;"
    spin = "\n    for (volatile uint32_t i = 0; i < 2000000u; ++i) {\n    }"
    src.write_text(src.read_text().replace(step, step + spin))
    scenario = tmp_path / "slow.toml"
    scenario.write_text((REPO / "tests" / "laws" / "zero_law.toml").read_text().replace('"zero_law"', '"slow_law"'))
    out = tmp_path / "run"
    args = ["run", str(scenario), "--law", str(law), "--bus", "direct", "--out", str(out), "--no-viewer"]
    for kv in ("scenario.timing=realtime", "drive.Ts_s=100e-6", "scenario.periods=300"):
        args += ["--set", kv]
    res = bench_cli(*args, timeout=900)
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "realtime_overrun" and res.returncode != 0, res.stdout + res.stderr
    causes = s["realtime"]["bus"]["overrun_causes"]
    drive = causes["drive_missing"] + causes["drive_late"]
    assert drive >= 150, (causes, res.stdout)  # most of the 300 periods
    assert drive > 5 * causes["plant_late"], causes
    assert f"drive_missing {causes['drive_missing']}" in res.stdout, res.stdout
