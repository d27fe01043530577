"""Your own motor over vcan (docs/YOUR_MOTOR.md): a motor folder's flux map (downloaded to the plant node's 0x2008
by segmented SDO) and the example FMU (loaded by the plant node from 0x2009) in lockstep over vcan give the direct
run's traces bit for bit: the same C plant in the node process as in-process."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.paths import REPO

STEP = REPO / "scenarios" / "you2019_step.toml"
EXAMPLE = REPO / "examples" / "motors" / "saturating_you2019"


def run(out: Path, *args: Any) -> tuple[dict[str, Any], Any]:
    bench_cli("run", *args, "--no-viewer", "--out", out, timeout=1800, expect=0)
    return json.loads((out / "summary.json").read_text()), np.load(out / "traces.npy")


def same(direct: Any, vcan: Any) -> None:
    assert set(vcan.dtype.names) == set(direct.dtype.names)
    for col in direct.dtype.names:
        np.testing.assert_array_equal(vcan[col], direct[col], err_msg=col)


def test_a_flux_map_over_vcan_equals_direct_bit_for_bit(vcan0: str, tmp_path: Path) -> None:
    args = (STEP, "--motor", EXAMPLE, "--set", "references.iq_ref_A=0", "--set", "controller.L_hat_ratio=0.8")
    _, direct = run(tmp_path / "direct", *args, "--bus", "direct")
    summary, vcan = run(tmp_path / "vcan", *args, "--bus", vcan0)
    assert summary["status"] == "ok" and summary["bus_stats"]["lost_frames"] == 0
    same(direct, vcan)
    # the folder's default trip level: where the dq currents would leave the map (16 A), per phase
    assert abs(summary["plant"]["I_trip_A"] - 8.0 * np.sqrt(3)) < 1e-5


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fmu") / "linear_pmsm.fmu"
    bench_cli("motor", "fmu-build", REPO / "examples" / "fmu" / "linear_pmsm", out, expect=0)
    return out


def test_the_example_fmu_over_vcan_equals_direct_bit_for_bit(vcan0: str, tmp_path: Path, fmu: Path) -> None:
    sc = tmp_path / "fmu_step.toml"
    sc.write_text(
        STEP.read_text() + f'\n[motor.fmu]\nfile = "{fmu}"\ninputs = {{ v_alpha_V = "v_alpha", v_beta_V = "v_beta" }}\n'
        'outputs = { i_a_A = "i_a", i_b_A = "i_b", theta_m_rad = "theta_m", omega_m_rad_s = "omega_m" }\n'
    )
    _, direct = run(tmp_path / "direct", sc, "--bus", "direct")
    summary, vcan = run(tmp_path / "vcan", sc, "--bus", vcan0)
    assert summary["status"] == "ok" and summary["bus_stats"]["lost_frames"] == 0
    same(direct, vcan)
    assert np.nanmax(direct["iq_A"]) > 0.9  # the step happened


def test_the_harmonic_model_over_vcan_equals_direct_bit_for_bit(vcan0: str, tmp_path: Path) -> None:
    """The harmonic PMSM (0x200A Model harmonic written by SDO like the motor model's record) at 150 rad/s."""
    sets = ("motor.model=harmonic", "motor.psi_5_Wb=0.0005", "motor.psi_7_Wb=-0.0003", "motor.cogging_Nm=0.02",
            "motor.cogging_periods=12", "motor.mech_mode=imposed_speed", "motor.omega_imposed_rad_s=150")  # fmt: skip
    args = (STEP, *(x for s in sets for x in ("--set", s)))
    _, direct = run(tmp_path / "direct", *args, "--bus", "direct")
    summary, vcan = run(tmp_path / "vcan", *args, "--bus", vcan0)
    assert summary["bus_stats"]["lost_frames"] == 0
    same(direct, vcan)
    _, linear = run(tmp_path / "linear", *args, "--set", "motor.model=dq_linear", "--bus", "direct")
    assert np.abs(linear["i_a_A"] - direct["i_a_A"]).max() > 1e-3  # the harmonics were written and used
