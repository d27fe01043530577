"""A motor's flux map: psi_d(id, iq) and psi_q(id, iq) on a rectangular grid, its interpolant (bilinear in a cell, the
edge cell extended beyond the grid) and incremental inductances, its small-signal values at zero current, the bytes
the plant's object 0x2008 "Flux map" takes, and the checks that make it usable (FluxMapProblem: where and what).

One definition: the arithmetic is the plant's own C (plant_rt/blocks/plant_fluxmap.c, plant_rt/node/
plant_fluxmap_obj.c), called through libhil.so (bench/motor/fluxmap_c.py); this module shapes arrays and words
messages. The plant's check decides whether a map is refused; problems() then names the grid points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.motor.fluxmap_c import (
    EVAL_NAMES,
    FluxMapBytesError,
    Tables,
    bad_cells,
    check,
    corners,
    evaluate,
    from_bytes,
    to_bytes,
)

MAX_POINTS = 128  # per axis: PLANT_FLUXMAP_MAX_POINTS (tests/host/test_fluxmap_one_definition.py checks it)
SHOWN = 3  # problems of a kind named at most
__all__ = ["MAX_POINTS", "FluxMap", "FluxMapBytesError", "FluxMapProblem"]


@dataclass(frozen=True)
class FluxMapProblem:
    """What is wrong with a map, at which grid point (indices into the grids), for the folder to name its row."""

    what: str
    i: int | None = None  # id index
    j: int | None = None  # iq index
    other: tuple[int, int] | None = None  # the grid point it is compared with


@dataclass(frozen=True)
class FluxMap:
    id_A: np.ndarray  # (n_d,) strictly increasing
    iq_A: np.ndarray  # (n_q,)
    psi_d_Wb: np.ndarray  # (n_d, n_q): [i, j] at (id_A[i], iq_A[j])
    psi_q_Wb: np.ndarray

    @property
    def tables(self) -> Tables:
        return self.id_A, self.iq_A, self.psi_d_Wb, self.psi_q_Wb

    # ------------------------------------------------------------------ the interpolant
    def eval(self, id_A: np.ndarray | float, iq_A: np.ndarray | float) -> dict[str, np.ndarray]:
        """The interpolant at (id, iq) (arrays broadcast): psi_d_Wb, psi_q_Wb and the incremental inductances
        Ldd_H (d psi_d/d id), Ldq_H (d psi_d/d iq), Lqd_H, Lqq_H: plant_flux_map_eval's values."""
        idv, iqv = np.broadcast_arrays(np.asarray(id_A, float), np.asarray(iq_A, float))
        out = evaluate(self.tables, idv.ravel(), iqv.ravel())
        return {name: out[:, k].reshape(idv.shape) for k, name in enumerate(EVAL_NAMES)}

    def small_signal(self) -> tuple[float, float, float]:
        """(Ld_H, Lq_H, psi_Wb) at zero current: what a datasheet would give the drive."""
        e = self.eval(0.0, 0.0)
        return float(e["Ldd_H"]), float(e["Lqq_H"]), float(e["psi_d_Wb"])

    # ------------------------------------------------------------------ checks
    def problems(self) -> list[FluxMapProblem]:
        """Why the plant would refuse this map (plant_flux_map_check decides), the first few, each at its grid
        point."""
        out = self._shape()
        if out:
            return out
        code = check(self.tables)
        if code == 0:
            return []
        found = {2: self._not_finite, 3: self._grid_order, 4: self._invertibility}.get(code, list)()
        return found or [FluxMapProblem(f"the plant's check refuses the map (plant_flux_map_check: {code})")]

    def _shape(self) -> list[FluxMapProblem]:
        """Sizes and shapes (before any table goes to the C, which takes them as given)."""
        out: list[FluxMapProblem] = []
        nd, nq = len(self.id_A), len(self.iq_A)
        for axis, g in (("id_A", self.id_A), ("iq_A", self.iq_A)):
            if np.ndim(g) != 1 or not 2 <= len(g) <= MAX_POINTS:
                out.append(FluxMapProblem(f"{len(g)} values of {axis}: a map needs 2 .. {MAX_POINTS} per axis"))
        if out:
            return out
        for name, t in (("psi_d_Wb", self.psi_d_Wb), ("psi_q_Wb", self.psi_q_Wb)):
            if np.shape(t) != (nd, nq):
                out.append(FluxMapProblem(f"{name} has shape {np.shape(t)}, the grid needs ({nd}, {nq})"))
        return out

    def _not_finite(self) -> list[FluxMapProblem]:
        out = [
            FluxMapProblem(f"{axis}[{k}] = {g[k]} is not finite")
            for axis, g in (("id_A", self.id_A), ("iq_A", self.iq_A))
            for k in np.flatnonzero(~np.isfinite(g))[:SHOWN]
        ]
        for name, t in (("psi_d_Wb", self.psi_d_Wb), ("psi_q_Wb", self.psi_q_Wb)):
            for i, j in np.argwhere(~np.isfinite(t))[:SHOWN]:
                out.append(FluxMapProblem(f"{name} = {t[i, j]} is not finite", int(i), int(j)))
        return out

    def _grid_order(self) -> list[FluxMapProblem]:
        out = []
        for axis, g in (("id_A", self.id_A), ("iq_A", self.iq_A)):
            k = next((k for k in range(len(g) - 1) if not g[k + 1] > g[k]), None)
            if k is not None:
                out.append(FluxMapProblem(f"{axis} not strictly increasing: {g[k]:g} then {g[k + 1]:g}"))
        return out

    def _invertibility(self) -> list[FluxMapProblem]:
        """The cells the plant's check refuses (each checked as a map of its own), named by what fails at their
        corners (the plant's values there): d psi_d/d id > 0 and d psi_q/d iq > 0 along each edge, else the
        Jacobian's determinant > 0."""
        d_edges: set[tuple[int, int]] = set()
        q_edges: set[tuple[int, int]] = set()
        dets: dict[int, list[tuple[int, int, float]]] = {}
        for i, j in np.argwhere(bad_cells(self.tables) != 0):
            i, j = int(i), int(j)
            for c, (_, _, ldd, ldq, lqd, lqq) in enumerate(corners(self.tables, i, j)):
                u, w = c & 1, c >> 1
                if not ldd > 0:
                    d_edges.add((i, j + w))
                if not lqq > 0:
                    q_edges.add((i + u, j))
                if ldd > 0 and lqq > 0:
                    dets.setdefault(2 * u + w, []).append((i, j, ldd * lqq - ldq * lqd))
        out = self._edges(d_edges, self.psi_d_Wb, "psi_d_Wb does not rise with id_A", (1, 0))
        out += self._edges(q_edges, self.psi_q_Wb, "psi_q_Wb does not rise with iq_A", (0, 1))
        if out:
            return out
        for corner in sorted(dets):
            for i, j, det in dets[corner][:SHOWN]:
                out.append(
                    FluxMapProblem(
                        f"the map cannot be inverted (the current is not found from the flux): the Jacobian's "
                        f"determinant is {det:.3g} H^2 in the cell from ({self.id_A[i]:g}, {self.iq_A[j]:g}) A",
                        i + corner // 2,
                        j + corner % 2,
                    )
                )
        return out

    @staticmethod
    def _edges(edges: set[tuple[int, int]], t: np.ndarray, what: str, step: tuple[int, int]) -> list[FluxMapProblem]:
        out = []
        for i, j in sorted(edges)[:SHOWN]:
            nxt = (i + step[0], j + step[1])
            out.append(FluxMapProblem(f"{what}: {t[i, j]:.6g}, then {t[nxt]:.6g} at the next point", i, j, nxt))
        return out

    # ------------------------------------------------------------------ the object's bytes
    def blob(self) -> bytes:
        """0x2008 "Flux map" (plant.eds): the bytes of a download, written by hil_fluxmap_blob."""
        return to_bytes(self.tables)

    @classmethod
    def from_blob(cls, data: bytes) -> FluxMap:
        """The map in a download's bytes, read as the plant node reads it (FluxMapBytesError if it refuses them)."""
        return cls(*from_bytes(data))
