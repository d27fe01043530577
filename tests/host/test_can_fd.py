"""CAN FD in the loop (issue 54 item 1), run the way users run it (bench.api.run in process, `bench replay`, `bench
export`): a scenario's frames.can = "fd" puts both nodes' PDOs in CAN FD frames (plant.eds / drive.eds 0x2105),
frames.measurement = "single_frame" carries the measurement's REAL32 values in one 16-byte CAN FD frame, and the
run equals today's classic run bit for bit in every column, over the three papers' scenarios:

- the loop's PDOs are CAN FD frames (with the bit-rate switch unless frames.bit_rate_switch = false); SDO, NMT,
  SYNC, heartbeat and the plant's hold announcement stay classic;
- a replay of the FD run's log is the run; its export to .asc and .blf keeps the CAN FD frames;
- what CAN FD cannot mean is refused by name (a 16-byte frame on classic CAN, a bit-rate switch without FD).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import can
import numpy as np
import pytest
from bench_cli import bench_cli
from papers import PAPERS, SENSORS

from bench.api import ScenarioError, run
from bench.paths import REPO

FD = ["frames.can=fd"]
SINGLE = [*FD, "frames.measurement=single_frame"]
LOOP_COBS = {0x190, 0x290, 0x210}  # plant TPDO1, TPDO2, drive TPDO1 (the EDS's COB-IDs at the default node-IDs)


def _same_columns(a: np.ndarray, b: np.ndarray) -> None:
    assert len(a) == len(b)
    common = [n for n in a.dtype.names if n in b.dtype.names]
    for name in ("i_a_A", "i_b_A", "theta_m_rad", "v_alpha_V", "v_beta_V", "id_A", "iq_A"):
        assert name in common, name
    assert [n for n in common if a[n].tobytes() != b[n].tobytes()] == []
    assert set(a.dtype.names) <= set(b.dtype.names) | {"sample_index"}


def _messages(folder: Path) -> list[can.Message]:
    with can.LogReader(str(folder / "bus.log")) as log:
        return list(log)


@pytest.mark.parametrize("scenario", PAPERS, ids=[s.split("/")[-1][:-5] for s in PAPERS])
@pytest.mark.parametrize(
    "frames",
    [SINGLE, [*SINGLE, "frames.period_mark=measurement"], [*FD, "frames.measurement=compact"]],
    ids=["single_frame", "single_frame_mark", "compact"],
)
def test_a_can_fd_run_is_todays_classic_run_bit_for_bit(scenario: str, frames: list[str], tmp_path: Path) -> None:
    classic = run(scenario, SENSORS, out=tmp_path / "classic")
    fd = run(scenario, [*SENSORS, *frames], out=tmp_path / "fd")
    assert classic.status == fd.status and fd.status_expected, (classic.status, fd.status)
    _same_columns(np.load(tmp_path / "classic" / "traces.npy"), np.load(tmp_path / "fd" / "traces.npy"))
    msgs = _messages(tmp_path / "fd")
    loop = [m for m in msgs if m.arbitration_id in LOOP_COBS]
    assert loop and all(m.is_fd and m.bitrate_switch for m in loop)
    one = [m for m in loop if m.arbitration_id == 0x190]
    assert len(one) == fd.summary["periods"] and {len(m.data) for m in one} == ({16} if SINGLE[1] in frames else {8})
    assert not any(m.arbitration_id == 0x290 for m in msgs)  # the whole sample in one frame
    service = [m for m in msgs if m.arbitration_id >= 0x580 or m.arbitration_id in (0x000, 0x080)]
    assert service and not any(m.is_fd for m in service)  # SDO, NMT, SYNC, heartbeat: classic
    assert fd.summary["bus_stats"]["lost_frames"] == 0 and fd.summary["bus_stats"]["interference"]["frames"] == 0


def test_can_fd_with_todays_frames_and_without_the_bit_rate_switch(tmp_path: Path) -> None:
    classic = run("scenarios/you2019_step.toml", [], out=tmp_path / "classic")
    fd = run("scenarios/you2019_step.toml", [*FD, "frames.bit_rate_switch=false"], out=tmp_path / "fd")
    assert classic.status == fd.status == "ok"
    _same_columns(np.load(tmp_path / "classic" / "traces.npy"), np.load(tmp_path / "fd" / "traces.npy"))
    msgs = _messages(tmp_path / "fd")
    loop = [m for m in msgs if m.arbitration_id in LOOP_COBS]
    assert {m.arbitration_id for m in loop} == LOOP_COBS and all(m.is_fd and not m.bitrate_switch for m in loop)


def test_replay_and_export_of_a_can_fd_log(tmp_path: Path) -> None:
    """`bench replay` of an FD run's log is the run, bit for bit; `bench export` to .asc and .blf keeps every frame
    with its CAN FD length and flags (python-can's readers)."""
    run("scenarios/you2019_step.toml", [*SINGLE, "frames.period_mark=measurement"], out=tmp_path / "run")
    bench_cli("replay", tmp_path / "run" / "bus.log", "--no-viewer", "--out", tmp_path / "replay", expect=0)
    a, b = np.load(tmp_path / "run" / "traces.npy"), np.load(tmp_path / "replay" / "traces.npy")
    assert a.dtype.names == b.dtype.names and len(a) == len(b) == 200
    assert [n for n in a.dtype.names if a[n].tobytes() != b[n].tobytes()] == []
    ref = [(m.arbitration_id, bytes(m.data), m.is_fd, m.bitrate_switch) for m in _messages(tmp_path / "run")]
    for fmt in ("asc", "blf"):
        dst = tmp_path / f"bus.{fmt}"
        bench_cli("export", tmp_path / "run" / "bus.log", dst, expect=0)
        with can.LogReader(str(dst)) as log:
            got = [(m.arbitration_id, bytes(m.data), m.is_fd, m.bitrate_switch) for m in log]
        assert got == ref, fmt


@pytest.mark.parametrize(
    ("overrides", "said"),
    [
        (["frames.measurement=single_frame"], "frames.measurement = 'single_frame' is 16 bytes: it needs frames.can"),
        (["frames.bit_rate_switch=false"], "frames.bit_rate_switch = false needs frames.can = 'fd'"),
        (["frames.can=fdx"], "frames.can = 'fdx': expected one of classic, fd"),
        ([*FD, "frames.bit_rate_switch=1"], "frames.bit_rate_switch = 1: expected true or false"),
    ],
)
def test_what_can_fd_cannot_mean_is_refused_by_name(overrides: list[str], said: str) -> None:
    with pytest.raises(ScenarioError) as err:
        run("scenarios/you2019_step.toml", overrides)
    assert said in str(err.value)


@pytest.mark.parametrize(
    ("info", "box", "said"),
    [
        ({"kind": "vcan", "mtu": 16}, None, "`ip link set vcan0 down && ip link set vcan0 mtu 72 up`"),
        ({"kind": "can", "mtu": 16}, None, "type can bitrate B dbitrate D fd on"),
        ({"kind": "vcan", "mtu": 16}, object(), "`bench box down`"),
    ],
)
def test_a_can_fd_run_on_a_classic_link_is_refused_with_the_fix(info: dict, box: object, said: str) -> None:
    """A link of MTU 16 carries no CAN FD frame: the run is refused before its nodes start, naming the link and the
    command that sets it (the kernel changes a vcan's MTU only while it is down); MTU 72 passes."""
    from bench.run.bus.kind import SettingRefused
    from bench.run.loop.session_bus import SessionBus

    session = SimpleNamespace(box=box)
    with pytest.raises(SettingRefused) as err:
        SessionBus._check_fd_links(session, {"vcan0": info})  # type: ignore[arg-type]
    assert "vcan0 carries classic CAN frames only (MTU 16)" in str(err.value) and said in str(err.value)
    SessionBus._check_fd_links(session, {"vcan0": {**info, "mtu": 72}})  # type: ignore[arg-type]


def test_the_docs_frames_table_switched_back_to_classic_by_set(tmp_path: Path) -> None:
    """docs/PHYSICAL_BUS.md's [frames] table (can = "fd", bit_rate_switch = true, single_frame, its mark) in a
    scenario, and the same scenario with --set frames.can=classic --set frames.measurement=compact: both run (the
    default bit_rate_switch = true is harmless on classic frames)."""
    text = (REPO / "docs" / "PHYSICAL_BUS.md").read_text()
    table = text.split("## CAN FD in the loop", 1)[1].split("```toml", 1)[1].split("```", 1)[0]
    scenario = tmp_path / "fd.toml"
    scenario.write_text((REPO / "scenarios" / "you2019_step.toml").read_text() + table)
    assert run(scenario, []).status == "ok"
    assert run(scenario, ["frames.can=classic", "frames.measurement=compact"]).status == "ok"
