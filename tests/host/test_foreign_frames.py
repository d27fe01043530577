"""Foreign frames in a run's stream never crash the decoder, never make periods, and never turn a
run into a success it was not: a real run's frames (direct mode) with frames spliced in, decoded
through the same pipeline as `bench replay`. The same frames on vcan: tests/can/test_liveness.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.run import RunOptions, run_scenario
from bench.run.bus.frames import FRAME_DTYPE
from bench.run.pipeline import Pipeline, RunResult
from bench.run.sinks import FrameCollector, TraceCollector
from bench.scenario import load

REPO = Path(__file__).resolve().parents[2]
PLANT, DRIVE = 0x10, 0x20


@pytest.fixture(scope="module")
def clean() -> tuple[RunResult, np.ndarray]:
    fc = FrameCollector()
    res = run_scenario(
        load(REPO / "scenarios/you2019_step.toml"), RunOptions(bus="direct"), frame_sinks=[fc], keep_trace=True
    )
    fc.close()
    assert res.status == "ok"
    return res, fc.frames


def _decode(frames: np.ndarray, chunk: int = 337) -> RunResult:
    tc = TraceCollector()
    pipe = Pipeline(PLANT, DRIVE, [tc])
    for i in range(0, len(frames), chunk):  # chunk edges fall anywhere, also between a SYNC and its PDOs
        pipe.feed(frames[i : i + chunk])
    res = pipe.finish("spliced", "test")
    res.trace = tc.trace
    return res


def _random(rng: np.random.Generator, n: int, cob: np.ndarray | int | None = None) -> np.ndarray:
    f = np.zeros(n, dtype=FRAME_DTYPE)
    f["cob_id"] = rng.integers(0, 0x800, n) if cob is None else cob
    f["dlc"] = rng.integers(0, 9, n)
    f["data"] = rng.integers(0, 256, (n, 8))
    f["sender"] = 255
    return f


def _splice(frames: np.ndarray, extra: np.ndarray, lo: int, hi: int, rng: np.random.Generator) -> np.ndarray:
    at = np.sort(rng.integers(lo, hi, len(extra)))
    return np.insert(frames, at, extra)


def _loop_span(frames: np.ndarray) -> tuple[int, int]:
    """Positions of the loop's first SYNC and of the frame after its last command (the loop's end)."""
    sync = np.flatnonzero(frames["cob_id"] == 0x080)
    cmd = np.flatnonzero(frames["cob_id"] == 0x210)
    return int(sync[0]), int(cmd[cmd > sync[-1]][0]) + 1


def _same_traces(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_unrelated_identifiers_are_counted_and_harmless(clean: tuple[RunResult, np.ndarray]) -> None:
    ref, frames = clean
    rng = np.random.default_rng(1)
    used = (
        {0x000, 0x080}
        | {b + n for b in (0x080, 0x180, 0x280, 0x380, 0x480, 0x580, 0x600, 0x700) for n in (PLANT, DRIVE)}
        | {0x210}
    )
    ids = np.array([i for i in range(0x800) if i not in used])
    extra = _random(rng, 3000, rng.choice(ids, 3000))
    lo, hi = _loop_span(frames)
    res = _decode(_splice(frames, extra, lo, len(frames), rng))
    assert res.status == "ok"
    assert res.summary["periods"] == ref.summary["periods"]
    assert res.summary["bus_stats"]["foreign_frames"]["frames"] == 3000
    _same_traces(res.trace, ref.trace)


def test_fake_syncs_in_the_loop_make_no_period_and_are_interference(clean: tuple[RunResult, np.ndarray]) -> None:
    ref, frames = clean
    rng = np.random.default_rng(2)
    extra = _random(rng, 500, 0x080)
    extra["dlc"] = rng.integers(0, 2, 500)  # what the nodes would take for a SYNC: length 0, or 1 with a counter
    lo, hi = _loop_span(frames)
    res = _decode(_splice(frames, extra, lo + 1, hi - 1, rng))
    assert res.summary["periods"] == ref.summary["periods"]
    assert res.status == "interference" and res.exit_code == 9
    assert res.summary["bus_stats"]["interference"]["by_cob_id"]["0x080"] == 500
    assert res.summary["bus_stats"]["lost_frames"] == 0
    _same_traces(res.trace, ref.trace)  # a foreign SYNC never starts a period


def test_random_frames_in_the_loop_never_pass_as_a_clean_run(clean: tuple[RunResult, np.ndarray]) -> None:
    ref, frames = clean
    for seed in range(3):
        rng = np.random.default_rng(10 + seed)
        extra = _random(rng, 20_000)
        lo, hi = _loop_span(frames)
        res = _decode(_splice(frames, extra, lo + 1, hi - 1, rng))
        assert res.summary["periods"] == ref.summary["periods"]
        hits = res.summary["bus_stats"]["interference"]["frames"]
        # 20,000 random identifiers hit the loop's own ones: the run says so
        assert hits > 0 and res.status == "interference", (seed, res.status, hits)


def test_a_flood_after_the_loop_changes_nothing(clean: tuple[RunResult, np.ndarray]) -> None:
    ref, frames = clean
    rng = np.random.default_rng(3)
    extra = np.concatenate([_random(rng, 20_000), _random(rng, 2000, 0x080)])
    rng.shuffle(extra)
    lo, hi = _loop_span(frames)
    flooded = np.concatenate([frames[:hi], extra, frames[hi:]])  # right after the plant's final hold
    res = _decode(flooded)
    assert res.status == "ok", res.summary["bus_stats"]
    assert res.summary["periods"] == ref.summary["periods"]
    assert res.summary["bus_stats"]["lost_frames"] == 0
    assert res.summary["bus_stats"]["after_loop_frames"] > 0
    _same_traces(res.trace, ref.trace)


def test_a_short_frame_on_a_pdo_identifier_is_interference(clean: tuple[RunResult, np.ndarray]) -> None:
    ref, frames = clean
    rng = np.random.default_rng(4)
    lo, hi = _loop_span(frames)
    extra = _random(rng, 200, rng.choice([0x190, 0x290, 0x210], 200))  # the loop's PDOs (not the drive's trace:
    # those of period 0 come with SYNC 1 and belong to no period)
    extra["dlc"] = rng.integers(0, 3, 200)
    service = _random(rng, 200, rng.choice([0x490, 0x5A0, 0x590, 0x720], 200))  # hold, SDO, heartbeat
    service["dlc"] = rng.integers(0, 3, 200)
    _decode(_splice(frames, service, lo, len(frames), rng))  # no crash
    res = _decode(_splice(frames, extra, lo + 1, hi - 1, rng))
    # the nodes receive them too (and refuse them: EMCY 0x8210): interference, never a lost frame, and
    # never the value of a period (a short frame first in its period once hid the plant's own)
    bs = res.summary["bus_stats"]
    assert res.status == "interference" and bs["interference"]["frames"] == 200, bs
    assert bs["lost_frames"] == 0 and bs["sync_counter_gaps"] == 0, bs
    assert res.summary["periods"] == ref.summary["periods"]


def test_a_measurement_the_plant_did_not_send_is_interference(clean: tuple[RunResult, np.ndarray]) -> None:
    # A full-length frame on the measurement identifier with a random sample index: the drive acts on it,
    # so the run is interference -- not a lost SYNC (that is a second measurement of the next period only).
    ref, frames = clean
    rng = np.random.default_rng(8)
    lo, hi = _loop_span(frames)
    extra = _random(rng, 50, 0x290)
    extra["dlc"] = 8
    res = _decode(_splice(frames, extra, lo + 1, hi - 1, rng))
    bs = res.summary["bus_stats"]
    assert res.status == "interference", bs
    assert bs["interference"]["by_cob_id"]["0x290"] == 50


def test_a_foreign_sync_while_the_master_configures_changes_nothing(clean: tuple[RunResult, np.ndarray]) -> None:
    ref, frames = clean
    rng = np.random.default_rng(5)
    lo, _ = _loop_span(frames)
    extra = _random(rng, 20, 0x080)
    extra["dlc"] = 1
    res = _decode(_splice(frames, extra, 5, lo - 50, rng))  # among the SDO configuration, before NMT start
    assert res.status == "ok" and res.summary["periods"] == ref.summary["periods"]
    assert res.signals == ref.signals  # the layout was read once the configuration was complete
    _same_traces(res.trace, ref.trace)


@pytest.mark.parametrize("dlc", [0, 1])
def test_foreign_syncs_before_the_master_starts_change_nothing(clean: tuple[RunResult, np.ndarray], dlc: int) -> None:
    # A bus that was never quiet: fake SYNCs (and other frames) recorded before the master's first frame,
    # with no NMT command yet to tell configuration from loop. None may start the loop.
    ref, frames = clean
    rng = np.random.default_rng(6 + dlc)
    syncs = _random(rng, 200, 0x080)
    syncs["dlc"] = dlc
    syncs["data"][:50, 0] = 1  # the counter the plant's first SYNC carries, too
    extra = np.concatenate([syncs, _random(rng, 400)])
    rng.shuffle(extra)
    res = _decode(np.concatenate([extra, frames]))
    assert res.status == "ok", res.summary["bus_stats"]
    assert res.summary["periods"] == ref.summary["periods"]
    assert res.signals == ref.signals  # the layout was read once the configuration was complete
    assert res.summary["bus_stats"]["lost_frames"] == 0
    _same_traces(res.trace, ref.trace)


def test_a_log_cut_short_is_not_a_clean_run(clean: tuple[RunResult, np.ndarray]) -> None:
    _, frames = clean
    lo, hi = _loop_span(frames)
    res = _decode(frames[: lo + (hi - lo) * 3 // 4])
    assert res.status == "frames_lost" and res.summary["bus_stats"]["planned_periods"] == 200


@pytest.mark.parametrize("what", ["measurement", "sync"])
def test_a_lost_plant_frame_is_a_lost_frame_not_interference(clean: tuple[RunResult, np.ndarray], what: str) -> None:
    _, frames = clean
    lo, hi = _loop_span(frames)
    cob = 0x290 if what == "measurement" else 0x080
    pos = np.flatnonzero(frames["cob_id"] == cob)
    pos = pos[(pos > lo) & (pos < hi)]
    res = _decode(np.delete(frames, pos[len(pos) // 2]))
    assert res.status == "frames_lost", (res.status, res.summary["bus_stats"])
    assert res.summary["bus_stats"]["interference"]["frames"] == 0


def _as_realtime(frames: np.ndarray) -> np.ndarray:
    """The same frames as if the master had written Run control.mode = 1 (real time) to the plant."""
    from bench import eds

    var = eds.load("plant")["Run control"]["mode"]
    f = frames.copy()
    req = np.flatnonzero(
        (f["cob_id"] == 0x600 + PLANT)
        & (f["data"][:, 1] == var.index & 0xFF)
        & (f["data"][:, 2] == var.index >> 8)
        & (f["data"][:, 3] == var.subindex)
    )
    assert len(req) == 1
    f["data"][req[0], 4] = 1
    return f


def test_a_drive_late_for_its_sync_in_real_time_is_late_not_interference(
    clean: tuple[RunResult, np.ndarray],
) -> None:
    # Real time in a slow VM: the drive answers SYNC k after SYNC k+1 and the plant's measurements of k+1.
    # Its synchronous TPDOs then share a period with the next ones; they are the earlier row's, not foreign.
    res0, frames = clean
    f = _as_realtime(frames)
    lo, hi = _loop_span(f)
    sync = np.flatnonzero(f["cob_id"] == 0x080)
    sync = sync[(sync >= lo) & (sync < hi)]
    k = len(sync) // 2
    span = np.arange(sync[k], sync[k + 1])
    drive = span[f["sender"][span] == 1]
    assert len(drive) == 3  # two synchronous trace TPDOs and the command
    after = sync[k + 1] + 3  # after SYNC k+1 and the plant's two measurements
    assert set(f["sender"][sync[k + 1] : after]) == {0}
    order = np.r_[np.arange(0, drive[0]), np.arange(drive[-1] + 1, after), drive, np.arange(after, len(f))]
    res = _decode(f[order])
    bs = res.summary["bus_stats"]
    assert bs["interference"]["frames"] == 0, bs["interference"]
    assert res.status == "frames_lost"  # the command came after the next SYNC: late, missing in its period
    assert bs["lost_frames"] == 1, bs
    tr0, tr = res0.trace, res.trace
    assert tr0 is not None and tr is not None
    late = np.zeros(len(tr["period"]), dtype=bool)
    late[k] = True
    for name in tr0:
        if np.isnan(tr[name][late]).all() and not np.isnan(tr0[name][late]).all():
            np.testing.assert_array_equal(tr[name][~late], tr0[name][~late], err_msg=name)  # the command
        else:
            np.testing.assert_array_equal(tr[name], tr0[name], err_msg=name)  # trace TPDOs in their own rows


def test_a_drive_two_syncs_behind_in_real_time_answers_three_at_once_not_interference(
    clean: tuple[RunResult, np.ndarray],
) -> None:
    # Real time on a busy machine: the drive missed SYNCs k and k+1 (it was not scheduled) and answers k, k+1
    # and k+2 together after SYNC k+2. Its trace TPDOs of the three go to their three rows (they were free);
    # the two commands that came too late are missing in their periods (frames_lost), not interference.
    res0, frames = clean
    f = _as_realtime(frames)
    lo, hi = _loop_span(f)
    sync = np.flatnonzero(f["cob_id"] == 0x080)
    sync = sync[(sync >= lo) & (sync < hi)]
    k = len(sync) // 2
    late = [np.arange(sync[j], sync[j + 1]) for j in (k, k + 1)]
    late = [span[f["sender"][span] == 1] for span in late]
    assert all(len(d) == 3 for d in late)
    after = sync[k + 2] + 3  # after SYNC k+2 and the plant's two measurements
    moved = np.r_[late[0], late[1]]
    keep = np.setdiff1d(np.arange(0, after), moved)
    order = np.r_[keep, moved, np.arange(after, len(f))]
    res = _decode(f[order])
    bs = res.summary["bus_stats"]
    assert bs["interference"]["frames"] == 0, bs["interference"]
    assert bs["lost_frames"] == 2, bs
    tr0, tr = res0.trace, res.trace
    assert tr0 is not None and tr is not None
    rows = np.zeros(len(tr["period"]), dtype=bool)
    rows[[k, k + 1]] = True
    for name in tr0:
        if np.isnan(tr[name][rows]).all() and not np.isnan(tr0[name][rows]).all():
            np.testing.assert_array_equal(tr[name][~rows], tr0[name][~rows], err_msg=name)  # the commands
        else:
            np.testing.assert_array_equal(tr[name], tr0[name], err_msg=name)  # trace TPDOs in their own rows


def test_a_trace_tpdo_reordered_after_the_next_sync_is_late_not_interference(
    clean: tuple[RunResult, np.ndarray],
) -> None:
    # Lockstep through a transport that reorders (SLCAN in a kernel on two CPUs; a controller sending by
    # priority): the drive's trace TPDO of SYNC k arrives after its command and after SYNC k+1. Its row is
    # free: it is that row's, the trace is unchanged, the run clean. A second frame where the row before
    # has its own stays interference.
    res0, frames = clean
    lo, hi = _loop_span(frames)
    sync = np.flatnonzero(frames["cob_id"] == 0x080)
    sync = sync[(sync >= lo) & (sync < hi)]
    k = len(sync) // 2
    span = np.arange(sync[k], sync[k + 1])
    tpdo = span[frames["cob_id"][span] == 0x4A0]
    assert len(tpdo) == 1
    order = np.r_[
        np.arange(0, tpdo[0]), np.arange(tpdo[0] + 1, sync[k + 1] + 1), tpdo, np.arange(sync[k + 1] + 1, len(frames))
    ]
    res = _decode(frames[order])
    assert res.status == "ok", res.summary["bus_stats"]
    assert res.summary["bus_stats"]["interference"]["frames"] == 0
    assert res0.trace is not None and res.trace is not None
    _same_traces(res.trace, res0.trace)
    extra = np.insert(frames, sync[k + 1] + 1, frames[tpdo])  # a copy after SYNC k+1: row k has its own
    assert _decode(extra).summary["bus_stats"]["interference"]["by_cob_id"] == {"0x4A0": 1}


# ---------------------------------------------------------------------------------------- the teardown


def _emcy(code: int, node: int, t_us: int) -> np.ndarray:
    f = np.zeros(1, dtype=FRAME_DTYPE)
    f["cob_id"], f["dlc"], f["t_us"], f["sender"] = 0x080 + node, 8, t_us, 255
    f["data"][0, :3] = [code & 0xFF, code >> 8, 0x11]
    return f


def _teardown_at(frames: np.ndarray) -> int:
    """The master's NMT Stop that ends the run (CiA 301 command 0x02), to the plant first."""
    nmt = np.flatnonzero((frames["cob_id"] == 0) & (frames["dlc"] == 2) & (frames["data"][:, 0] == 0x02))
    assert len(nmt) == 2, "a run ends with NMT Stop to each of its two nodes"
    assert frames["data"][nmt[0], 1] == PLANT and frames["data"][nmt[1], 1] == DRIVE
    return int(nmt[0])


def test_an_alarm_of_the_teardown_is_not_the_runs(clean: tuple[RunResult, np.ndarray]) -> None:
    """The race of issue 52: the plant's process stopped first, the drive outlives its heartbeat-consumer time
    and sends EMCY 0x8130 (then its safe state's 0xFF04). After the teardown's NMT Stop it is listed apart, with how
    long after the stop it came, and changes neither the run's EMCYs nor its status nor its traces."""
    ref, frames = clean
    at = _teardown_at(frames)
    t = int(frames["t_us"][-1])
    late = np.concatenate([_emcy(0x8130, DRIVE, t + 1_000_000), _emcy(0xFF04, DRIVE, t + 1_000_100)])
    res = _decode(np.concatenate([frames, late]))
    assert res.status == "ok" and res.summary["emcy"] == []
    td = res.summary["teardown"]
    assert [(e["node"], e["code"], e["period"]) for e in td["emcy"]] == [
        ("drive", "0x8130", None),
        ("drive", "0xFF04", None),
    ]
    assert td["emcy"][0]["after_stop_s"] == pytest.approx((t + 1_000_000 - int(frames["t_us"][at])) / 1e6)
    assert td["frames"] == len(frames) - at + 2
    _same_traces(res.trace, ref.trace)


def test_an_alarm_in_the_run_is_still_the_runs(clean: tuple[RunResult, np.ndarray]) -> None:
    """The same EMCY before the teardown (mid-run, and between the loop's end and the NMT Stop) is the run's,
    with its period: the teardown's cut takes nothing from the run."""
    ref, frames = clean
    lo, hi = _loop_span(frames)
    at = _teardown_at(frames)
    mid = lo + (hi - lo) // 2
    spliced = np.insert(frames, [mid, at], np.concatenate([_emcy(0x8130, DRIVE, 0), _emcy(0x8130, PLANT, 0)]))
    res = _decode(spliced)
    got = [(e["node"], e["code"]) for e in res.summary["emcy"]]
    assert got == [("drive", "0x8130"), ("plant", "0x8130")]
    assert 0 < res.summary["emcy"][0]["period"] < res.summary["emcy"][1]["period"] == ref.summary["periods"] - 1
    assert res.summary["teardown"]["emcy"] == []


def test_another_masters_stop_is_not_the_teardown(clean: tuple[RunResult, np.ndarray]) -> None:
    """NMT Stop to a node that is not the run's (another master on a shared bus) mid-run: a foreign frame of the
    bus, not the run's end; the run's own Stop still begins its teardown."""
    ref, frames = clean
    lo, hi = _loop_span(frames)
    stop = np.zeros(1, dtype=FRAME_DTYPE)
    stop["dlc"], stop["sender"] = 2, 255
    stop["data"][0, :2] = [0x02, 0x05]
    res = _decode(np.insert(frames, (lo + hi) // 2, stop))
    assert res.status == "ok" and res.summary["periods"] == ref.summary["periods"]
    assert res.summary["teardown"]["frames"] == len(frames) - _teardown_at(frames)
    _same_traces(res.trace, ref.trace)
