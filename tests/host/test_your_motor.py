"""Your own motor in the loop (docs/YOUR_MOTOR.md, issue 42): a motor folder (motor.toml and a flux-map table) run
through the bench's front doors (`bench run --motor`, the plugin's hil_run with motor.folder), checked for exactness
against the built-in linear plant (a tabulated linear map) and against an independent integration of a saturating
map written here from the equations (flux linkages as states, the currents by Newton's method with a finite-
difference Jacobian, fine RK4), and refused when bad, each refusal naming the file, the row and the value."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner

STEP = REPO / "scenarios" / "you2019_step.toml"
EXAMPLE = REPO / "examples" / "motors" / "saturating_you2019"
# You 2019's motor (the preset you2019: plant_rt/core/presets.c, Table A1)
R_OHM, LD_H, LQ_H, PSI_WB, POLES, TS_S = 1.4, 4.46e-3, 4.54e-3, 0.042, 5, 55e-6


def write_folder(folder: Path, ids: np.ndarray, iqs: np.ndarray, pd: np.ndarray, pq: np.ndarray, **motor: Any) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    keys = {"name": "test motor", "source": "tests/host/test_your_motor.py", "pole_pairs": POLES, "R_ohm": R_OHM}
    keys.update(motor)
    body = "\n".join(f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"' for k, v in keys.items())
    (folder / "motor.toml").write_text(f'[motor]\n{body}\n[flux_map]\nfile = "flux_map.csv"\n')
    rows = ["id_A,iq_A,psi_d_Wb,psi_q_Wb"]
    rows += [
        f"{float(a)!r},{float(b)!r},{float(pd[i, j])!r},{float(pq[i, j])!r}"
        for i, a in enumerate(ids)
        for j, b in enumerate(iqs)
    ]
    (folder / "flux_map.csv").write_text("\n".join(rows) + "\n")
    return folder


def linear_folder(folder: Path) -> Path:
    g = np.linspace(-16.0, 16.0, 9)
    idg, iqg = np.meshgrid(g, g, indexing="ij")
    return write_folder(folder, g, g, LD_H * idg + PSI_WB, LQ_H * iqg)


# ---------------------------------------------------------------- the independent model (from the equations)
def read_map(folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    with (folder / "flux_map.csv").open() as f:
        a = np.array([r for r in csv.reader(line for line in f if not line.startswith("#"))][1:], float)
    ids, iqs = np.unique(a[:, 0]), np.unique(a[:, 1])
    pd, pq = np.zeros((len(ids), len(iqs))), np.zeros((len(ids), len(iqs)))
    for r in a:
        i, j = np.searchsorted(ids, r[0]), np.searchsorted(iqs, r[1])
        pd[i, j], pq[i, j] = r[2], r[3]
    return ids, iqs, pd, pq


def interp2(m: tuple[np.ndarray, ...], t: np.ndarray, x: float, y: float) -> float:
    """Bilinear interpolation by fractional grid indices (the currents of these runs stay inside the grid)."""
    ids, iqs = m[0], m[1]
    fi, fj = np.interp(x, ids, np.arange(len(ids))), np.interp(y, iqs, np.arange(len(iqs)))
    i, j = min(int(fi), len(ids) - 2), min(int(fj), len(iqs) - 2)
    u, w = fi - i, fj - j
    return float(
        (1 - u) * (1 - w) * t[i, j] + u * (1 - w) * t[i + 1, j] + (1 - u) * w * t[i, j + 1] + u * w * t[i + 1, j + 1]
    )


def fluxes(m: tuple[np.ndarray, ...], x: np.ndarray) -> np.ndarray:
    return np.array([interp2(m, m[2], x[0], x[1]), interp2(m, m[3], x[0], x[1])])


def currents(m: tuple[np.ndarray, ...], psi: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """Newton's method with a central-difference Jacobian (not the plant's analytic cell derivatives)."""
    x = guess.copy()
    for _ in range(50):
        J = np.empty((2, 2))
        for c in range(2):
            e = np.zeros(2)
            e[c] = 1e-6
            J[:, c] = (fluxes(m, x + e) - fluxes(m, x - e)) / 2e-6
        dx = np.linalg.solve(J, fluxes(m, x) - psi)
        x = x - dx
        if np.abs(dx).max() < 1e-12:
            break
    return x


def integrate(m: tuple[np.ndarray, ...], tr: np.ndarray, R: float, sub: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Phase currents a, b at each period's sample: the command of row k held over [k+1, k+2) (the drive's one-period
    computation delay), RK4 on the flux linkages with `sub` steps a period."""
    n = len(tr)
    va, vb = tr["v_alpha_V"].astype(float), tr["v_beta_V"].astype(float)
    th = tr["theta_m_rad"].astype(float) * POLES
    x = np.zeros(2)
    psi = fluxes(m, x)
    out = np.zeros((n, 2))
    for k in range(n):
        out[k] = x
        a, b = (va[k - 1], vb[k - 1]) if k >= 1 else (0.0, 0.0)
        c, s = np.cos(th[k]), np.sin(th[k])
        v = np.array([a * c + b * s, -a * s + b * c])
        h = TS_S / sub
        for _ in range(sub):
            k1 = v - R * (x := currents(m, psi, x))
            k2 = v - R * (x := currents(m, psi + h / 2 * k1, x))
            k3 = v - R * (x := currents(m, psi + h / 2 * k2, x))
            k4 = v - R * (x := currents(m, psi + h * k3, x))
            psi = psi + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        x = currents(m, psi, x)
    ia = out[:, 0] * np.cos(th) - out[:, 1] * np.sin(th)
    beta = out[:, 0] * np.sin(th) + out[:, 1] * np.cos(th)
    return ia, -0.5 * ia + 0.5 * np.sqrt(3) * beta


# ---------------------------------------------------------------- exactness
@pytest.mark.parametrize("ratio", [0.6, 1.0, 1.4])
def test_a_tabulated_linear_map_reproduces_the_built_in_plant(hil_run: HilRunner, tmp_path: Path, ratio: float) -> None:
    """The regression net of issue 42: psi_d = Ld id + psi, psi_q = Lq iq on a grid gives the linear plant's
    currents to <= 1e-6 A over the step response with a mismatched controller (You 2019 Fig. 14's L_hat)."""
    folder = linear_folder(tmp_path / "linear")
    over = {"controller.L_hat_ratio": ratio}
    built_in = hil_run(STEP, over, bus="direct", name="built-in").expect_status("ok")
    mapped = hil_run(STEP, {**over, "motor.folder": str(folder)}, bus="direct", name="map").expect_status("ok")
    for col in ("i_a_A", "i_b_A", "iq_A"):
        diff = np.abs(built_in[col].astype(float) - mapped[col].astype(float)).max()
        assert diff <= 1e-6, f"{col}: the tabulated linear map differs from the built-in plant by {diff:.3g} A"
    assert np.abs(mapped["iq_A"]).max() > 0.9  # the step ran


def test_a_saturating_map_matches_an_independent_integration(hil_run: HilRunner, tmp_path: Path) -> None:
    """The example motor's map, an 8 A step (its incremental Lq falls to ~60 %): the plant's sampled currents equal the
    independent fine-step integration of the same map to 2e-6 A (the samples are REAL32: 8 A has a 1e-6 A
    spacing), and differ from the unsaturated plant's by far more."""
    sc = {
        "scenario": {"name": "sat-step", "periods": 120},
        "drive": {"preset": "ideal", "mod_limit": "none"},  # the command applied as is: the map alone is tested
        "events": [{"at_period": 20, "references": {"iq_ref_A": 8.0}}],
    }
    # the example without its thermal model (the C tests check that one: test_plant_fluxmap.c): R stays R_ohm
    folder = tmp_path / "example"
    folder.mkdir()
    (folder / "flux_map.csv").write_text((EXAMPLE / "flux_map.csv").read_text())
    desc = (EXAMPLE / "motor.toml").read_text()
    (folder / "motor.toml").write_text(desc[: desc.index("[thermal]")])
    run = hil_run(sc, {"motor.folder": str(folder), "controller.controller": "deadbeat_you2019"}, bus="direct")
    run.expect_status("ok")
    tr = run.traces
    ia, ib = integrate(read_map(folder), tr, R_OHM)
    err = max(np.abs(ia - tr["i_a_A"]).max(), np.abs(ib - tr["i_b_A"]).max())
    assert err <= 2e-6, f"the plant differs from the independent integration of its map by {err:.3g} A"
    linear = hil_run(sc, {"controller.controller": "deadbeat_you2019"}, bus="direct", name="unsaturated")
    apart = np.abs(linear["i_b_A"].astype(float) - tr["i_b_A"]).max()
    assert apart > 0.05, f"the saturating map changed the response by {apart:.3g} A only"


# ---------------------------------------------------------------- the folder, its commands, its refusals
def test_the_committed_example_is_what_bench_motor_example_writes(tmp_path: Path) -> None:
    out = tmp_path / "ex"
    res = bench_cli("motor", "example", out, expect=0)
    assert "bench run SCENARIO --motor" in res.stdout
    for name in ("motor.toml", "flux_map.csv"):
        assert (out / name).read_text() == (EXAMPLE / name).read_text(), name
    res = bench_cli("motor", "check", EXAMPLE, expect=0)
    assert "33 x 33 points" in res.stdout and "invertible" in res.stdout and "Ld 4.45 mH" in res.stdout
    again = bench_cli("motor", "example", out)
    assert again.returncode != 0 and "exists" in again.stderr


def _bad(folder: Path, edit: Any) -> Path:
    linear_folder(folder)
    p = folder / "flux_map.csv"
    lines = p.read_text().splitlines()
    edit(lines)
    p.write_text("\n".join(lines) + "\n")
    return folder


def _set_cell(lines: list[str], row: int, col: int, value: str) -> None:
    cells = lines[row - 1].split(",")
    cells[col] = value
    lines[row - 1] = ",".join(cells)


@pytest.mark.parametrize(
    "edit, needles",
    [
        (lambda ls: _set_cell(ls, 5, 2, "nan"), ["flux_map.csv: row 5: psi_d_Wb = 'nan' is not finite"]),
        (lambda ls: _set_cell(ls, 7, 3, "0.01x"), ["row 7: psi_q_Wb = '0.01x' is not a number"]),
        (lambda ls: ls.pop(30), ["the grid is not complete: no row for id_A = -4, iq_A = -8"]),
        (lambda ls: ls.append(ls[3]), ["row 83: the point id_A = -16, iq_A = -8 is already row 4"]),
        (
            lambda ls: _set_cell(ls, 41, 2, "-0.5"),
            ["flux_map.csv: row 32 and row 41: psi_d_Wb does not rise with id_A: 0.02416, then -0.5"],
        ),
        (lambda ls: _set_cell(ls, 41, 3, "0.9"), ["psi_q_Wb does not rise with iq_A"]),
        (lambda ls: ls.__setitem__(0, "id,iq,psid,psiq"), ["row 1: header 'id,iq,psid,psiq'"]),
    ],
)
def test_a_bad_map_is_refused_naming_file_row_and_value(tmp_path: Path, edit: Any, needles: list[str]) -> None:
    folder = _bad(tmp_path / "bad", edit)
    out = tmp_path / "run"
    res = bench_cli("run", STEP, "--bus", "direct", "--no-viewer", "--out", out, "--motor", folder)
    assert res.returncode != 0, res.stdout
    for needle in needles:
        assert needle in res.stderr, res.stderr
    assert not out.exists()  # nothing half-written
    check = bench_cli("motor", "check", folder)
    assert check.returncode == 65 and needles[0] in check.stderr


def test_a_folder_without_its_table_or_description_is_refused(tmp_path: Path) -> None:
    folder = linear_folder(tmp_path / "m")
    (folder / "flux_map.csv").unlink()
    res = bench_cli("motor", "check", folder)
    assert res.returncode == 65 and "flux_map.csv is missing" in res.stderr, res.stderr
    (folder / "motor.toml").unlink()
    res = bench_cli("motor", "check", folder)
    assert res.returncode == 65 and "motor.toml: missing" in res.stderr, res.stderr


def test_a_map_smaller_than_the_trip_level_is_refused(tmp_path: Path) -> None:
    """The plant must trip before it would extrapolate the map; the trip is per phase, so a dq current reaches
    2/sqrt(3) times it: without a trip level of its own the folder's run trips at sqrt(3)/2 of where the map ends;
    a scenario's (or the folder's) level beyond that is refused, naming both; a map of one sign is refused."""
    import json

    g = np.linspace(-10.0, 10.0, 5)
    idg, iqg = np.meshgrid(g, g, indexing="ij")
    folder = write_folder(tmp_path / "small", g, g, LD_H * idg + PSI_WB, LQ_H * iqg)
    run = ("run", STEP, "--bus", "direct", "--no-viewer", "--motor", folder)
    bench_cli(*run, "--out", tmp_path / "o1", expect=0)
    trip = json.loads((tmp_path / "o1" / "summary.json").read_text())["plant"]["I_trip_A"]
    assert abs(trip - 10.0 * np.sqrt(3) / 2) < 1e-5, trip  # REAL32 in the OD
    res = bench_cli(*run, "--out", tmp_path / "o2", "--set", "drive.I_trip_A=12")
    assert res.returncode != 0 and not (tmp_path / "o2").exists()
    assert "covers id_A -10 .. 10 A, but with the inverter's trip at 12 A a phase" in res.stderr, res.stderr
    assert "the dq currents reach +-13.86 A" in res.stderr and "drive.I_trip_A <= 8.66 A" in res.stderr
    write_folder(tmp_path / "small2", g, g, LD_H * idg + PSI_WB, LQ_H * iqg, I_trip_A=9.0)
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--no-viewer", "--motor", tmp_path / "small2", "--out", tmp_path / "o3"
    )
    assert res.returncode != 0 and "trip at 9 A a phase" in res.stderr, res.stderr
    half = np.linspace(0.0, 10.0, 3)  # a one-quadrant map, as FEA often gives one
    idh, iqh = np.meshgrid(g, half, indexing="ij")
    write_folder(tmp_path / "half", g, half, LD_H * idh + PSI_WB, LQ_H * iqh)
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--no-viewer", "--motor", tmp_path / "half", "--out", tmp_path / "o4"
    )
    assert res.returncode != 0 and "iq_A 0 .. 10 A: a run's currents take both signs" in res.stderr, res.stderr


def test_the_cli_names_every_example() -> None:
    from bench.cli_motor import EXAMPLE_NAMES
    from bench.motor.example import EXAMPLES

    assert set(EXAMPLE_NAMES) == set(EXAMPLES)


def test_the_ready_sweep_puts_the_identified_L_beside_the_maps_truth(tmp_path: Path) -> None:
    """bench sweep over the step's amplitude on the example motor: each row carries the identified L_hat and the map's
    incremental Lq at the row's own last operating point (as bench/motor/fluxmap.py evaluates the map), and the
    plot draws them together."""
    import pyarrow.parquet as pq

    from bench.motor import load

    out = tmp_path / "sweep"
    args = ("sweep", REPO / "scenarios" / "you2019_saturation.toml", "--motor", EXAMPLE)
    bench_cli(*args, "--grid", "references.iq_ref_A=2,6,10", "--serial", "--out", out, expect=0)
    rows = pq.read_table(out / "sweep.parquet").to_pylist()
    assert [r["references.iq_ref_A"] for r in rows] == ["2", "6", "10"]
    fm = load(EXAMPLE).map
    for r in rows:
        assert r["status"] == "ok"
        lqq = float(fm.eval(0.0, float(r["references.iq_ref_A"]))["Lqq_H"])
        assert abs(r["motor.Lqq_H"] - lqq) < 1e-4 * lqq, r  # the loop holds iq at its reference (REAL32 samples)
        assert 0.5 * lqq < r["identified.L_hat_H"] < 1.2 * lqq, r
    assert rows[-1]["motor.Lqq_H"] < 0.6 * rows[0]["motor.Lqq_H"]  # it saturates over the sweep
    assert (out / "line_inductance.png").stat().st_size > 5000


def test_the_periods_off_the_map_are_counted_and_named(hil_run: HilRunner, tmp_path: Path) -> None:
    """With the trip off (drive.I_trip_A = 0, which asks the map for nothing) a 15 A step leaves a +-10 A map: the
    plant counts the periods that ended off its grid (plant.eds Run control.outside_map_periods), the summary has
    the count and a note naming the extrapolation. The count equals the samples whose dq currents (the trace's)
    are off the grid, within the samples' float32 rounding at the edge; a run on the map counts 0 and says nothing."""
    g = np.linspace(-10.0, 10.0, 5)
    idg, iqg = np.meshgrid(g, g, indexing="ij")
    folder = write_folder(tmp_path / "small", g, g, LD_H * idg + PSI_WB, LQ_H * iqg)
    over = {"drive.I_trip_A": 0.0, "references.iq_ref_A": 15.0}
    run = hil_run(STEP, over, bus="direct", motor=folder, name="off").expect_status("ok")
    n = run.summary["counters"]["plant_outside_map_periods"]
    tr = run.traces
    off = np.maximum(np.abs(tr["id_A"][1:]), np.abs(tr["iq_A"][1:])) - 10.0  # rows 1..: the ends of periods 1..
    assert np.count_nonzero(off > 1e-4) <= n <= np.count_nonzero(off > -1e-4), (n, off.max())
    assert n > 0 and any(f"left the flux map's grid in {n} periods" in note for note in run.summary["notes"])
    inside = hil_run(STEP, {"drive.I_trip_A": 0.0}, bus="direct", motor=folder, name="on").expect_status("ok")
    assert inside.summary["counters"]["plant_outside_map_periods"] == 0
    assert not any("flux map's grid" in note for note in inside.summary.get("notes") or [])
