"""Faults on purpose in direct mode: every fault check, the [[faults]] table's errors, determinism, the
report in summary.json and the events panel in Rerun, `bench faults` as a user runs it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from bench_cli import bench_cli
from rerun.chunk import RrdReader

from bench.faults.checks import CHECKS, run_checks
from bench.faults.scenario import base, with_command_timeout, with_fault
from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.scenario import ScenarioError, load, parse

SCEN = REPO / "scenarios" / "faults" / "you2019_drop_command.toml"


@pytest.mark.parametrize("check", list(CHECKS))
def test_fault_check_passes_in_direct_mode(check: str) -> None:
    (c,) = run_checks("direct", [check])
    assert c.ok, (c.expectation, c.measured)


def test_the_checks_through_another_law_judge_its_recovery_by_its_own_step() -> None:
    """`bench faults --set controller.controller=pi`: the runs are the PI's (its step settles in more than the
    deadbeat's 2 periods, and that is the recovery bound); the protocol reactions pass as for the deadbeat."""
    law = ("controller.controller=pi",)
    (pi,) = run_checks("direct", ["drop-command"], law)
    (db,) = run_checks("direct", ["drop-command"])
    assert pi.ok and db.ok, (pi.measured, db.measured)
    assert db.measured["bound_periods"] == 2 < pi.measured["bound_periods"]
    assert {r.result.summary["identified"]["controller"] for r in pi.runs} == {"pi"}
    (short,) = run_checks("direct", ["short-measurement"], law)
    assert short.ok and short.measured["bound_A"] == pytest.approx(0.02), short.measured


def test_a_check_a_law_cannot_be_judged_by_fails_with_a_note() -> None:
    """Open loop never drives i_b into [1, 2) A: the non-finite check has no period to corrupt and says so
    (not judged, not ok) instead of raising; the drop check's recovery is then not judged either."""
    (nf,) = run_checks("direct", ["non-finite-measurement"], ("controller.controller=open_loop",))
    assert not nf.ok and "not judged" in nf.measured["note"], nf.measured


def test_bench_faults_refuses_a_bad_setting_before_any_run(tmp_path: Path) -> None:
    res = bench_cli("faults", "--set", "controller.Vmax_V=-5", "--out", tmp_path / "f", expect=2)
    assert "controller.Vmax_V = -5 is out of range: allowed 0 .. 2000" in res.stderr
    assert "[1/" not in res.stdout and not (tmp_path / "f").exists()


def test_a_check_fails_when_the_reaction_is_wrong() -> None:
    """The checks can fail: with the drive's measurement timeout off (0x2209:01 = 0) there is no safe state."""
    from bench.claims import run_raw

    raw = with_command_timeout(base("fc-timeout-off"))
    raw["controller"]["meas_timeout_periods"] = 0
    hit = run_raw(
        with_fault(raw, ["frames_lost"], {"kind": "drop", "frame": "plant.TPDO2", "at_period": 30, "periods": 6}),
        "direct",
    )
    assert not [e for e in hit.result.summary["emcy"] if e["code"] == "0xFF03"]


@pytest.mark.parametrize(
    ("fault", "message"),
    [
        ({"kind": "explode"}, "faults[0].kind = 'explode': expected one of drop, delay"),
        ({"kind": "drop", "frame": "drive.TPDO9"}, "faults[0].frame = 'drive.TPDO9': expected one of SYNC"),
        ({"kind": "drop"}, "name the frames with frame ="),
        (
            {"kind": "drop", "frame": "SYNC", "at_period": 500},
            "faults[0].at_period = 500: expected an integer in 0 .. 199",
        ),
        ({"kind": "drop", "frame": "SYNC", "probability": 1.5}, "probability = 1.5: expected a number in (0, 1]"),
        ({"kind": "drop", "frame": "SYNC", "bit": 3}, "key 'bit' does not apply to kind 'drop'"),
        ({"kind": "delay", "frame": "SYNC"}, "a delay needs exactly one of delay_periods"),
        (
            {"kind": "delay", "frame": "SYNC", "delay_us": 300},
            "delay_us: microseconds mean something only in real time",
        ),
        ({"kind": "corrupt", "frame": "SYNC", "bit": 64}, "faults[0].bit = 64: expected an integer in 0 .. 63"),
        ({"kind": "freeze", "node": "plant", "periods": 3}, "freeze node = 'plant'"),
        ({"kind": "kill", "node": "motor"}, "faults[0].node = 'motor': expected one of plant, drive"),
        ({"kind": "drop", "cob_id": 0x190}, "with cob_id, say who sends the frames"),
        ({"kind": "freeze", "node": "drive", "at_period": 195, "periods": 5}, "after the run's last period 199"),
        ({"kind": "freeze", "node": "drive", "at_period": 48, "periods": 5}, "covers the event at period 50"),
    ],
)
def test_a_bad_fault_is_named_before_anything_runs(fault: dict, message: str) -> None:
    raw = {
        "scenario": {"name": "bad", "periods": 200},
        "events": [{"at_period": 50, "references": {"iq_ref_A": 1.0}}],
        "faults": [fault],
    }
    with pytest.raises(ScenarioError) as exc:
        parse(raw, "bad.toml")
    assert message in str(exc.value), str(exc.value)


def test_more_faults_than_the_injector_holds_are_refused() -> None:
    raw = {"scenario": {"name": "bad", "periods": 200}, "faults": [{"kind": "drop", "frame": "SYNC"}] * 33}
    with pytest.raises(ScenarioError, match="33 \\[\\[faults\\]\\] entries; the injector holds at most 32"):
        parse(raw, "bad.toml")


def test_the_same_faults_give_the_same_run() -> None:
    """A seeded probability hits the same frames in two runs, and the traces are equal bit for bit."""
    raw = with_command_timeout(base("fc-random", periods=3000))
    raw = with_fault(raw, ["frames_lost"], {"kind": "drop", "frame": "drive.TPDO1", "probability": 0.01, "seed": 5})
    sc = parse(raw, "<random>")
    a = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    b = run_scenario(parse(raw, "<random>"), RunOptions(bus="direct"), keep_trace=True)
    fa, fb = a.summary["faults"]["injected"][0], b.summary["faults"]["injected"][0]
    assert fa["action_periods"] == fb["action_periods"] and 10 <= fa["actions"] <= 50, fa
    assert a.trace is not None and b.trace is not None
    for col in a.trace:
        assert np.array_equal(a.trace[col], b.trace[col], equal_nan=True), col
    # every dropped command is one held period of the plant, at the next period
    held = [r["period"] for r in a.summary["faults"]["reactions"] if r["what"] == "command held"]
    assert held == [p + 1 for p in fa["action_periods"]][: len(held)]


def test_bench_run_reports_the_faults_and_shows_them_in_rerun(tmp_path: Path) -> None:
    out = tmp_path / "run"
    res = bench_cli("run", SCEN, "--bus", "direct", "--out", out, "--no-viewer", expect=0)  # frames_lost: expected
    assert "fault 0: drop drive.TPDO1 at period 21: 1 action(s)" in res.stdout, res.stdout
    s = json.loads((out / "summary.json").read_text())
    f = s["faults"]["injected"][0]
    assert f["first_period"] == 21 and f["held_periods"] == 1 and f["first_reaction"]["what"] == "command held"
    assert f["reaction_periods"] == 1 and s["status"] == "frames_lost" and s["status_expected"]
    texts = []
    reader = RrdReader(out / "run.rrd")
    for chunk in reader.stream(store=reader.recordings()[0]):
        if chunk.entity_path.startswith("/events"):
            b = chunk.to_record_batch()
            col = [c for c in b.schema.names if c.endswith(":text")][0]
            texts += [str(t) for t in b.column(col).flatten().to_pylist()]
    assert any("fault 0: drop drive.TPDO1" in t for t in texts), texts
    assert any("plant: command held" in t for t in texts), texts


def test_bench_faults_cli(tmp_path: Path) -> None:
    res = bench_cli("faults", "--only", "drop-command,kill-drive", "--out", tmp_path, expect=0)
    assert "2 of 2 fault checks pass on bus direct" in res.stdout
    data = json.loads((tmp_path / "faults.json").read_text())
    assert [c["check_id"] for c in data["checks"]] == ["drop-command", "kill-drive"]
    bad = bench_cli("faults", "--only", "drop-everything", timeout=60, expect=2)
    assert "unknown check 'drop-everything'" in bad.stderr


def test_the_fault_scenario_file_loads() -> None:
    sc = load(SCEN)
    assert [f.kind for f in sc.faults] == ["drop"] and sc.faults[0].at_period == 21


def test_a_fault_reset_event_enables_the_drive_again() -> None:
    """CiA 402: a scenario's fault reset (controller.clear = 1) takes the drive from FAULT to SWITCH ON
    DISABLED; the bench enables it again, so the control goes on as before the fault (without that, the
    drive would command 0 V for the rest of the run and iq would decay)."""
    from bench.claims import run_raw

    raw = with_command_timeout(base("cia402-clear", periods=160))
    raw["events"].append({"at_period": 60, "controller": {"clear": 1}})
    hit = run_raw(
        with_fault(raw, ["frames_lost"], {"kind": "drop", "frame": "plant.TPDO2", "at_period": 30, "periods": 6}),
        "direct",
    )
    assert [e for e in hit.result.summary["emcy"] if e["code"] == "0xFF03"]  # the fault happened
    p, iq = hit.tr["period"], hit.tr["iq_A"]
    assert (np.diff(iq[(p >= 40) & (p < 60)]) < 0).all()  # 0 V in FAULT: the current decays (L/R = 58 Ts)
    assert abs(iq[p >= 100] - 1.0).max() < 0.05, iq[p >= 100]  # back on the 1 A reference after the reset


def test_a_second_command_is_late_only_where_the_plant_held() -> None:
    """Lockstep with a command timeout: a command after its SYNC is the drive's own late frame only in a
    period whose sample says the period before went without its command; a doubled command elsewhere is
    still interference (the plant may have acted on it)."""
    from bench.claims import run_raw

    raw = with_command_timeout(base("fc-dup-command"))
    hit = run_raw(
        with_fault(raw, ["interference"], {"kind": "duplicate", "frame": "drive.TPDO1", "at_period": 30}), "direct"
    )
    itf = hit.result.summary["bus_stats"]["interference"]
    assert hit.result.status == "interference" and itf["frames"] == 1 and itf["first_period"] == 30, itf
