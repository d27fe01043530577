"""Issue 54's frame sets ([frames], bench/scenario/frames.py), run the way users run them (bench.api.run, in process):

- the compact measurement frame with the ADC model quantizing and an encoder is today's run bit for bit in every
  column both have (currents, angle, commands, the Park transforms, the law's trace), over the three papers'
  scenarios, with one measurement frame a period instead of two;
- without the sensor models the decoded currents sit on the code's grid, and the drive still numbers its samples:
  a dropped measurement frame is one the drive counts as lost (from the SYNC counter the frame carries);
- bad [frames] values are refused naming the key and the allowed values.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import can
import numpy as np
import pytest
from bench_cli import bench_cli
from papers import PAPERS, SENSORS

from bench.api import RunRefused, ScenarioError, run
from bench.paths import REPO
from bench.run.bus.frames import FRAME_DTYPE
from bench.run.decode.decoder import Decoder
from bench.scenario import load
from bench.signals import column_name

COMPACT = ["frames.measurement=compact"]


@pytest.mark.parametrize("scenario", PAPERS, ids=[s.split("/")[-1][:-5] for s in PAPERS])
def test_compact_frame_is_todays_run_bit_for_bit_with_the_sensor_models(scenario: str, tmp_path: Path) -> None:
    default = run(scenario, SENSORS, out=tmp_path / "default")
    compact = run(scenario, SENSORS + COMPACT, out=tmp_path / "compact")
    assert default.status == compact.status and compact.status_expected, (default.status, compact.status)
    a, c = np.load(tmp_path / "default" / "traces.npy"), np.load(tmp_path / "compact" / "traces.npy")
    assert len(a) == len(c) == default.summary["periods"]
    common = [n for n in a.dtype.names if n in c.dtype.names]
    for name in ("i_a_A", "i_b_A", "theta_m_rad", "v_alpha_V", "v_beta_V", "id_A", "iq_A"):
        assert name in common, name
    differ = [n for n in common if a[n].tobytes() != c[n].tobytes()]
    assert differ == [], f"columns that differ: {differ}"
    # the compact layout carried the codes (and no sample index): one frame a period less on the bus
    assert {"i_a_code", "i_b_code", "theta_code"} <= set(c.dtype.names) and "sample_index" not in c.dtype.names
    periods = default.summary["periods"]
    assert _frames_on(tmp_path / "default", 0x190, 0x290) == (periods, periods)
    assert _frames_on(tmp_path / "compact", 0x190, 0x290) == (periods, 0)


def _frames_on(folder: Path, *cob_ids: int) -> tuple[int, ...]:
    """Frames of each identifier in a run's bus.log (python-can's reader)."""
    with can.LogReader(str(folder / "bus.log")) as log:
        ids = [m.arbitration_id for m in log]
    return tuple(ids.count(c) for c in cob_ids)


def test_compact_frame_without_sensor_models_rounds_to_its_code() -> None:
    r = run("scenarios/you2019_step.toml", [*COMPACT, "frames.current_lsb_A=0.002"])
    assert r.status == "ok"
    rows = r.rows
    assert rows is not None
    lsb = float(np.float32(0.002))
    for code, amps in (("i_a_code", "i_a_A"), ("i_b_code", "i_b_A")):
        k = rows[code].astype(np.float64)
        assert np.all(k == np.round(k))
        assert np.array_equal(rows[amps], (lsb * k).astype(np.float32).astype(np.float64))
    assert np.abs(rows["i_b_code"]).max() > 100  # the step moved them (at theta = 0, i_a carries no q current)
    # the step still reaches its reference through the 2 mA grid: the last 20 periods within 2 codes of 1 A
    assert np.abs(rows["iq_A"][-20:] - 1.0).max() < 2 * lsb


def test_a_dropped_compact_frame_is_counted_lost_by_the_drive() -> None:
    """The compact frame has no sample index: the drive numbers its samples by the SYNC counter they carry."""
    drop = 'faults=[{kind="drop", frame="plant.TPDO1", at_period=50}]'
    r = run(
        "scenarios/you2019_step.toml",
        [*COMPACT, drop, "scenario.expect='frames_lost'", "drive.command_timeout_us=2000000"],
    )
    assert r.status == "frames_lost"
    assert r.summary["bus_stats"]["drive_lost_measurements"] == 1
    assert r.summary["bus_stats"]["drive_late_measurements"] == 0


@pytest.mark.parametrize("scenario", PAPERS, ids=[s.split("/")[-1][:-5] for s in PAPERS])
def test_measurement_as_period_mark_is_todays_run_without_a_sync_frame(scenario: str, tmp_path: Path) -> None:
    """period_mark = "measurement": no SYNC frame, and the same run, every column (the law's trace included: the
    drive sends it when the next measurement arrives, as it would at SYNC k + 1)."""
    default = run(scenario, SENSORS, out=tmp_path / "default")
    marked = run(scenario, [*SENSORS, *COMPACT, "frames.period_mark=measurement"], out=tmp_path / "marked")
    assert default.status == marked.status and marked.status_expected, (default.status, marked.status)
    a, c = np.load(tmp_path / "default" / "traces.npy"), np.load(tmp_path / "marked" / "traces.npy")
    assert len(a) == len(c) == default.summary["periods"]
    traced = set(_trace_columns(scenario))
    assert traced and traced <= set(c.dtype.names), "the scenario traces its law's quantities"
    for name in (n for n in a.dtype.names if n in c.dtype.names):
        assert a[name].tobytes() == c[name].tobytes(), name
    periods = default.summary["periods"]
    assert _frames_on(tmp_path / "marked", 0x080, 0x190, 0x290) == (0, periods, 0)
    assert _frames_on(tmp_path / "default", 0x080)[0] >= periods
    assert marked.summary["bus_stats"]["sync_counter_gaps"] == 0 and marked.summary["bus_stats"]["lost_frames"] == 0
    assert marked.summary["bus_stats"]["interference"]["frames"] == 0


def _trace_columns(scenario: str) -> list[str]:
    """The columns of the scenario's drive trace TPDOs ([trace] or its law's default trace)."""
    return [column_name(e) for entries in load(REPO / scenario).trace.values() for e in entries]


@pytest.mark.parametrize(
    "frames", [COMPACT, ["frames.can=fd", "frames.measurement=single_frame"]], ids=["compact", "can_fd_single_frame"]
)
def test_a_dropped_marking_frame_is_counted_lost_by_the_drive(frames: list[str]) -> None:
    """The fault injector acts on the one measurement frame, classic or CAN FD: dropped once, it is one
    measurement the drive counts as lost (its SYNC counter skips one)."""
    drop = 'faults=[{kind="drop", frame="plant.TPDO1", at_period=50}]'
    r = run(
        "scenarios/you2019_step.toml",
        [*frames, "frames.period_mark=measurement", drop, "scenario.expect='frames_lost'",
         "drive.command_timeout_us=2000000"],
    )  # fmt: skip
    assert r.status == "frames_lost"
    assert r.summary["bus_stats"]["drive_lost_measurements"] == 1


@pytest.mark.parametrize(
    ("override", "said"),
    [
        ("frames.measurement=tiny", "frames.measurement = 'tiny': expected one of default, compact"),
        ("frames.current_lsb_A=0", "frames.current_lsb_A = 0: expected a number in 1e-06 .. 10 (A)"),
        ("frames.angle_counts=70000", "frames.angle_counts = 70000: expected an integer in 1 .. 65536"),
        (
            "frames.crc=1",
            "unknown key frames.crc; allowed in [frames]: measurement, current_lsb_A, angle_counts, period_mark",
        ),
        ("frames.period_mark=none", "frames.period_mark = 'none': expected one of sync, measurement"),
    ],
)
def test_bad_frames_values_are_refused_by_name(override: str, said: str) -> None:
    extra = [] if override.startswith(("frames.measurement", "frames.crc")) else COMPACT
    with pytest.raises(ScenarioError) as err:
        run("scenarios/you2019_step.toml", [*extra, override])
    assert said in str(err.value)


def test_a_coding_or_a_mark_without_the_compact_frame_is_refused() -> None:
    with pytest.raises(ScenarioError, match="need frames.measurement = 'compact'"):
        run("scenarios/you2019_step.toml", ["frames.current_lsb_A=0.001"])
    with pytest.raises(ScenarioError, match="period_mark = 'measurement' needs frames.measurement = 'compact'"):
        run("scenarios/you2019_step.toml", ["frames.period_mark=measurement"])


def test_replay_of_a_run_without_sync_frames_is_the_run(tmp_path: Path) -> None:
    """`bench replay` of the log of a run whose periods the compact frame marks: the run's traces, bit for bit (the
    layout, the coding and the mark from the log's own SDO traffic)."""
    run("scenarios/you2019_step.toml", [*SENSORS, *COMPACT, "frames.period_mark=measurement"], out=tmp_path / "run")
    bench_cli("replay", tmp_path / "run" / "bus.log", "--no-viewer", "--out", tmp_path / "replay", expect=0)
    a, b = np.load(tmp_path / "run" / "traces.npy"), np.load(tmp_path / "replay" / "traces.npy")
    assert a.dtype.names == b.dtype.names and len(a) == len(b) == 200
    for name in a.dtype.names:
        assert a[name].tobytes() == b[name].tobytes(), name


def test_a_lost_or_repeated_marking_frame_does_not_shift_the_rows(tmp_path: Path) -> None:
    """The decoder numbers the periods of a SYNC-less run by the counter in the compact frame: the run's log with
    period 100's frames gone (its measurement lost on the bus: the drive never answered it) and period 150's
    measurement frame recorded twice replays to the run's rows, but row 100, which is missing (and counted)."""
    run("scenarios/you2019_step.toml", [*COMPACT, "frames.period_mark=measurement"], out=tmp_path / "run")
    lines = (tmp_path / "run" / "bus.log").read_text().splitlines(keepends=True)
    marks = [i for i, line in enumerate(lines) if " 190#" in line]
    assert len(marks) == 200
    lost = [i for i in range(marks[100], marks[101]) if " 190#" in lines[i] or " 210#" in lines[i] or
            " 3A0#" in lines[i] or " 4A0#" in lines[i]]  # fmt: skip
    assert len(lost) == 4  # the measurement, the command and the two trace TPDOs of period 100
    edited = [line for i, line in enumerate(lines) if i not in lost]
    edited.insert(edited.index(lines[marks[150]]) + 1, lines[marks[150]])
    (tmp_path / "edited.log").write_text("".join(edited))
    res = bench_cli("replay", tmp_path / "edited.log", "--no-viewer", "--out", tmp_path / "replay")
    assert res.returncode == 6, res.stdout[-2000:]  # frames_lost: period 100
    a, b = np.load(tmp_path / "run" / "traces.npy"), np.load(tmp_path / "replay" / "traces.npy")
    assert len(a) == len(b) == 200
    stats = json.loads((tmp_path / "replay" / "summary.json").read_text())["bus_stats"]
    assert stats["missing_measurements"] == 1 and stats["missing_commands"] == 1
    # the repeated frame started no period: it is one frame too many in period 150, as a repeated frame is with SYNC
    assert stats["interference"]["frames"] == 1 and stats["interference"]["first_period"] == 150
    rows = np.ones(200, dtype=bool)
    rows[[99, 100]] = False  # row 100 lost; row 99's trace is the state after step 99, sent in period 100
    for name in a.dtype.names:
        assert a[name][rows].tobytes() == b[name][rows].tobytes(), name
    assert np.isnan(b["i_a_code"][100]) and np.isnan(b["v_alpha_V"][100])
    assert a["i_a_code"][99] == b["i_a_code"][99] and a["v_alpha_V"][99] == b["v_alpha_V"][99]


def test_a_log_that_starts_mid_period_decodes() -> None:
    """A capture that starts in the middle of a period (a plant TPDO before the first SYNC) is decoded, not looped on:
    the frames before the first SYNC are left, the periods start at it."""
    frames = np.zeros(6, dtype=FRAME_DTYPE)
    frames["cob_id"] = [0x190, 0x080, 0x190, 0x290, 0x080, 0x190]
    frames["dlc"] = [8, 1, 8, 8, 1, 8]
    frames["t_us"] = np.arange(6)
    frames["data"][1, 0], frames["data"][4, 0] = 5, 6
    frames["data"][3, 4] = 5  # the sync_counter of TPDO2 (theta_m_rad, sync_counter, ...)
    done = threading.Event()
    result: list[object] = []

    def decode() -> None:
        dec = Decoder()
        result.append(dec.feed(frames, last=True))
        result.append(dec.finish())
        done.set()

    threading.Thread(target=decode, daemon=True).start()
    assert done.wait(30), "the decoder did not return"


def test_faults_on_frames_the_set_never_sends_are_refused() -> None:
    with pytest.raises(ScenarioError, match=r"never sends plant\.TPDO2: the compact frame \(plant\.TPDO1\) carries"):
        run("scenarios/you2019_step.toml", [*COMPACT, 'faults=[{kind="drop", frame="plant.TPDO2", at_period=5}]'])
    with pytest.raises(ScenarioError, match="never sends SYNC: the compact frame"):
        run(
            "scenarios/you2019_step.toml",
            [*COMPACT, "frames.period_mark=measurement", 'faults=[{kind="drop", frame="SYNC", at_period=5}]'],
        )
    # with the compact frame its loss stalls a plant that waits for every command: refused as a stall
    with pytest.raises(ScenarioError, match=r"a drop of plant\.TPDO1 \(a frame of the loop\) stalls"):
        run("scenarios/you2019_step.toml", [*COMPACT, 'faults=[{kind="drop", frame="plant.TPDO1", at_period=5}]'])


def test_a_coding_that_cannot_reach_the_adc_full_scale_is_refused() -> None:
    with pytest.raises(RunRefused) as err:
        run("scenarios/you2019_step.toml", [*COMPACT, "drive.adc_lsb_A=0.005", "drive.adc_full_scale_A=200"])
    said = str(err.value)
    assert "frames.current_lsb_A = 0.005 A (the ADC model's LSB) carries +-163.835 A" in said
    assert "full scale 200 A" in said and "frames.current_lsb_A >= 0.0061" in said
