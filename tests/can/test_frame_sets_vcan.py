"""Issue 54's frame sets over vcan, through `bench run`. The compact measurement frame ([frames] measurement =
"compact"): the plant and drive processes map it by SDO and code/decode it in C, and with the ADC model quantizing
and an encoder the run is today's default run in direct mode bit for bit in every column both have, for the three
papers' scenarios (tests/host/test_frame_sets.py compares compact and default in direct mode). The measurement as
the period's mark (period_mark = "measurement", no SYNC frame): over vcan = direct, bit for bit."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli, why

from bench.paths import REPO

PAPERS = ["you2019_step", "yao2020_identification", "zhao2022_stability"]
SENSORS = ("--set", "drive.adc_lsb_A=0.005", "--set", "drive.encoder_lines=2500")


# Yao 2020's identification: its first 1000 periods over vcan (the whole 3000 run in direct mode, the host twin)
SHORTER = {"yao2020_identification": ("--set", "scenario.periods=1000")}


def run(scenario: str, out: Path, *args: str) -> tuple[dict[str, Any], Any]:
    bench_cli("run", REPO / "scenarios" / f"{scenario}.toml", "--no-viewer", "--out", out, *SENSORS,
              *SHORTER.get(scenario, ()), *args, timeout=1800)  # fmt: skip
    return json.loads((out / "summary.json").read_text()), np.load(out / "traces.npy")


@pytest.mark.parametrize("scenario", PAPERS)
def test_compact_frame_over_vcan_is_the_default_direct_run(scenario: str, vcan0: str, tmp_path: Path) -> None:
    d_sum, direct = run(scenario, tmp_path / "direct", "--bus", "direct")
    c_sum, compact = run(scenario, tmp_path / "vcan", "--bus", vcan0, "--set", "frames.measurement=compact")
    assert c_sum["status"] == d_sum["status"] and c_sum["status_expected"], why(c_sum)
    assert c_sum["bus_stats"]["lost_frames"] == 0 and c_sum["counters"]["drive_lost_measurements"] == 0
    assert {"i_a_code", "theta_code"} <= set(compact.dtype.names) and "sample_index" not in compact.dtype.names
    common = [n for n in direct.dtype.names if n in compact.dtype.names]
    assert {"i_a_A", "i_b_A", "theta_m_rad", "v_alpha_V", "v_beta_V", "iq_A"} <= set(common)
    for col in common:
        np.testing.assert_array_equal(compact[col], direct[col], err_msg=col)


@pytest.mark.parametrize("scenario", PAPERS)
def test_measurement_as_period_mark_over_vcan_equals_direct(scenario: str, vcan0: str, tmp_path: Path) -> None:
    """No SYNC frame on the bus: the plant's compact measurement frame marks each period; the processes over vcan
    and the in-process nodes give the same run, bit for bit, every column (the law's trace included)."""
    marked = ("--set", "frames.measurement=compact", "--set", "frames.period_mark=measurement")
    d_sum, direct = run(scenario, tmp_path / "direct", "--bus", "direct", *marked)
    v_sum, vcan = run(scenario, tmp_path / "vcan", "--bus", vcan0, *marked)
    assert v_sum["status"] == d_sum["status"] and v_sum["status_expected"], why(v_sum)
    assert v_sum["bus_stats"]["lost_frames"] == 0 and v_sum["bus_stats"]["sync_counter_gaps"] == 0, why(v_sum)
    assert vcan.dtype.names == direct.dtype.names
    for col in direct.dtype.names:
        np.testing.assert_array_equal(vcan[col], direct[col], err_msg=col)
    assert np.isfinite(vcan["iq_A"]).all()
