"""A real-time run's timing (bench/run/verdict/realtime.py): the bus-side view computed from time stamps whose
lateness, turnaround and percentiles are known by construction (a grid with late SYNCs, known command delays,
two segments each anchored on its earliest SYNC), the same from frames through the pipeline and from their
candump log through `bench replay`'s path; the status realtime_overrun (priority, exit code, expectation, its
message); the overview's timing panel and the Rerun timing entities. Timings of this machine are never asserted:
every time stamp here is made up."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rrd_util import read_recording

from bench.eds import default_node_id, load
from bench.run import RunOptions, run_scenario
from bench.run.console import _realtime_overrun
from bench.run.pipeline import Pipeline, RunResult, replay_log
from bench.run.record.canlog import CandumpWriter
from bench.run.sinks import FrameCollector
from bench.run.verdict import realtime
from bench.run.verdict.summary import EXIT_CODES, PRIORITY, verdict
from bench.scenario import STATUSES
from bench.scenario import load as load_scenario
from bench.signals import SignalInfo
from bench.view.plots import overview_plot
from bench.view.rerun_sink import RerunSink

REPO = Path(__file__).resolve().parents[2]
T0_US = 1_700_000_000_000_007  # an epoch time stamp (candump's), 7 us off any grid: the anchor takes it out
TS_US = 100.0

# Two segments of ten periods: the second after a 5 ms hold, on a grid 37 us out of phase with the first.
# Lateness per period: SYNC 5 150 us late (more than a period), SYNC 6 52 us (catching up); in the second segment
# every SYNC 3 us late but SYNC 12, the segment's earliest, which anchors its grid.
LATE = [0, 0, 0, 0, 0, 150, 52, 0, 0, 0] + [3, 3, 0, 3, 3, 3, 3, 3, 3, 3]
SEGS = [(0, TS_US), (10, TS_US)]
DELAY = [10.0 + k % 5 for k in range(20)]  # command delay after its SYNC, us; period 7's command never comes
MISSING = 7


def grid(k: int, late: float, hold_us: float = 5000.0, phase_us: float = 37.0) -> float:
    return T0_US + k * TS_US + (hold_us + phase_us if k >= 10 else 0.0) + late


def test_bus_view_equals_the_construction() -> None:
    period = np.arange(20)
    sync = np.array([grid(k, LATE[k]) for k in period])
    cmd = sync + np.array(DELAY)
    cmd[MISSING] = np.nan
    pp = realtime.per_period(period, sync - sync[0], cmd - sync[0], SEGS)  # from a common origin, as BusTiming
    np.testing.assert_array_equal(pp.lateness, LATE)
    bus = realtime.bus_view(pp, SEGS)
    # 9 zeros, nine 3s, 52, 150: nearest rank (p50 the 10th of 20, p99 and p99.9 the 20th)
    assert bus["sync_lateness_us"] == {
        "min": 0.0,
        "mean": 11.45,
        "p50": 3.0,
        "p99": 150.0,
        "p99_9": 150.0,
        "max": 150.0,
    }
    # intervals within a segment only (18): 250 into SYNC 5, 2 and 48 after it, 97 and 103 around SYNC 12
    iv = pp.interval
    assert np.isnan(iv[0]) and np.isnan(iv[10])
    assert (iv[5], iv[6], iv[7], iv[12], iv[13]) == (250.0, 2.0, 48.0, 97.0, 103.0)
    assert bus["sync_interval_us"]["min"] == 2.0 and bus["sync_interval_us"]["max"] == 250.0
    # 19 commands: four each of 10, 11, 13, 14 us and three of 12 (period 7's is missing)
    assert bus["turnaround_us"] == {"min": 10.0, "mean": 12.0, "p50": 12.0, "p99": 14.0, "p99_9": 14.0, "max": 14.0}
    assert bus["commands_timed"] == 19 and bus["periods"] == 20
    assert (bus["overruns"], bus["sync_overruns"], bus["worst_period"]) == (1, 1, 5)
    assert bus["first_overrun_period"] == 5  # the late SYNC, before the missing command
    assert bus["segments"] == [{"from_period": 0, "period_us": TS_US}, {"from_period": 10, "period_us": TS_US}]


def test_one_segment_less_is_anchored_on_the_earliest_sync_of_both() -> None:
    period = np.arange(20)
    sync = np.array([grid(k, LATE[k]) for k in period]) - T0_US
    pp = realtime.per_period(period, sync, sync + 10.0, [(0, TS_US)])
    assert pp.lateness[0] == 0.0 and pp.lateness[12] == 5000.0 + 37.0  # the hold, as lateness: why segments
    assert realtime.per_period(period, sync, sync + 10.0, SEGS).lateness[12] == 0.0


def test_segments_and_the_plant_period_from_the_bus() -> None:
    assert realtime.period_us(np.float32(55e-6)) == 55.0  # the plant rounds its REAL32 Ts to whole ns
    assert realtime._segments([0, 20, 0], [(0, 100e-6), (20, 50e-6)], 55e-6) == [(0, 100.0), (20, 50.0)]
    assert realtime._segments([], [], 55e-6) == [(0, 55.0)]
    assert realtime.stats(np.array([np.nan])) == dict.fromkeys(realtime.STATS)


# ---------------------------------------------------------------------------------------------- frames
@pytest.fixture(scope="module")
def frames() -> tuple[np.ndarray, Any]:
    """A direct lockstep run's frames made a real-time run's: Run control.mode written 1, every frame re-stamped
    on the construction's grid (two segments: the scenario's event at period 20 makes a hold), and the layout."""
    fc = FrameCollector()
    res = run_scenario(load_scenario(REPO / "scenarios/you2019_step.toml"), RunOptions(bus="direct"), frame_sinks=[fc])
    fc.close()
    assert res.status == "ok" and "realtime" not in res.summary  # lockstep: no block, no flag
    assert "realtime_overrun" not in res.summary["status_flags"]
    pipe = Pipeline(None, None)
    pipe.feed(fc.frames)
    pipe.finish("lockstep", "test")
    layout = pipe.dec.layout
    assert layout is not None
    return _restamped(_as_realtime(fc.frames), layout), layout


def _as_realtime(f: np.ndarray) -> np.ndarray:
    var = load("plant")["Run control"]["mode"]
    d = f["data"]
    req = np.flatnonzero(
        (f["cob_id"] == 0x600 + default_node_id("plant"))
        & (d[:, 1] == var.index & 0xFF)
        & (d[:, 2] == var.index >> 8)
        & (d[:, 3] == var.subindex)
    )
    assert len(req) == 1
    f = f.copy()
    f["data"][req[0], 4] = 1
    return f


# The run's construction (its Ts 55 us; the scenario's event at period 20 is a hold): segment 2 on a grid 5037 us
# after segment 1's, every SYNC 3 us late but SYNC 33 (its anchor); SYNC 50 a whole period late and the next four
# catching up, each after the frames of the one before.
RUN_LATE = {50: 150.0, 51: 120.0, 52: 90.0, 53: 60.0, 54: 30.0}


def _run_sync(k: int) -> float:
    if k < 20:
        return T0_US + k * 55.0
    return T0_US + k * 55.0 + 5037.0 + RUN_LATE.get(k, 0.0 if k == 33 else 3.0)


def _command(layout: Any) -> int:
    return next(p.cob_id for p in layout.pdos if p.node == "drive" and p.signals[0][0].startswith("Voltage command."))


def _restamped(f: np.ndarray, layout: Any) -> np.ndarray:
    """Bus order kept, time stamps increasing: SYNC k at _run_sync(k), its command DELAY[k % 20] after it, every
    other frame 1 us after the one before; the configuration before the first SYNC, the end reads after."""
    sync = np.flatnonzero(f["cob_id"] == layout.sync_cob_id)
    cmd = _command(layout)
    t = np.zeros(len(f))
    t[: sync[0]] = _run_sync(0) - sync[0] + np.arange(sync[0])
    for k, (a, b) in enumerate(zip(sync, [*sync[1:], len(f)], strict=True)):
        now = _run_sync(k)
        for i in range(a, b):
            now = _run_sync(k) + DELAY[k % 20] if f["cob_id"][i] == cmd else (now + 1.0 if i > a else now)
            t[i] = now
    out = f.copy()
    out["t_us"] = t.astype(np.uint64)
    assert (np.diff(out["t_us"].astype(np.int64)) > 0).all()
    return out


def _plant_report(f: np.ndarray, values: dict[str, float]) -> np.ndarray:
    """The plant's timing record read by SDO after the loop (expedited uploads), as the master does: before its
    teardown."""
    rec = load("plant")["Realtime timing"]
    plant = default_node_id("plant")
    extra = np.zeros(2 * len(values), dtype=f.dtype)
    for j, (name, v) in enumerate(values.items()):
        var = rec[name]
        head = [var.index & 0xFF, var.index >> 8, var.subindex]
        payload = struct.pack("<f" if name.endswith("_us") else "<I", v)
        extra[2 * j]["cob_id"], extra[2 * j + 1]["cob_id"] = 0x600 + plant, 0x580 + plant
        extra[2 * j]["data"] = [0x40, *head, 0, 0, 0, 0]
        extra[2 * j + 1]["data"] = [0x43, *head, *payload]
    extra["dlc"] = 8
    # before the run's teardown (the master's NMT Stop: what follows it is not the run's), after the rest
    stop = np.flatnonzero((f["cob_id"] == 0) & (f["dlc"] == 2) & (f["data"][:, 0] == 0x02))
    at = int(stop[0]) if len(stop) else len(f)
    extra["t_us"] = int(f["t_us"][at - 1]) + np.arange(len(extra))
    return np.insert(f, at, extra)


def _decode(f: np.ndarray, expect: tuple[str, ...] = ("ok",), chunk: int = 337) -> RunResult:
    pipe = Pipeline(None, None, expect=expect)
    for i in range(0, len(f), chunk):  # chunk edges anywhere, also between a SYNC and its frames
        pipe.feed(f[i : i + chunk])
    return pipe.finish("restamped", "test")


def test_bus_view_from_frames_and_from_their_log(frames: tuple[np.ndarray, Any], tmp_path: Path) -> None:
    f, layout = frames
    res = _decode(f)
    rt = res.summary["realtime"]
    bus = rt["bus"]
    assert bus is not None, "the decoder gave no per-period time stamps (rows.py: sync_t_us / command_t_us)"
    assert rt["period_us"] == 55.0 and res.summary["periods"] == 200 == bus["periods"]
    assert bus["segments"] == [{"from_period": 0, "period_us": 55.0}, {"from_period": 20, "period_us": 55.0}]
    # 21 zeros (segment 1, SYNC 33), 174 threes, 30 .. 150 (SYNCs 54 .. 50): p50 the 100th, p99 the 198th (90)
    lat = bus["sync_lateness_us"]
    assert lat == {"min": 0.0, "mean": 4.86, "p50": 3.0, "p99": 90.0, "p99_9": 150.0, "max": 150.0}
    assert (bus["worst_period"], bus["sync_overruns"], bus["first_overrun_period"]) == (50, 4, 50)
    assert bus["sync_interval_us"]["max"] == 55.0 + 150.0 - 3.0 and bus["sync_interval_us"]["min"] == 55.0 - 30.0
    assert bus["turnaround_us"] == {"min": 10.0, "mean": 12.0, "p50": 12.0, "p99": 14.0, "p99_9": 14.0, "max": 14.0}
    assert bus["commands_timed"] == 200 and bus["overruns"] == 0
    assert res.status == "ok"  # the plant counted no overrun (its record: the EDS defaults, 0)
    log = tmp_path / "bus.log"
    w = CandumpWriter(log, "vcan0", t0_us=0)
    w.write(f)
    w.close()
    assert replay_log(log).summary["realtime"] == rt  # bench replay: the same figures


def test_overruns_are_the_status_before_the_lost_command(frames: tuple[np.ndarray, Any]) -> None:
    f, layout = frames
    cmd = np.flatnonzero(f["cob_id"] == _command(layout))
    f = _plant_report(np.delete(f, cmd[60]), {"overruns": 3, "sync_overruns": 1, "worst_period": 50})
    f = _plant_report(f, {"periods": 200, "sync_lateness_max_us": 412.25})
    res = _decode(f)
    s = res.summary
    assert s["status_flags"]["frames_lost"] and s["status_flags"]["realtime_overrun"]
    assert (res.status, res.exit_code, res.expected) == ("realtime_overrun", EXIT_CODES["realtime_overrun"], False)
    plant = s["realtime"]["plant"]
    assert (plant["overruns"], plant["sync_overruns"], plant["worst_period"]) == (3, 1, 50)
    assert plant["sync_lateness_max_us"] == 412.25 and "reset" not in plant
    assert {"missed_commands", "late_commands", "turnaround_p99_9_us", "commands_timed"} <= plant.keys()
    expected = _decode(f, expect=("ok", "realtime_overrun"))
    assert (expected.status, expected.exit_code, expected.expected) == ("realtime_overrun", 0, True)
    assert _decode(f, expect=("frames_lost",)).exit_code == EXIT_CODES["realtime_overrun"]


# ---------------------------------------------------------------------------------------------- the status
def test_realtime_overrun_is_a_status_with_its_own_exit_code() -> None:
    assert "realtime_overrun" in STATUSES and set(EXIT_CODES) == set(STATUSES)
    assert EXIT_CODES["realtime_overrun"] == 11 and len(set(EXIT_CODES.values())) == len(EXIT_CODES)
    assert PRIORITY.index("realtime_overrun") == PRIORITY.index("frames_lost") - 1


@pytest.mark.parametrize(
    ("first", "expect", "result"),
    [
        ({"realtime_overrun": 42, "frames_lost": 42}, ("ok",), ("realtime_overrun", 11, False)),
        ({"realtime_overrun": 42, "frames_lost": 42}, ("realtime_overrun",), ("realtime_overrun", 0, True)),
        ({"realtime_overrun": 42, "frames_lost": 41}, ("realtime_overrun",), ("frames_lost", 6, False)),
        ({"realtime_overrun": None, "frames_lost": None}, ("ok",), ("realtime_overrun", 11, False)),
    ],
)
def test_priority_and_expectation(first: dict[str, int | None], expect: tuple[str, ...], result: tuple) -> None:
    assert verdict({"realtime_overrun": True, "frames_lost": True}, expect, first) == result


def test_overrun_flag_and_message() -> None:
    rt = {"period_us": 5.0, "plant": {"periods": 1000, "overruns": 37, "sync_overruns": 0}, "bus": None}
    assert realtime.overran(rt) and not realtime.overran({"plant": {"overruns": 0, "sync_overruns": 0}})
    assert realtime.overran({"plant": {"overruns": 0, "sync_overruns": 2}}) and not realtime.overran(None)
    assert realtime.first_overrun(rt, 9) == 9  # no time stamps: the first lost frame
    rt["plant"] |= {"sync_lateness_max_us": 412.3, "worst_period": 18, "missed_commands": 12}
    assert _realtime_overrun({"realtime": rt}) == (
        "37 overruns in 1000 periods at Ts = 5.0 us: the command was not at the plant by its deadline (12 missed "
        "their SYNC); worst SYNC lateness 412.3 us at period 18"
    )
    rt["plant"] |= {"overruns": 0, "sync_overruns": 2}
    assert _realtime_overrun({"realtime": rt}).startswith("2 SYNCs more than one period late in 1000 periods")


# ---------------------------------------------------------------------------------------------- the views
def _pp() -> realtime.PerPeriod:
    period = np.arange(20)
    sync = np.array([grid(k, LATE[k]) for k in period]) - T0_US
    return realtime.per_period(period, sync, sync + np.array(DELAY), SEGS)


def test_overview_has_a_timing_panel_in_real_time_only(tmp_path: Path) -> None:
    env = realtime.envelopes(_pp(), {"sync_lateness_p99_us": 12.5, "sync_lateness_max_us": 412.3})
    iq = (np.arange(20.0), np.zeros(20), np.ones(20))
    rt_svg = overview_plot(tmp_path, {"iq_A": iq, **env}, "rt", TS_US * 1e-6, name="rt.svg")
    lock_svg = overview_plot(tmp_path, {"iq_A": iq}, "lockstep", TS_US * 1e-6, name="lock.svg")
    assert rt_svg is not None and lock_svg is not None
    text = rt_svg.read_text()
    assert "real-time timing" in text and "SYNC lateness p99 12.5 µs, max 412.3 µs" in text and "Ts = 100 µs" in text
    assert "real-time timing" not in lock_svg.read_text()


def test_rerun_has_the_timing_per_period(tmp_path: Path) -> None:
    period = np.arange(20)
    sync = np.array([grid(k, LATE[k]) for k in period])
    chunk = {"period": period, "t_s": period * 1e-4, "iq_A": np.zeros(20), "sync_t_us": sync}
    chunk["command_t_us"] = sync + np.array(DELAY)
    sink = RerunSink("rt", tmp_path / "run.rrd")
    sink.begin([SignalInfo.of("iq_A", "test")])
    sink.write({k: v[:13] for k, v in chunk.items()})  # two chunks: the anchor of segment 2 is in the second
    sink.write({k: v[13:] for k, v in chunk.items()})
    segs = [{"from_period": s, "period_us": t} for s, t in SEGS]
    sink.end({"Ts_s": 1e-4, "realtime": {"bus": {"segments": segs}}})
    rec = read_recording(tmp_path / "run.rrd")
    np.testing.assert_array_equal(rec["/timing/sync_lateness_us"]["value"], LATE)
    np.testing.assert_array_equal(rec["/timing/turnaround_us"]["value"], DELAY)
    np.testing.assert_array_equal(rec["/timing/sync_lateness_us"]["period"], period)


def test_a_sync_more_than_100_periods_late_starts_a_new_grid() -> None:
    # the plant re-grids after a SYNC over 100 periods late (plant_pacing.c): the SYNCs after it are on time on
    # the new grid, not all 50 ms late
    ts = 100.0
    t = np.arange(12) * ts
    t[2] += 30.0
    t[5:] += 50_000.0
    pp = realtime.per_period(np.arange(12), t, t + 5.0, [(0, ts)])
    assert pp.lateness.tolist() == [0.0, 0.0, 30.0, 0.0, 0.0, 50_000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    assert pp.sync_late.tolist() == [False] * 5 + [True] + [False] * 6
    # a stall under 100 periods: the plant catches up on its grid, the SYNCs after it are late on it
    t2 = np.arange(12) * ts
    t2[5:] += np.maximum(0.0, 5_000.0 - (np.arange(7) * ts))
    pp2 = realtime.per_period(np.arange(12), t2, t2 + 5.0, [(0, ts)])
    assert pp2.lateness[5] == 5_000.0 and pp2.lateness[6] == 4_900.0


def test_an_overrun_is_charged_to_the_larger_share_of_its_period() -> None:
    from bench.run.verdict.realtime import causes, per_period

    # Ts 100 us, periods 0..5: in time; SYNC 70 us late, its command 40 us after it (plant_late); SYNC on time, no
    # command (drive_missing); SYNC 10 us late, its command 95 us after it (drive_late); SYNC 60 us late, no
    # command (plant_late: more than half the period gone before the drive heard it); in time
    sync = np.array([0.0, 170.0, 200.0, 310.0, 460.0, 500.0])
    cmd = np.array([5.0, 210.0, np.nan, 405.0, np.nan, 505.0])
    pp = per_period(np.arange(6), sync, cmd, [(0, 100.0)])
    got = causes(pp)
    assert got == {"plant_late": 2, "drive_late": 1, "drive_missing": 1, "bus_late": 0}, (got, pp.lateness)
