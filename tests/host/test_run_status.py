"""A run's verdict tells the truth: a diverging loop, a trip, non-finite values and lost frames
each give their own status and exit code; a scenario that expects one passes with it; a NaN
that arrived is never counted as a lost frame."""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.pipeline import Pipeline
from bench.run.sinks import FrameCollector
from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET, verdict
from bench.run.verdict.watch import swing_seen_from
from bench.scenario import ScenarioError, load, parse

STEP = REPO / "scenarios" / "you2019_step.toml"


def zhao(ratio: float, **head: Any) -> dict[str, Any]:
    """Zhao 2022 incremental deadbeat at L/L0 = ratio, 10 kHz, locked rotor, an iq step of 0.1 A."""
    return {
        "scenario": {"name": f"zhao-{ratio}", "periods": 1500, **head},
        "motor": {"preset": "zhao2022", "mech_mode": "locked"},
        "drive": {"t_dead_s": 0.0, "encoder_lines": 0, "adc_noise_std_A": 0.0, "adc_lsb_A": 0.0},
        "controller": {"controller": "incremental_zhao2022", "Vmax_V": 28.0 / 3**0.5, "L_hat_ratio": 1 / ratio},
        "events": [{"at_period": 20, "references": {"iq_ref_A": 0.1}}],
    }


def test_unstable_loop_is_diverged_and_a_stable_one_is_ok() -> None:
    bad = run_scenario(parse(zhao(0.68), "<zhao>"), RunOptions(bus="direct"))
    assert bad.status == "diverged" and bad.exit_code == EXIT_CODES["diverged"] == 4
    assert bad.summary["oscillating_steps"] == [20]
    assert bad.summary["steps"][0]["periods_to_settle"] is None
    good = run_scenario(parse(zhao(0.8), "<zhao>"), RunOptions(bus="direct"))
    assert good.status == "ok" and good.exit_code == 0, good.summary["steps"]


def test_expected_divergence_passes_and_an_unmet_expectation_fails() -> None:
    raw = zhao(0.68, expect=["diverged", "tripped"])
    res = run_scenario(parse(raw, "<zhao>"), RunOptions(bus="direct"))
    assert res.status == "diverged" and res.expected and res.exit_code == 0
    res = run_scenario(parse(zhao(0.8, expect="diverged"), "<zhao>"), RunOptions(bus="direct"))
    assert res.status == "ok" and not res.expected and res.exit_code == EXIT_EXPECTATION_NOT_MET


def test_trip_is_reported_with_its_period() -> None:
    sc = load(STEP, ["drive.I_trip_A=0.5"])  # a 1 A step through a 0.5 A trip
    res = run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)
    assert res.status == "tripped" and res.exit_code == 3
    p = res.summary["first_trip_period"]
    assert 20 < p < 30  # the step is at period 20
    assert res.trace is not None and int(res.trace["status"][p]) & 1 and not int(res.trace["status"][p - 1]) & 1


def test_bad_expect_is_refused() -> None:
    with pytest.raises(ScenarioError, match="scenario.expect = 'broken'"):
        load(STEP, ["scenario.expect=broken"])


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    fc = FrameCollector()
    run_scenario(load(STEP), RunOptions(bus="direct"), frame_sinks=[fc])
    fc.close()
    return fc.frames


def _pipe(frames: np.ndarray) -> Any:
    p = Pipeline(0x10, 0x20)
    for i in range(0, len(frames), 333):
        p.feed(frames[i : i + 333])
    return p.finish("t", "direct")


def test_nan_in_a_pdo_is_non_finite_not_lost(frames: np.ndarray) -> None:
    f = frames.copy()
    cmd = np.nonzero(f["cob_id"] == 0x210)[0]  # the drive's command TPDO, on the plant's RPDO1 COB-ID
    assert len(cmd) >= 200
    for i in cmd[100:103]:
        f["data"][i, :4] = np.frombuffer(struct.pack("<f", float("nan")), np.uint8)
    res = _pipe(f)
    bs = res.summary["bus_stats"]
    assert res.status == "non_finite" and res.exit_code == 5
    assert bs["non_finite_values"] == {"v_alpha_V": 3}
    assert bs["lost_frames"] == 0 and bs["missing_commands"] == 0


def test_missing_frames_are_lost(frames: np.ndarray) -> None:
    cmd = np.nonzero(frames["cob_id"] == 0x210)[0]
    meas = np.nonzero(frames["cob_id"] == 0x190)[0]
    keep = np.ones(len(frames), bool)
    keep[cmd[50]] = keep[meas[60]] = False
    res = _pipe(frames[keep])
    bs = res.summary["bus_stats"]
    assert res.status == "frames_lost" and res.exit_code == 6
    assert bs["missing_commands"] == 1 and bs["missing_measurements"] == 1  # TPDO1 (i_a, i_b) counts too
    assert bs["non_finite_values"] == {} and bs["lost_frames"] == 2
    ref = _pipe(frames)
    assert ref.status == "ok" and ref.summary["bus_stats"]["lost_frames"] == 0


def test_cli_exit_code_is_the_status(tmp_path: Path) -> None:
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--no-viewer", "--out", tmp_path / "r", "--set", "drive.I_trip_A=0.5", expect=3
    )
    assert "TRIPPED" in res.stdout and (tmp_path / "r" / "summary.json").exists()
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    # the console line names the first event and its period
    assert f"status: TRIPPED at period {s['first_trip_period']}: " in res.stdout, res.stdout
    assert s["status_first_period"]["tripped"] == s["first_trip_period"]


def test_runaway_without_voltage_limit_trips_by_default_and_diverges_without_trip() -> None:
    """Zhao 2022 at L/L0 = 0.68 with the voltage limiter off runs away: the plant's default trip
    (from the preset) stops it; with the trip level off the current passes the inverter's bound
    first, and the verdict names that, not what followed: the law's command overflowing, which the drive refuses
    (0 V, its safe state law_output, EMCY 0xFF06) instead of sending it."""
    raw = zhao(0.68)
    raw["scenario"]["periods"] = 3000
    raw["controller"]["Vmax_V"] = 0.0
    tripped = run_scenario(parse(raw, "<zhao>"), RunOptions(bus="direct"))
    assert tripped.status == "tripped" and tripped.summary["first_trip_period"] < 200
    assert tripped.summary["bus_stats"]["non_finite_values"] == {}
    raw["drive"]["I_trip_A"] = 0.0
    runaway = run_scenario(parse(raw, "<zhao>"), RunOptions(bus="direct"))
    s = runaway.summary
    assert runaway.status == "diverged" and runaway.exit_code == 4
    assert s["max_phase_current_A"] > s["divergence_bound_A"]
    # later events are still reported: the law's command overflowed, the drive refused it and entered its safe
    # state (EMCY 0xFF06): no non-finite value reached the bus
    assert not s["status_flags"]["non_finite"] and s["bus_stats"]["non_finite_values"] == {}
    assert any(e["code"] == "0xFF06" and e["node"] == "drive" for e in s["emcy"]), s["emcy"][:5]


def test_stopped_at_period_is_the_last_period_on_the_bus() -> None:
    """A plant killed mid-run: summary.json's stopped.at_period is the period the loop stopped at, the
    traces' last row, whatever period the master had last heard of. Over a bus a dead plant answers no
    SDO, and the master knew only the end of the lockstep segment before the last event (period 19 of the
    step scenario's event at 20) while the traces went on: the record says where the loop stopped."""
    p = 150
    sc = load(STEP, [f'faults=[{{kind="kill", node="plant", at_period={p}}}]', "scenario.expect=node_lost"])
    fc = FrameCollector()
    res = run_scenario(sc, RunOptions(bus="direct"), frame_sinks=[fc], keep_trace=True)
    fc.close()
    assert res.status == "node_lost" and res.expected and res.trace is not None
    last = int(res.trace["period"][-1])
    assert last == p and res.summary["stopped"]["at_period"] == last and res.summary["periods"] == last + 1
    stale = {**res.summary["stopped"], "at_period": 19}  # what the master of a run over vcan reported
    pipe = Pipeline(0x10, 0x20, expect=("node_lost",))
    for i in range(0, len(fc.frames), 4096):
        pipe.feed(fc.frames[i : i + 4096])
    again = pipe.finish("t", "vcan0", stopped=stale)
    assert again.status == "node_lost" and again.summary["periods"] == last + 1
    assert again.summary["stopped"]["at_period"] == last, again.summary["stopped"]


def test_a_trip_followed_by_swings_is_tripped() -> None:
    """Statuses name the first cause (issue 52): a flux-map run tripped at period 370 and then swung until its
    window ended; the swing is measured over the window's last fifth, after the trip, and is the trip's doing."""
    step = {"at_period": 20, "window_periods": 480, "periods_to_settle": None}
    assert swing_seen_from([step], 370) == 404  # 20 + 480 - 96: the measured fifth's first period
    flags = {"tripped": True, "diverged": True}
    assert verdict(flags, ("ok",), {"tripped": 370, "diverged": 404})[:2] == ("tripped", EXIT_CODES["tripped"])
    # no trip, or one inside the measured fifth (the swing was there before it): the oscillation from its step
    assert swing_seen_from([step], None) == 20 and swing_seen_from([step], 450) == 20
    assert verdict(flags, ("ok",), {"tripped": 450, "diverged": 20})[0] == "diverged"
    assert swing_seen_from([], None) is None  # no step swings
