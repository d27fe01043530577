"""The plant's own flux-map code, called through libhil.so (bench/direct/hil_fluxmap.c over
plant_rt/blocks/plant_fluxmap.c and plant_rt/node/plant_fluxmap_obj.c): the interpolant and its incremental
inductances, the check, and the bytes of object 0x2008. bench/motor/fluxmap.py's FluxMap is the Python face of it;
nothing here computes a flux linkage itself. The library is opened on the first call, not at import (`bench --help`,
a motor folder's description need no build)."""

from __future__ import annotations

import ctypes
import functools
import threading

import numpy as np

from bench.paths import BUILD, MISSING_BUILD

Tables = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # id_A (n_d,), iq_A (n_q,), psi_d, psi_q (n_d, n_q)
EVAL_NAMES = ("psi_d_Wb", "psi_q_Wb", "Ldd_H", "Ldq_H", "Lqd_H", "Lqq_H")  # hil_fluxmap_eval's columns

_D = ctypes.POINTER(ctypes.c_double)
_U32 = ctypes.c_uint32
_MAP = [_U32, _U32, _D, _D, _D, _D]
_READ = threading.Lock()  # the node's parser keeps a static scratch (hil_fluxmap_read)


class FluxMapBytesError(ValueError):
    """Bytes the plant's object 0x2008 refuses: `code` is the SDO abort code it answers a download of them with."""

    def __init__(self, code: int) -> None:
        super().__init__(f"not a flux map the plant accepts (its download is aborted with 0x{code:08X})")
        self.code = code


@functools.cache
def lib() -> ctypes.CDLL:
    """libhil.so with the flux map's functions typed, once per process."""
    path = BUILD / "libhil.so"
    if not path.exists():
        raise FileNotFoundError(
            f"{path} is missing (a flux map is evaluated, checked and written by the plant's code in it): "
            f"{MISSING_BUILD}"
        )
    so = ctypes.CDLL(str(path))
    so.hil_fluxmap_max_points.restype = _U32
    so.hil_fluxmap_check.argtypes = _MAP
    so.hil_fluxmap_check.restype = ctypes.c_int32
    so.hil_fluxmap_eval.argtypes = [*_MAP, _D, _D, _U32, _D]
    so.hil_fluxmap_eval.restype = None
    so.hil_fluxmap_cells.argtypes = [*_MAP, ctypes.POINTER(ctypes.c_uint8)]
    so.hil_fluxmap_cells.restype = ctypes.c_int32
    so.hil_fluxmap_corners.argtypes = [_U32, _D, _D, _D, _D, _U32, _U32, _D]
    so.hil_fluxmap_corners.restype = None
    so.hil_fluxmap_blob_bytes.argtypes = [_U32, _U32]
    so.hil_fluxmap_blob_bytes.restype = _U32
    so.hil_fluxmap_blob.argtypes = [*_MAP, ctypes.c_char_p, _U32]
    so.hil_fluxmap_blob.restype = _U32
    so.hil_fluxmap_read.argtypes = [ctypes.c_char_p, _U32, ctypes.POINTER(_U32), ctypes.POINTER(_U32), _D, _U32]
    so.hil_fluxmap_read.restype = _U32
    return so


def _doubles(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _ptr(a: np.ndarray) -> ctypes._Pointer[ctypes.c_double]:
    return a.ctypes.data_as(_D)


def _map_args(t: Tables) -> tuple[list[object], list[np.ndarray]]:
    """hil_fluxmap_*'s map arguments and the arrays they point into (kept alive for the call)."""
    arrays = [_doubles(a) for a in t]
    return [len(arrays[0]), len(arrays[1]), *map(_ptr, arrays)], arrays


def max_points() -> int:
    """PLANT_FLUXMAP_MAX_POINTS: the grid points per axis the plant takes."""
    return int(lib().hil_fluxmap_max_points())


def check(t: Tables) -> int:
    """plant_flux_map_check: 0, or the first failing check (1 sizes, 2 not finite, 3 grid order, 4 not invertible).
    The tables' shapes must be consistent (FluxMap.problems checks them first)."""
    args, _keep = _map_args(t)
    return int(lib().hil_fluxmap_check(*args))


def evaluate(t: Tables, id_A: np.ndarray, iq_A: np.ndarray) -> np.ndarray:
    """plant_flux_map_eval at each point of the flat arrays: (n, 6), the columns EVAL_NAMES."""
    args, _keep = _map_args(t)
    idv, iqv = _doubles(id_A), _doubles(iq_A)
    out = np.empty((len(idv), len(EVAL_NAMES)))
    lib().hil_fluxmap_eval(*args, _ptr(idv), _ptr(iqv), len(idv), _ptr(out))
    return out


def bad_cells(t: Tables) -> np.ndarray:
    """plant_flux_map_check of every cell as a map of its own: (n_d - 1, n_q - 1) codes, 0 where the cell is usable."""
    args, _keep = _map_args(t)
    codes = np.zeros((len(t[0]) - 1, len(t[1]) - 1), np.uint8)
    lib().hil_fluxmap_cells(*args, codes.ctypes.data_as(ctypes.POINTER(ctypes.c_uint8)))
    return codes


def corners(t: Tables, i: int, j: int) -> np.ndarray:
    """The interpolant at the four corners of cell (i, j) as the check sees them: (4, 6), the columns EVAL_NAMES,
    corner c at (id_A[i + (c & 1)], iq_A[j + (c >> 1)])."""
    args, _keep = _map_args(t)
    out = np.empty((4, len(EVAL_NAMES)))
    lib().hil_fluxmap_corners(args[1], *args[2:], i, j, _ptr(out))
    return out


def to_bytes(t: Tables) -> bytes:
    """The bytes of a download of the map to 0x2008 (any values: a map the plant refuses too)."""
    args, _keep = _map_args(t)
    size = int(lib().hil_fluxmap_blob_bytes(args[0], args[1]))
    buf = ctypes.create_string_buffer(size)
    written = int(lib().hil_fluxmap_blob(*args, buf, size))
    if written != size:
        raise ValueError(f"{args[0]} x {args[1]} grid points: a flux map takes 2 .. {max_points()} per axis")
    return buf.raw


def from_bytes(data: bytes) -> Tables:
    """The map in bytes, as the plant node reads a download (its parser and its check); FluxMapBytesError with the
    node's abort code when it refuses them."""
    n = max_points()
    words = np.empty(2 * n + 2 * n * n)
    nd, nq = _U32(), _U32()
    with _READ:
        code = int(lib().hil_fluxmap_read(data, len(data), ctypes.byref(nd), ctypes.byref(nq), _ptr(words), len(words)))
    if code:
        raise FluxMapBytesError(code)
    d, q = nd.value, nq.value
    tab = d * q
    v = words[: d + q + 2 * tab].copy()
    return v[:d], v[d : d + q], v[d + q : d + q + tab].reshape(d, q), v[d + q + tab :].reshape(d, q)
