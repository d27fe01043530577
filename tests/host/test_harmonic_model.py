"""The harmonic PMSM (plant_rt/models/harmonic/, plant.eds 0x200A Model harmonic; docs/YOUR_MOTOR.md), through the
bench as a user runs it: a scenario's [motor] keys model = "harmonic", psi_5_Wb, psi_7_Wb, cogging_Nm,
cogging_periods.

- In direct mode the sampled phase currents equal an independent calculation written here: the stator-frame
  model with Ld = Lq, whose periods are closed form (numpy; the plant integrates the rotor frame with RK4);
- with every harmonic 0 it is the built-in linear plant, traces bit for bit;
- a sweep over psi_5_Wb runs each point on the model (the iq ripple grows with the harmonic; at 2 mWb and 150 rad/s
  the You 2019 deadbeat's 1 A step ends `diverged`: the step rule reads a ripple of over half the step as an
  unsettled loop, a limit of that rule with a periodic disturbance, noted in docs/YOUR_MOTOR.md).
Over vcan = direct bit for bit: tests/can/test_your_motor_vcan.py."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
from bench_cli import bench_cli

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner

STEP = REPO / "scenarios" / "you2019_step.toml"
W_M = 150.0  # rad/s, imposed
PSI5, PSI7 = 0.0015, -0.0008  # Wb: a few percent of the fundamental's 42 mWb
HARMONIC = {
    "motor.mech_mode": "imposed_speed",
    "motor.omega_imposed_rad_s": W_M,
    "motor.Lq_H": 0.00446,  # Ld = Lq: the closed form below is the surface machine's
    "motor.model": "harmonic",
    "motor.psi_5_Wb": PSI5,
    "motor.psi_7_Wb": PSI7,
    "references.iq_ref_A": 0.0,
}


def closed_form(plant: dict[str, Any], tr: np.ndarray, psi5: float, psi7: float) -> np.ndarray:
    """Phase currents a, b at each sample: L di/dt = v - R i - d psi_pm/dt in the stator frame, psi_pm = psi e^(j th)
    + psi_5 e^(-j5 th) + psi_7 e^(j7 th), th = p w_m t; the command of row k held over [k+1, k+2) (the drive's
    one-period delay). Over a period with v held: i(T) = e^(-aT) i0 + (1 - e^(-aT)) v / R - sum_k (j k w c_k / L)
    e^(j k th0) (e^(j k w T) - e^(-aT)) / (a + j k w), a = R / L."""
    R, L, T = plant["R_ohm"], plant["Ld_H"], plant["Ts_s"]
    w = plant["pole_pairs"] * plant["omega_imposed_rad_s"]
    terms = ((1.0, plant["psi_Wb"]), (-5.0, float(np.float32(psi5))), (7.0, float(np.float32(psi7))))
    a = R / L
    ea = np.exp(-a * T)
    v = tr["v_alpha_V"].astype(float) + 1j * tr["v_beta_V"].astype(float)
    i = 0j
    out = np.zeros(len(tr), complex)
    for k in range(len(tr)):
        out[k] = i
        vk = v[k - 1] if k >= 1 else 0j
        th0 = w * T * k
        nxt = ea * i + (1 - ea) * vk / R
        for order, c in terms:
            f = 1j * order * w * c / L * np.exp(1j * order * th0)
            nxt -= f * (np.exp(1j * order * w * T) - ea) / (a + 1j * order * w)
        i = nxt
    return np.stack([out.real, -0.5 * out.real + 0.5 * np.sqrt(3) * out.imag])


def test_the_harmonic_motor_equals_its_closed_form(hil_run: HilRunner) -> None:
    run = hil_run(STEP, HARMONIC, bus="direct", name="harmonic")
    tr, plant = run.traces, run.summary["plant"]
    assert plant["Ld_H"] == plant["Lq_H"]
    ia, ib = closed_form(plant, tr, PSI5, PSI7)
    err = max(np.abs(ia - tr["i_a_A"]).max(), np.abs(ib - tr["i_b_A"]).max())
    peak = np.abs(ia).max()
    assert err <= 2e-6, f"the plant differs from the closed form by {err:.3g} A (peak {peak:.3g} A)"
    # the harmonics are what the currents carry: without them the same commands give other currents
    ia0, _ = closed_form(plant, tr, 0.0, 0.0)
    assert np.abs(ia0 - tr["i_a_A"]).max() > 1000 * max(err, 1e-9)


def test_zero_harmonics_are_the_linear_plant_bit_for_bit(hil_run: HilRunner) -> None:
    over = {**HARMONIC, "motor.psi_5_Wb": 0.0, "motor.psi_7_Wb": 0.0, "references.iq_ref_A": 1.0}
    harmonic = hil_run(STEP, over, bus="direct", name="zero").expect_status("ok")
    linear = hil_run(STEP, {**over, "motor.model": "dq_linear"}, bus="direct", name="linear").expect_status("ok")
    for col in ("i_a_A", "i_b_A", "v_alpha_V", "v_beta_V"):
        np.testing.assert_array_equal(harmonic.traces[col], linear.traces[col], err_msg=col)


def test_a_sweep_over_the_fifth_harmonic(tmp_path: Path) -> None:
    out = tmp_path / "study"
    sets = [x for k, v in HARMONIC.items() if k != "motor.psi_5_Wb" for x in ("--set", f"{k}={v}")]
    bench_cli("sweep", STEP, "--grid", "motor.psi_5_Wb=0:0.002:0.001", *sets, "--set", "scenario.periods=200",
              "--serial", "--no-dashboard", "--out", out, expect=0)  # fmt: skip
    rows = sorted(pq.read_table(out / "sweep.parquet").to_pylist(), key=lambda r: float(r["motor.psi_5_Wb"]))
    assert [float(r["motor.psi_5_Wb"]) for r in rows] == [0.0, 0.001, 0.002]
    # each point ran on the model: the 6th-harmonic ripple raises the peak phase current with psi_5
    peaks = [r["max_phase_current_A"] for r in rows]
    assert peaks[0] < peaks[1] < peaks[2], peaks
    assert rows[0]["status"] == "ok"


def _folder(path: Path, motor: dict[str, Any], **tables: dict[str, Any]) -> Path:
    def toml(values: dict[str, Any]) -> str:
        return "".join(f"{k} = {v!r}\n" if not isinstance(v, str) else f'{k} = "{v}"\n' for k, v in values.items())

    path.mkdir(parents=True, exist_ok=True)
    text = "[motor]\n" + toml({"name": "harmonic test motor", "source": "this test", **motor})
    text += "".join(f"[{name}]\n{toml(values)}" for name, values in tables.items())
    (path / "motor.toml").write_text(text)
    return path


def test_a_motor_folder_gives_the_harmonic_model_as_the_scenario_keys_do(hil_run: HilRunner, tmp_path: Path) -> None:
    """The motor folder's [harmonic] table (the keys of plant.eds "Model harmonic") and [motor]'s Ld_H, Lq_H, psi_Wb:
    the same plant as a scenario's [motor] keys, traces bit for bit; the summary names the folder."""
    keys = hil_run(STEP, HARMONIC, bus="direct", name="keys").expect_status("ok")
    plant = keys.summary["plant"]
    base = {k: plant[k] for k in ("pole_pairs", "R_ohm", "Ld_H", "Lq_H", "psi_Wb")}
    folder = _folder(tmp_path / "motor", base, harmonic={"psi_5_Wb": PSI5, "psi_7_Wb": PSI7})
    rest = {k: v for k, v in HARMONIC.items() if not k.startswith("motor.") or k.startswith("motor.mech")}
    rest["motor.omega_imposed_rad_s"] = W_M
    run = hil_run(STEP, rest, bus="direct", motor=folder, name="folder").expect_status("ok")
    assert run.summary["motor"]["folder"] == str(folder)
    for col in ("i_a_A", "i_b_A", "v_alpha_V", "v_beta_V"):
        np.testing.assert_array_equal(run.traces[col], keys.traces[col], err_msg=col)


def test_a_motor_folder_without_a_map_is_checked_key_by_key(tmp_path: Path) -> None:
    base = {"pole_pairs": 4, "R_ohm": 0.2, "Ld_H": 0.002, "Lq_H": 0.003, "psi_Wb": 0.05}
    ok = _folder(tmp_path / "ok", base, harmonic={"psi_5_Wb": 0.001, "cogging_periods": 24})
    res = bench_cli("motor", "check", ok, expect=0)
    assert "model: harmonic" in res.stdout and "psi_5_Wb = 0.001" in res.stdout, res.stdout
    linear = _folder(tmp_path / "linear", base)
    assert "model: dq_linear" in bench_cli("motor", "check", linear, expect=0).stdout
    bad = {
        "no Ld_H": (_folder(tmp_path / "a", {k: v for k, v in base.items() if k != "Ld_H"}), "motor.Ld_H is required"),
        "unknown": (_folder(tmp_path / "b", base, harmonic={"psi_11_Wb": 0.1}), "unknown key harmonic.psi_11_Wb"),
        "not a number": (_folder(tmp_path / "c", base, harmonic={"psi_5_Wb": "x"}), "harmonic.psi_5_Wb = 'x'"),
        "an integer": (_folder(tmp_path / "d", base, harmonic={"cogging_periods": 2.5}), "expected an integer"),
        "thermal": (_folder(tmp_path / "e", base, thermal={"T_ref_degC": 20}), "[thermal] is the flux-map"),
        "out of range": (_folder(tmp_path / "g", {**base, "Ld_H": -0.001}), "motor.Ld_H = -0.001 is out of range"),
        "the record's range": (
            _folder(tmp_path / "h", base, harmonic={"psi_5_Wb": 1e9}),
            "harmonic.psi_5_Wb = 1000000000.0 is out of range",
        ),
        "two models": (
            _folder(tmp_path / "f", base, harmonic={}, flux_map={"file": "x.csv"}),
            "a folder describes one machine model",
        ),
    }
    for what, (folder, text) in bad.items():
        res = bench_cli("motor", "check", folder)
        assert res.returncode == 65 and text in res.stderr, (what, res.stderr)
