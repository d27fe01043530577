"""Motor provenance through the plugin (issue 52 item 7, docs/CI.md "Motor provenance"): hil_run(..., motor=) and
the hil marker's motor= run a motor folder or an FMU mapping; summary.json's "motor" block names the folder or the
FMU and a digest of its files, and the JUnit properties hil_motor and hil_motor_digest carry them. The digest is
computed here from the files themselves; editing the flux map changes it, a built-in motor has none."""

from __future__ import annotations

import csv
import hashlib
import shutil
from pathlib import Path
from typing import Any

import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner

STEP = REPO / "scenarios" / "you2019_step.toml"
EXAMPLE = REPO / "examples" / "motors" / "saturating_you2019"
SHORT = {"scenario.periods": 60}


def _digest(files: list[tuple[str, Path]]) -> str:
    """16 hex of the SHA-256 over each file's name (from its folder) and bytes, the way the summary's is defined."""
    h = hashlib.sha256()
    for name, path in files:
        h.update(name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _props(request: pytest.FixtureRequest) -> dict[str, str]:
    return dict(request.node.user_properties)


def _scale_flux_map(folder: Path, factor: float) -> None:
    """Every flux linkage of the folder's flux_map.csv times `factor` (a valid map stays valid: its Jacobian is only
    scaled)."""
    path = folder / "flux_map.csv"
    lines = path.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#") or ln.startswith("id_A")]
    rows = list(csv.reader(ln for ln in lines if ln and not ln.startswith("#") and not ln.startswith("id_A")))
    body = [f"{a},{b},{float(d) * factor!r},{float(q) * factor!r}" for a, b, d, q in rows]
    path.write_text("\n".join(head + body) + "\n")


def test_a_motor_folder_is_named_with_its_digest_and_an_edit_changes_it(
    hil_run: HilRunner, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    folder = tmp_path / "my_motor"
    shutil.copytree(EXAMPLE, folder)
    first = hil_run(STEP, SHORT, bus="direct", motor=folder).expect_status("ok")
    want = _digest([("motor.toml", folder / "motor.toml"), ("flux_map.csv", folder / "flux_map.csv")])
    block = first.summary["motor"]
    assert block == {"folder": str(folder), "fmu": None, "name": block["name"], "digest": want}, block
    assert block["name"] == "You 2019 motor with an assumed saturating flux map"
    props = _props(request)
    assert props["hil_motor"] == str(folder) and props["hil_motor_digest"] == want, props
    _scale_flux_map(folder, 1.001)
    second = hil_run(STEP, SHORT, bus="direct", motor=str(folder)).expect_status("ok")
    edited = _digest([("motor.toml", folder / "motor.toml"), ("flux_map.csv", folder / "flux_map.csv")])
    assert edited != want and second.summary["motor"]["digest"] == edited, second.summary["motor"]
    assert _props(request)["hil_run2_motor_digest"] == edited
    assert abs(second["iq_A"] - first["iq_A"]).max() > 0  # the edited map is the one the plant ran


@pytest.mark.hil(motor=str(EXAMPLE))
def test_the_markers_motor_is_the_tests_default(hil_run: HilRunner, request: pytest.FixtureRequest) -> None:
    run = hil_run(STEP, SHORT, bus="direct").expect_status("ok")
    assert run.summary["motor"]["folder"] == str(EXAMPLE) and len(run.summary["motor"]["digest"]) == 16
    assert _props(request)["hil_motor"] == str(EXAMPLE)


def test_a_built_in_motor_names_its_preset(hil_run: HilRunner, request: pytest.FixtureRequest) -> None:
    run = hil_run(STEP, SHORT, bus="direct").expect_status("ok")
    assert run.summary["motor"] == {"builtin": "you2019"}
    props = _props(request)
    assert props["hil_motor"] == "builtin:you2019" and "hil_motor_digest" not in props, props


def test_an_fmu_mapping_is_named_with_the_fmus_digest(
    hil_run: HilRunner, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    fmu = tmp_path / "linear_pmsm.fmu"
    bench_cli("motor", "fmu-build", REPO / "examples" / "fmu" / "linear_pmsm", fmu, expect=0)
    mapping: dict[str, Any] = {
        "file": str(fmu),
        "inputs": {"v_alpha_V": "v_alpha", "v_beta_V": "v_beta"},
        "outputs": {"i_a_A": "i_a", "i_b_A": "i_b", "theta_m_rad": "theta_m", "omega_m_rad_s": "omega_m"},
    }
    run = hil_run(STEP, SHORT, bus="direct", motor=mapping).expect_status("ok")
    want = _digest([("linear_pmsm.fmu", fmu)])
    assert run.summary["motor"]["fmu"] == str(fmu) and run.summary["motor"]["folder"] is None
    assert run.summary["motor"]["digest"] == want
    props = _props(request)
    assert props["hil_motor"] == str(fmu) and props["hil_motor_digest"] == want, props


def test_a_motor_that_is_neither_a_folder_nor_a_mapping_is_refused_by_name(hil_run: HilRunner) -> None:
    with pytest.raises(pytest.fail.Exception, match=r"hil_run: motor= takes a motor folder's path or an FMU"):
        hil_run(STEP, SHORT, bus="direct", motor=3)
    with pytest.raises(pytest.fail.Exception, match=r"hil_run: motor= 'no_such_motor': no such folder \(/"):
        hil_run(STEP, SHORT, bus="direct", motor="no_such_motor")
