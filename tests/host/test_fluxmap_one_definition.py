"""The flux map written once (issue 53 item 2): bench/motor/fluxmap.py's FluxMap evaluates, checks, writes and reads a
map with the plant's own C through libhil.so (bench/direct/hil_fluxmap.c). Its eval is the plant's
plant_flux_map_eval bit for bit (called here on its own, through the symbol libhil.so exports); its blob() is what the
plant node's parser (plant_fluxmap_obj_accept) reads back; its problems() refuses a map exactly when the plant's
check and the node's download do, a map that a copy's own arithmetic would pass among them; nothing is loaded at
import, and a missing library is named."""

from __future__ import annotations

import ctypes
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from bench.motor import fluxmap_c
from bench.motor.example import example_map
from bench.motor.fluxmap import MAX_POINTS, FluxMap, FluxMapBytesError
from bench.paths import BUILD

LD, LQ, PSI = 4.46e-3, 4.54e-3, 0.042
NOT_A_MAP, TOO_SHORT = 0x06090030, 0x06070013  # CiA 301 abort codes (plant.eds 0x2008)


class _Map(ctypes.Structure):
    """plant_flux_map_t (plant_rt/blocks/plant_fluxmap.h)."""

    _fields_ = [("n_d", ctypes.c_uint32), ("n_q", ctypes.c_uint32)] + [
        (n, ctypes.POINTER(ctypes.c_double)) for n in ("id_A", "iq_A", "psi_d_Wb", "psi_q_Wb")
    ]


class _Eval(ctypes.Structure):
    """plant_flux_eval_t."""

    _fields_ = [(n, ctypes.c_double) for n in ("psi_d_Wb", "psi_q_Wb", "Ldd_H", "Ldq_H", "Lqd_H", "Lqq_H")]


def _linear(grid: np.ndarray) -> FluxMap:
    idg, iqg = np.meshgrid(grid, grid, indexing="ij")
    return FluxMap(grid.copy(), grid.copy(), LD * idg + PSI, LQ * iqg)


def _plant_eval(fm: FluxMap, id_A: np.ndarray, iq_A: np.ndarray) -> dict[str, np.ndarray]:
    """plant_flux_map_eval itself, one point a call."""
    lib = fluxmap_c.lib()
    lib.plant_flux_map_eval.argtypes = [ctypes.POINTER(_Map), ctypes.c_double, ctypes.c_double, ctypes.POINTER(_Eval)]
    arrays = [np.ascontiguousarray(a, np.float64) for a in fm.tables]
    ptrs = [a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in arrays]
    m = _Map(len(arrays[0]), len(arrays[1]), *ptrs)
    out: dict[str, list[float]] = {n: [] for n, _ in _Eval._fields_}
    e = _Eval()
    for a, b in zip(id_A, iq_A, strict=True):
        lib.plant_flux_map_eval(ctypes.byref(m), float(a), float(b), ctypes.byref(e))
        for n in out:
            out[n].append(getattr(e, n))
    return {n: np.array(v) for n, v in out.items()}


def test_eval_is_the_plants_interpolant_bit_for_bit() -> None:
    fm = example_map()
    rng = np.random.default_rng(53)
    lo, hi = fm.id_A[0], fm.id_A[-1]
    pts_d = np.concatenate([rng.uniform(1.3 * lo, 1.3 * hi, 400), fm.id_A, [lo - 1.0, hi + 1.0, 0.0]])
    pts_q = np.concatenate([rng.uniform(1.3 * lo, 1.3 * hi, 400), fm.iq_A[::-1], [hi + 1.0, lo - 1.0, 0.0]])
    got, want = fm.eval(pts_d, pts_q), _plant_eval(fm, pts_d, pts_q)
    assert set(got) == set(want)
    for name in want:  # the same doubles, NaN-free
        assert got[name].tobytes() == want[name].tobytes(), name
    # shapes broadcast as numpy's: a scalar gives 0-d arrays, a grid its shape
    assert fm.eval(0.0, 0.0)["Ldd_H"].shape == ()
    idg, iqg = np.meshgrid(fm.id_A[:5], fm.iq_A[:3], indexing="ij")
    assert fm.eval(idg, iqg)["psi_q_Wb"].shape == (5, 3)


def test_eval_of_a_tabulated_linear_motor_is_the_linear_motor() -> None:
    """An independent calculation: a linear map's interpolant is the linear model, inside the grid and beyond it."""
    fm = _linear(np.linspace(-20.0, 20.0, 9))
    rng = np.random.default_rng(7)
    d, q = rng.uniform(-30.0, 30.0, 200), rng.uniform(-30.0, 30.0, 200)
    e = fm.eval(d, q)
    np.testing.assert_allclose(e["psi_d_Wb"], LD * d + PSI, rtol=0, atol=1e-15)
    np.testing.assert_allclose(e["psi_q_Wb"], LQ * q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(e["Ldd_H"], LD, rtol=1e-12)
    np.testing.assert_allclose(e["Lqq_H"], LQ, rtol=1e-12)
    np.testing.assert_allclose(np.abs(np.r_[e["Ldq_H"], e["Lqd_H"]]), 0.0, atol=1e-15)
    assert fm.small_signal() == pytest.approx((LD, LQ, PSI), rel=1e-12)


def test_blob_round_trips_through_the_plant_nodes_layout() -> None:
    for fm in (example_map(), _linear(np.array([-3.0, 0.5, 4.0]))):
        data = fm.blob()
        magic, version, nd, nq = struct.unpack_from("<4sIII", data)  # plant.eds 0x2008's layout, read here
        assert (magic, version, nd, nq) == (b"FMAP", 1, len(fm.id_A), len(fm.iq_A))
        assert len(data) == 16 + 8 * (nd + nq + 2 * nd * nq)
        assert np.frombuffer(data, "<f8", count=nd, offset=16).tobytes() == fm.id_A.astype("<f8").tobytes()
        back = FluxMap.from_blob(data)  # the node's parser and check
        for a, b in zip(back.tables, fm.tables, strict=True):
            assert a.shape == b.shape and a.tobytes() == np.asarray(b, np.float64).tobytes()
        assert back.blob() == data
    with pytest.raises(FluxMapBytesError) as cut:
        FluxMap.from_blob(example_map().blob()[:-8])
    assert cut.value.code == TOO_SHORT


def _edit(change: Callable[[FluxMap], FluxMap]) -> FluxMap:
    return change(_linear(np.linspace(-8.0, 8.0, 5)))


def _with(fm: FluxMap, table: str, i: int, j: int, value: float) -> FluxMap:
    tables = {"psi_d_Wb": fm.psi_d_Wb.copy(), "psi_q_Wb": fm.psi_q_Wb.copy()}
    tables[table][i, j] = value
    return FluxMap(fm.id_A, fm.iq_A, tables["psi_d_Wb"], tables["psi_q_Wb"])


def _rounding_edge() -> FluxMap:
    """psi_d rises along the upper edge of the cell (f11 - f01 = 1e-300 > 0, what a copy taking that difference sees)
    but the plant's bilinear form takes the slope there as a + c = 2 + (-2) = 0: the plant refuses it."""
    g = np.array([0.0, 1.0])
    pd = np.array([[1e16, 0.0], [1e16 + 2.0, 1e-300]])
    pq = np.array([[0.0, 1.0], [0.0, 1.0]])
    return FluxMap(g, g, pd, pq)


BAD = {
    "psi_d falls along id": lambda: _edit(lambda m: _with(m, "psi_d_Wb", 2, 3, -0.5)),
    "psi_q falls along iq": lambda: _edit(lambda m: _with(m, "psi_q_Wb", 1, 2, 0.9)),
    "not finite": lambda: _edit(lambda m: _with(m, "psi_q_Wb", 4, 0, float("nan"))),
    "grid not increasing": lambda: _edit(lambda m: FluxMap(m.id_A[[0, 2, 1, 3, 4]], m.iq_A, m.psi_d_Wb, m.psi_q_Wb)),
    "cross-coupled: det < 0": lambda: _edit(
        lambda m: FluxMap(m.id_A, m.iq_A, m.psi_d_Wb + 0.01 * m.iq_A[None, :], m.psi_q_Wb + 0.01 * m.id_A[:, None])
    ),
    "a slope of 0 by rounding": _rounding_edge,
}


@pytest.mark.parametrize("name", list(BAD))
def test_problems_refuses_exactly_what_the_plant_refuses(name: str) -> None:
    fm = BAD[name]()
    problems = fm.problems()
    assert problems, name
    assert fluxmap_c.check(fm.tables) != 0
    with pytest.raises(FluxMapBytesError) as node:  # the plant node's answer to the download
        FluxMap.from_blob(fm.blob())
    assert node.value.code == NOT_A_MAP
    if name == "a slope of 0 by rounding":
        assert fm.psi_d_Wb[1, 1] - fm.psi_d_Wb[0, 1] > 0  # the difference a copy would take passes
        assert "psi_d_Wb does not rise with id_A" in problems[0].what
    if name == "cross-coupled: det < 0":
        assert all("cannot be inverted" in p.what and p.i is not None for p in problems)


@pytest.mark.parametrize("fm", [example_map(), _linear(np.linspace(-8.0, 8.0, 5))], ids=["example", "linear"])
def test_a_good_map_passes_everywhere(fm: FluxMap) -> None:
    assert fm.problems() == [] and fluxmap_c.check(fm.tables) == 0
    assert not fluxmap_c.bad_cells(fm.tables).any()
    FluxMap.from_blob(fm.blob())


def test_the_grid_limit_is_the_plants() -> None:
    assert MAX_POINTS == fluxmap_c.max_points()
    g = np.linspace(-1.0, 1.0, MAX_POINTS + 1)
    big = FluxMap(g, g[:2], np.zeros((len(g), 2)), np.zeros((len(g), 2)))
    assert "a map needs 2 .. 128 per axis" in big.problems()[0].what


def test_nothing_is_loaded_at_import_and_a_missing_library_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    code = (
        "import bench.cli, bench.motor, bench.motor.folder, bench.motor.trip\n"
        "maps = open('/proc/self/maps').read()\n"
        "assert 'libhil.so' not in maps, 'loaded at import'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=Path(__file__).resolve().parents[2])
    fluxmap_c.lib.cache_clear()
    monkeypatch.setattr(fluxmap_c, "BUILD", BUILD / "no-such-build")
    try:
        with pytest.raises(FileNotFoundError, match=r"no-such-build/libhil\.so is missing.*make"):
            example_map().small_signal()
    finally:
        monkeypatch.undo()
        fluxmap_c.lib.cache_clear()
