"""A motor's flux map: psi_d(id, iq) and psi_q(id, iq) on a rectangular grid, as the plant interpolates it
(bilinear in a cell, the edge cell extended beyond the grid: plant_rt/blocks/plant_fluxmap.c), its incremental
inductances, its small-signal values at zero current, the bytes the plant's object 0x2008 "Flux map" takes, and the
checks that make it usable (FluxMapProblem: where and what)."""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

MAX_POINTS = 128  # per axis (plant_fluxmap.h PLANT_FLUXMAP_MAX_POINTS)
BLOB_VERSION = 1


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

    # ------------------------------------------------------------------ the interpolant
    def _cell(self, grid: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(grid, v, side="right") - 1, 0, len(grid) - 2)

    def eval(self, id_A: np.ndarray | float, iq_A: np.ndarray | float) -> dict[str, np.ndarray]:
        """The interpolant at (id, iq) (arrays broadcast): psi_d_Wb, psi_q_Wb and the incremental inductances
        Ldd_H (d psi_d/d id), Ldq_H (d psi_d/d iq), Lqd_H, Lqq_H, as the plant computes them."""
        idv, iqv = np.broadcast_arrays(np.asarray(id_A, float), np.asarray(iq_A, float))
        i, j = self._cell(self.id_A, idv), self._cell(self.iq_A, iqv)
        hd = self.id_A[i + 1] - self.id_A[i]
        hq = self.iq_A[j + 1] - self.iq_A[j]
        u, w = (idv - self.id_A[i]) / hd, (iqv - self.iq_A[j]) / hq
        out: dict[str, np.ndarray] = {}
        for name, t, dn, qn in (
            ("psi_d_Wb", self.psi_d_Wb, "Ldd_H", "Ldq_H"),
            ("psi_q_Wb", self.psi_q_Wb, "Lqd_H", "Lqq_H"),
        ):
            f00, f01, f10, f11 = t[i, j], t[i, j + 1], t[i + 1, j], t[i + 1, j + 1]
            a, b, c = f10 - f00, f01 - f00, f11 - f10 - f01 + f00
            out[name] = f00 + a * u + b * w + c * u * w
            out[dn] = (a + c * w) / hd
            out[qn] = (b + c * u) / hq
        return out

    def small_signal(self) -> tuple[float, float, float]:
        """(Ld_H, Lq_H, psi_Wb) at zero current: what a datasheet would give the drive."""
        e = self.eval(0.0, 0.0)
        return float(e["Ldd_H"]), float(e["Lqq_H"]), float(e["psi_d_Wb"])

    # ------------------------------------------------------------------ checks
    def problems(self) -> list[FluxMapProblem]:
        """Why the plant would refuse this map (plant_flux_map_check), the first few, each at its grid point."""
        out: list[FluxMapProblem] = []
        nd, nq = len(self.id_A), len(self.iq_A)
        for axis, n in (("id_A", nd), ("iq_A", nq)):
            if not 2 <= n <= MAX_POINTS:
                out.append(FluxMapProblem(f"{n} values of {axis}: a map needs 2 .. {MAX_POINTS} per axis"))
        if out:
            return out
        for axis, g in (("id_A", self.id_A), ("iq_A", self.iq_A)):
            bad = np.flatnonzero(~(np.diff(g) > 0))
            if len(bad):
                k = int(bad[0])
                out.append(FluxMapProblem(f"{axis} not strictly increasing: {g[k]:g} then {g[k + 1]:g}"))
        for name, t in (("psi_d_Wb", self.psi_d_Wb), ("psi_q_Wb", self.psi_q_Wb)):
            if t.shape != (nd, nq):
                out.append(FluxMapProblem(f"{name} has shape {t.shape}, the grid needs ({nd}, {nq})"))
            else:
                for i, j in np.argwhere(~np.isfinite(t))[:3]:
                    out.append(FluxMapProblem(f"{name} = {t[i, j]} is not finite", int(i), int(j)))
        return out if out else self._invertibility()

    def _invertibility(self) -> list[FluxMapProblem]:
        """In each cell, at each corner: d psi_d/d id > 0, d psi_q/d iq > 0, det > 0 (the plant's check)."""
        out: list[FluxMapProblem] = []
        pd, pq = self.psi_d_Wb, self.psi_q_Wb
        hd = np.diff(self.id_A)[:, None]
        hq = np.diff(self.iq_A)[None, :]
        checks = (
            ("psi_d_Wb does not rise with id_A", np.diff(pd, axis=0) / hd, 1, 0),
            ("psi_q_Wb does not rise with iq_A", np.diff(pq, axis=1) / hq, 0, 1),
        )
        for what, slope, di, dj in checks:
            for i, j in np.argwhere(~(slope > 0))[:3]:
                nxt = (int(i + di), int(j + dj))
                t = pd if di else pq
                out.append(
                    FluxMapProblem(f"{what}: {t[i, j]:.6g}, then {t[nxt]:.6g} at the next point", int(i), int(j), nxt)
                )
        if out:
            return out
        # det of the Jacobian at the four corners of each cell
        ldd, ldq = np.diff(pd, axis=0) / hd, np.diff(pd, axis=1) / hq  # (nd-1, nq), (nd, nq-1)
        lqd, lqq = np.diff(pq, axis=0) / hd, np.diff(pq, axis=1) / hq
        for ci, cj in ((0, 0), (0, 1), (1, 0), (1, 1)):
            det = ldd[:, cj : cj + ldd.shape[1] - 1] * lqq[ci : ci + lqq.shape[0] - 1, :] - (
                ldq[ci : ci + ldq.shape[0] - 1, :] * lqd[:, cj : cj + lqd.shape[1] - 1]
            )
            for i, j in np.argwhere(~(det > 0))[:3]:
                out.append(
                    FluxMapProblem(
                        f"the map cannot be inverted (the current is not found from the flux): the Jacobian's "
                        f"determinant is {det[i, j]:.3g} H^2 in the cell from ({self.id_A[i]:g}, {self.iq_A[j]:g}) A",
                        int(i + ci),
                        int(j + cj),
                    )
                )
        return out

    # ------------------------------------------------------------------ the object's bytes
    def blob(self) -> bytes:
        """0x2008 "Flux map" (plant.eds): FMAP, version, n_d, n_q, then REAL64 grids and tables, little-endian."""
        head = b"FMAP" + struct.pack("<III", BLOB_VERSION, len(self.id_A), len(self.iq_A))
        body = np.concatenate([self.id_A, self.iq_A, self.psi_d_Wb.ravel(), self.psi_q_Wb.ravel()])
        return head + body.astype("<f8").tobytes()

    @classmethod
    def from_blob(cls, data: bytes) -> FluxMap:
        if data[:4] != b"FMAP":
            raise ValueError("not a flux map (no FMAP header)")
        _, nd, nq = struct.unpack("<III", data[4:16])
        v = np.frombuffer(data[16:], "<f8")
        return cls(
            v[:nd].copy(),
            v[nd : nd + nq].copy(),
            v[nd + nq : nd + nq + nd * nq].reshape(nd, nq).copy(),
            v[nd + nq + nd * nq :].reshape(nd, nq).copy(),
        )
