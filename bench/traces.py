"""Decode recorded frames into per-period traces (numpy), from the PDO layout of the run.

Alignment (CiA 301 synchronous semantics, docs/ARCHITECTURE.md): the k-th SYNC starts
period k; the plant's measurement TPDOs after it carry the sample i(k); the drive's
command TPDO that follows is v*(k); the drive's synchronous trace TPDOs sent at SYNC k
carry its state after step k-1.

Stored as `traces.npz` (numpy's columnar archive: one 1-D array per signal, all of
length `periods`, NaN where a frame was missing). Column names carry SI units.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .layout import BusLayout

SQRT3 = math.sqrt(3.0)


def _pdo_values(frames: np.ndarray, cob_id: int, dtype: np.dtype) -> tuple[np.ndarray, np.ndarray]:
    """(frame positions, structured values) of every frame with this COB-ID."""
    idx = np.nonzero(frames["cob_id"] == cob_id)[0]
    raw = np.ascontiguousarray(frames["data"][idx][:, : dtype.itemsize])
    return idx, raw.view(dtype).reshape(-1)


def decode(frames: np.ndarray, layout: BusLayout, pole_pairs: int, ts_s: float,
           references: list[tuple[int, str, float]] | None = None) -> dict[str, np.ndarray]:
    sync_mask = frames["cob_id"] == layout.sync_cob_id
    period_of = np.cumsum(sync_mask) - 1  # period index of every frame
    n = int(sync_mask.sum())
    out: dict[str, np.ndarray] = {"period": np.arange(n, dtype=np.int64), "t_s": np.arange(n) * ts_s}
    sync_data = frames["data"][sync_mask][:, 0].astype(np.int64)
    out["sync_counter"] = np.where(frames["dlc"][sync_mask] > 0, sync_data, -1)
    short = {"Measurement": "", "Voltage command": "", "Online tuning": "", "Plant state": "true_", "Drive status": "drive_",
             "Live trace": "live_"}
    for pdo in layout.pdos:
        pos, vals = _pdo_values(frames, pdo.cob_id, pdo.numpy_dtype())
        per = period_of[pos]
        if pdo.node == "drive" and pdo.trans_type <= 240:
            per = per - 1  # synchronous drive TPDO at SYNC k: state after step k-1
        ok = (per >= 0) & (per < n)
        for name, _ in pdo.signals:
            obj, _, sub = name.partition(".")
            col = short.get(obj, obj.replace(" ", "_") + "_") + sub
            arr = np.full(n, np.nan)
            arr[per[ok]] = vals[name][ok].astype(np.float64)
            out[col] = arr
    if "i_a_A" in out and "theta_m_rad" in out:
        ia, ib = out["i_a_A"], out["i_b_A"]
        i_alpha, i_beta = ia, (ia + 2.0 * ib) / SQRT3
        th = pole_pairs * out["theta_m_rad"]
        c, s = np.cos(th), np.sin(th)
        out["id_A"] = c * i_alpha + s * i_beta
        out["iq_A"] = -s * i_alpha + c * i_beta
        if "v_alpha_V" in out:
            va, vb = out["v_alpha_V"], out["v_beta_V"]
            out["vd_V"] = c * va + s * vb
            out["vq_V"] = -s * va + c * vb
    for name in ("iq_ref_A", "id_ref_A"):
        ref = np.zeros(n)
        for period, which, value in sorted(references or []):
            if which == name and period < n:
                ref[period:] = value
        out[name] = ref
    return out


def check_continuity(tr: dict[str, np.ndarray]) -> dict[str, int]:
    """Lost frames seen from the SYNC counters and the sample indices."""
    n = len(tr["period"])
    res = {"periods": n, "sync_counter_gaps": 0, "missing_measurements": 0, "missing_commands": 0,
           "sample_index_mismatches": 0}
    sc = tr["sync_counter"]
    if n > 1 and (sc >= 0).all():
        expect = np.where(sc[:-1] >= 240, 1, sc[:-1] + 1)
        res["sync_counter_gaps"] = int((sc[1:] != expect).sum())
    if "sample_index" in tr:
        si = tr["sample_index"]
        res["missing_measurements"] = int(np.isnan(si).sum())
        good = ~np.isnan(si)
        res["sample_index_mismatches"] = int((si[good] != (tr["period"][good] % 65536)).sum())
    if "v_alpha_V" in tr:
        res["missing_commands"] = int(np.isnan(tr["v_alpha_V"]).sum())
    return res


def save(path: Path, tr: dict[str, np.ndarray]) -> None:
    np.savez_compressed(path, **tr)


def load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def references_from_sdo(frames: np.ndarray, drive_id: int, refs_index: int, subs: dict[int, str],
                        sync_cob_id: int) -> list[tuple[int, str, float]]:
    """Reference changes recovered from the SDO downloads to the drive seen on the bus
    (expedited, REAL32): the bench sets references between periods in lockstep, so the
    number of SYNCs before the request is the period it takes effect."""
    sdo = frames["cob_id"] == 0x600 + drive_id
    if not sdo.any():
        return []
    sync_count = np.cumsum(frames["cob_id"] == sync_cob_id)
    out = []
    for i in np.nonzero(sdo)[0]:
        d = bytes(frames["data"][i][: frames["dlc"][i]])
        if len(d) != 8 or d[0] != 0x23:
            continue
        index = d[1] | (d[2] << 8)
        if index != refs_index or d[3] not in subs:
            continue
        value = float(np.frombuffer(d[4:8], dtype="<f4")[0])
        out.append((int(sync_count[i]), subs[d[3]], value))
    return out
