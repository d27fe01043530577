"""CAN FD in the loop over vcan (issue 54 item 1), through `bench run`: the plant and drive processes send their PDOs
as CAN FD frames over the CAN box's vcan (MTU 72), candump records them, the decoder reads them, and the run equals
today's classic run in direct mode bit for bit in every column both have, for the three papers' scenarios
(tests/host/test_can_fd.py compares FD and classic in direct mode):

- frames.measurement = "single_frame" with the measurement as the period's mark: one 16-byte CAN FD frame a period
  from the plant, no SYNC frame;
- the integer option (the compact frame, ADC model and encoder on) on CAN FD frames without the bit-rate switch;
- `bench replay` of the box's FD log (candump's `##` lines) is the run."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest
from bench_cli import bench_cli, why

from bench.paths import REPO

PAPERS = ["you2019_step", "yao2020_identification", "zhao2022_stability"]
SENSORS = ("--set", "drive.adc_lsb_A=0.005", "--set", "drive.encoder_lines=2500")
SHORTER = {"yao2020_identification": ("--set", "scenario.periods=1000")}  # its first 1000 periods over vcan
SINGLE_MARK = (
    "--set", "frames.can=fd", "--set", "frames.measurement=single_frame", "--set", "frames.period_mark=measurement",
)  # fmt: skip


def run(scenario: str, out: Path, *args: str) -> tuple[dict[str, Any], Any]:
    bench_cli("run", REPO / "scenarios" / f"{scenario}.toml", "--no-viewer", "--out", out, *SENSORS,
              *SHORTER.get(scenario, ()), *args, timeout=1800)  # fmt: skip
    return json.loads((out / "summary.json").read_text()), np.load(out / "traces.npy")


def equal_columns(fd: Any, classic: Any) -> None:
    common = [n for n in classic.dtype.names if n in fd.dtype.names]
    assert {"i_a_A", "i_b_A", "theta_m_rad", "v_alpha_V", "v_beta_V", "iq_A"} <= set(common)
    for col in common:
        np.testing.assert_array_equal(fd[col], classic[col], err_msg=col)


def fd_frames_of(folder: Path) -> tuple[set[int], set[int], set[int]]:
    """(CAN FD identifiers, their lengths, the classic identifiers) of a run's bus.log (python-can's reader)."""
    with can.LogReader(str(folder / "bus.log")) as log:
        msgs = list(log)
    fd = {m.arbitration_id for m in msgs if m.is_fd}
    return fd, {len(m.data) for m in msgs if m.is_fd}, {m.arbitration_id for m in msgs if not m.is_fd}


@pytest.mark.parametrize("scenario", PAPERS)
def test_single_can_fd_frame_over_vcan_is_the_classic_direct_run(scenario: str, vcan0: str, tmp_path: Path) -> None:
    d_sum, direct = run(scenario, tmp_path / "direct", "--bus", "direct")
    v_sum, vcan = run(scenario, tmp_path / "vcan", "--bus", vcan0, *SINGLE_MARK)
    assert v_sum["status"] == d_sum["status"] and v_sum["status_expected"], why(v_sum)
    assert v_sum["bus_stats"]["lost_frames"] == 0 and v_sum["bus_stats"]["sync_counter_gaps"] == 0, why(v_sum)
    equal_columns(vcan, direct)
    fd, lengths, classic = fd_frames_of(tmp_path / "vcan")
    assert {0x190, 0x210} <= fd and 16 in lengths and 0x290 not in fd | classic and 0x080 not in classic
    assert 0x490 in classic and 0x490 not in fd  # the plant's hold announcement: classic, for the SLCAN master
    if scenario == "you2019_step":  # the box's log, replayed on the host: the run, bit for bit
        bench_cli("replay", tmp_path / "vcan" / "bus.log", "--no-viewer", "--out", tmp_path / "replay", expect=0)
        replay = np.load(tmp_path / "replay" / "traces.npy")
        assert replay.dtype.names == vcan.dtype.names
        for col in vcan.dtype.names:
            np.testing.assert_array_equal(replay[col], vcan[col], err_msg=col)


@pytest.mark.parametrize("scenario", PAPERS)
def test_compact_frame_on_can_fd_over_vcan_is_the_classic_direct_run(scenario: str, vcan0: str, tmp_path: Path) -> None:
    d_sum, direct = run(scenario, tmp_path / "direct", "--bus", "direct")
    args = ("--set", "frames.can=fd", "--set", "frames.measurement=compact", "--set", "frames.bit_rate_switch=false")
    v_sum, vcan = run(scenario, tmp_path / "vcan", "--bus", vcan0, *args)
    assert v_sum["status"] == d_sum["status"] and v_sum["status_expected"], why(v_sum)
    equal_columns(vcan, direct)
    fd, lengths, _ = fd_frames_of(tmp_path / "vcan")
    assert {0x190, 0x210} <= fd and 8 in lengths and max(lengths) == 8  # the compact frame fits classic sizes
