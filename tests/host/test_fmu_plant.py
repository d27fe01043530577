"""Any plant as an FMU (docs/YOUR_MOTOR.md, issue 42): the bench's own linear PMSM as a C source FMU
(examples/fmu/linear_pmsm), built by `bench motor fmu-build` as a user builds theirs, run as the plant through the
plugin's hil_run: it reproduces the built-in plant; every bad mapping or FMU is refused before anything starts,
naming the key, the variable and what is wrong; an FMU whose step fails mid-run ends the run plant_fault with its
frames kept."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner

SOURCE = REPO / "examples" / "fmu" / "linear_pmsm"
INPUTS = {"v_alpha_V": "v_alpha", "v_beta_V": "v_beta"}
OUTPUTS = {"i_a_A": "i_a", "i_b_A": "i_b", "theta_m_rad": "theta_m", "omega_m_rad_s": "omega_m"}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    """The example as FMI 2.0 (examples/fmu/linear_pmsm) and 3.0 (linear_pmsm_fmi3, the same model)."""
    d = tmp_path_factory.mktemp("fmu")
    out = {2: d / "linear_pmsm.fmu", 3: d / "linear_pmsm_fmi3.fmu"}
    for src, fmu_file in ((SOURCE, out[2]), (SOURCE.with_name("linear_pmsm_fmi3"), out[3])):
        res = bench_cli("motor", "fmu-build", src, fmu_file, expect=0)
        assert "wrote" in res.stdout
    return out


@pytest.fixture(scope="module")
def fmu(fmus: dict[int, Path]) -> Path:
    return fmus[2]


def scenario(fmu: Path | None, periods: int = 200, **fmu_keys: Any) -> dict[str, Any]:
    sc: dict[str, Any] = {
        "scenario": {"name": "fmu-step", "periods": periods},
        "motor": {"preset": "you2019"},
        "drive": {"preset": "ideal"},
        "events": [
            {"at_period": 20, "references": {"iq_ref_A": 1.0}},
            {"at_period": 120, "references": {"iq_ref_A": -2.0}},
        ],
    }
    if fmu is not None:
        sc["motor"]["fmu"] = {"file": str(fmu), "inputs": INPUTS, "outputs": OUTPUTS, **fmu_keys}
    return sc


@pytest.mark.parametrize(
    "fmi, over, fmu_params",
    [
        (2, {"controller.L_hat_ratio": 0.6}, {}),
        (2, {"controller.L_hat_ratio": 1.4}, {}),
        (2, {"motor.mech_mode": "imposed_speed", "motor.omega_imposed_rad_s": 150.0}, {"omega_imposed": 150.0}),
        (3, {"motor.mech_mode": "imposed_speed", "motor.omega_imposed_rad_s": 150.0}, {"omega_imposed": 150.0}),
    ],
    ids=["fmi2-L_hat_0.6", "fmi2-L_hat_1.4", "fmi2-150_rad_s", "fmi3-150_rad_s"],
)
def test_the_example_fmu_reproduces_the_built_in_plant(
    hil_run: HilRunner, fmus: dict[int, Path], fmi: int, over: dict[str, Any], fmu_params: dict[str, float]
) -> None:
    """The regression net of issue 42: the linear PMSM as an FMU (RK4, 20 steps a period; FMI 2.0 and 3.0) against
    the plant's exact discretization, locked with a mismatched controller and at an imposed speed: <= 1e-6 A."""
    built_in = hil_run(scenario(None), over, bus="direct", name="built-in").expect_status("ok")
    sc = scenario(fmus[fmi], parameters=fmu_params)
    with_fmu = hil_run(sc, over, bus="direct", name="fmu").expect_status("ok")
    for col in ("i_a_A", "i_b_A", "theta_m_rad"):
        diff = np.abs(built_in[col].astype(float) - with_fmu[col].astype(float)).max()
        assert diff <= 1e-6, f"{col}: the FMU plant differs from the built-in plant by {diff:.3g}"
    assert np.abs(with_fmu["iq_A"]).max() > 1.5  # the steps ran


def _refused(tmp_path: Path, sc: dict[str, Any], needle: str) -> None:

    path = tmp_path / "sc.toml"
    path.write_text(_toml(sc))
    out = tmp_path / "out"
    res = bench_cli("run", path, "--bus", "direct", "--no-viewer", "--out", out)
    assert res.returncode != 0, res.stdout
    assert needle in res.stderr, res.stderr
    assert not out.exists()  # nothing half-written


def _toml(sc: dict[str, Any]) -> str:
    def val(v: Any) -> str:
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        if isinstance(v, str):
            return json.dumps(v)
        return repr(v)

    lines = []
    for table, body in sc.items():
        if table == "events":
            for ev in body:
                lines.append("[[events]]")
                lines += [f"{k} = {val(v)}" for k, v in ev.items()]
            continue
        subs = {k: v for k, v in body.items() if k == "fmu"}
        lines.append(f"[{table}]")
        lines += [f"{k} = {val(v)}" for k, v in body.items() if k not in subs]
        for k, v in subs.items():
            lines.append(f"[{table}.{k}]")
            lines += [f"{kk} = {val(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "change, needle",
    [
        (
            {"inputs": {"v_alpha_V": "v_x", "v_beta_V": "v_beta"}},
            "motor.fmu.inputs.v_alpha_V = 'v_x': the FMU has no variable 'v_x' (its inputs: v_alpha, v_beta)",
        ),
        (
            {"inputs": {"v_alpha_V": "i_a", "v_beta_V": "v_beta"}},
            "motor.fmu.inputs.v_alpha_V = 'i_a': 'i_a' has causality output, motor.fmu.inputs.v_alpha_V needs an input",
        ),
        (
            {"outputs": {**OUTPUTS, "theta_m_rad": "omega_m"}},
            "'omega_m' is in 'rad/s', motor.fmu.outputs.theta_m_rad needs 'rad'",
        ),
        ({"outputs": {"i_a_A": "i_a", "theta_m_rad": "theta_m"}}, "motor.fmu.outputs must map {i_a_A, i_b_A} or"),
        ({"parameters": {"Rs": 1.0}}, "motor.fmu.parameters.Rs = 'Rs': the FMU has no variable 'Rs'"),
        ({"substeps": 0}, "motor.fmu.substeps = 0: expected an integer in 1 .. 10000"),
        ({"tolerance": 1e-6}, "unknown key motor.fmu.tolerance; allowed: file, inputs, outputs, parameters, substeps"),
    ],
    ids=["no-such-variable", "wrong-causality", "wrong-unit", "no-currents", "no-such-parameter", "substeps", "key"],
)
def test_a_bad_mapping_is_refused_naming_the_key_and_the_variable(
    tmp_path: Path, fmu: Path, change: dict[str, Any], needle: str
) -> None:
    sc = scenario(fmu)
    sc["motor"]["fmu"].update(change)
    _refused(tmp_path, sc, needle)


def test_an_fmu_without_a_linux_binary_is_refused(tmp_path: Path, fmu: Path) -> None:
    win = tmp_path / "win_only.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(win, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            name = item.filename.replace("binaries/linux64/linear_pmsm.so", "binaries/win64/linear_pmsm.dll")
            dst.writestr(name, data)
    sc = scenario(win)
    _refused(tmp_path, sc, "no binary for Linux x86-64 (binaries/linux64/linear_pmsm.so); it has: win64")


def test_a_file_that_is_no_fmu_is_refused(tmp_path: Path) -> None:
    bad = tmp_path / "not.fmu"
    bad.write_bytes(b"not a zip")
    _refused(tmp_path, scenario(bad), "not a valid FMU")
    _refused(tmp_path, scenario(tmp_path / "missing.fmu"), "missing.fmu is missing")


def test_an_fmu_whose_step_fails_mid_run_ends_the_run_plant_fault(hil_run: HilRunner, fmu: Path) -> None:
    """fail_at (the example's test hook) makes doStep return fmi2Error from 5 ms on: the plant raises EMCY
    model_fault, switches its inverter off and stops stepping the model; the run keeps every frame."""
    run = hil_run(scenario(fmu, parameters={"fail_at": 0.005}), bus="direct")
    assert run.status == "plant_fault" and run.exit_code == 12, run.summary["status"]
    period = int(round(0.005 / 55e-6)) + 1  # the first period whose step starts at or after 5 ms
    emcy = [e for e in run.summary["emcy"] if e["node"] == "plant"]
    assert emcy and emcy[0]["code"].upper().endswith("FF20") and abs(emcy[0]["period"] - period) <= 1, emcy
    assert len(run.traces) == 200 and run.summary["bus_stats"]["lost_frames"] == 0
    assert "the plant's model failed" in run.stdout
