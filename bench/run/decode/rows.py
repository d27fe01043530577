"""The trace rows of periods [r0, r1) from a buffer of frames whose periods the decoder has counted.

HIL profile (the project's plant and drive): the plant's measurement TPDOs after SYNC k are row k; the
drive's command is row k; its synchronous trace TPDOs sent at SYNC k carry its state after step k-1: row k-1.
One frame of each PDO per period: a second one is interference, a lost SYNC, a late command or the drive's
safe-state command (each told apart below). CiA 402 profile (the bench as the master of a drive, no plant, no
lockstep): the drive's TPDOs after SYNC k are row k (a synchronous one samples at its SYNC); the RPDO the master
sent before SYNC k takes effect at it: row k; the master's RPDO task is not phase-locked to its SYNC task, so
the last frame of a row is its value. Row k's time is then its SYNC's, from the first SYNC (no Ts on the bus).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.eds import bits
from bench.run.bus.frames import fd_len
from bench.run.decode.coding import decode_codes
from bench.run.decode.counts import DecodeStats, PdoStats
from bench.run.decode.layout import BusLayout, PdoLayout
from bench.run.decode.sdo_log import SdoLog
from bench.run.decode.syncs import PeriodMark
from bench.signals import column_name

SQRT3 = math.sqrt(3.0)
REFERENCES = ("iq_ref_A", "id_ref_A")
# Measurement.status: the period before this sample ended without its command (plant.eds BitNames)
PLANT_STATUS_MISSED = bits("plant", "Measurement", "status")["missed"]


@dataclass
class Where:
    """Plant fields the HIL rows check, as (COB-ID, byte offset) in its PDOs (None: not mapped)."""

    sample_index: tuple[int, int] | None = None  # Measurement.sample_index
    status: tuple[int, int] | None = None  # Measurement.status


@dataclass
class Late:
    """What the HIL rows of one call allow after the SYNC a frame was meant for."""

    realtime: bool  # Run control.mode: a command may be late in any period
    # the periods whose sample says the period before ended without its command (lockstep with a command timeout:
    # where a late command may come; real time: where the drive was late, with its trace TPDOs)
    late_ok: np.ndarray | None
    misaligned: np.ndarray  # periods holding a measurement of the next period's sample (a SYNC lost)


class Rows:
    """Rows of the frozen layout's PDOs; keeps the SYNC counter's last value across calls (continuity)."""

    def __init__(
        self,
        layout: BusLayout,
        sdo: SdoLog,
        stats: DecodeStats,
        hil: bool,
        where: Where,
        ts_s: float = 1.0,
        pole_pairs: int = 1,
        t0_us: int = 0,
    ) -> None:
        """hil: the HIL profile (else CiA 402); ts_s, pole_pairs: the plant's (HIL); t0_us: the first SYNC's time."""
        self.layout, self.sdo, self.stats, self.hil, self.where = layout, sdo, stats, hil, where
        self.ts_s, self.pole_pairs, self.t0_us = ts_s, pole_pairs, t0_us
        self._last_sync = -1
        self._last_sync_period = -1
        self.coding: tuple[float, int] | None = None  # the compact frame's (current_lsb_A, angle_counts)
        self.mark = PeriodMark(layout.sync_cob_id)  # what starts a period (the decoder's, when it froze the layout)

    def shift(self, pdo: PdoLayout) -> int:
        """Row of a frame minus the period it was sent in (see the module's docstring)."""
        if self.hil:
            return -1 if self.behind(pdo) else 0
        return 1 if pdo.received else 0

    def behind(self, pdo: PdoLayout) -> bool:
        """A drive TPDO that carries the step before: a synchronous one (at SYNC k + 1), and without SYNC frames an
        event-driven trace (the drive sends it when the next measurement arrives, before its step: drive_app.c)."""
        if pdo.node != "drive":
            return False
        commands = any(q.startswith("Voltage command.") for q, _ in pdo.signals)
        return pdo.trans_type <= 240 or (not self.mark.is_sync and not commands)

    def make(
        self, buf: np.ndarray, period_of: np.ndarray, is_sync: np.ndarray, r0: int, r1: int
    ) -> dict[str, np.ndarray]:
        n = r1 - r0
        st = self.stats
        out: dict[str, np.ndarray] = {"period": np.arange(r0, r1, dtype=np.int64)}
        counter, t_us = self._syncs(buf, period_of, is_sync, r0, r1)
        out["t_s"] = out["period"] * self.ts_s if self.hil else (t_us - float(self.t0_us)) / 1e6
        out["sync_counter"] = counter
        cob = np.ascontiguousarray(buf["cob_id"])
        late = self._late(buf, period_of, r0, r1) if self.hil else None
        miss_meas = np.zeros(n, dtype=bool)
        miss_cmd = np.zeros(n, dtype=bool)
        # real time: each period's SYNC and command time stamps (bench/run/verdict/realtime.py), not trace signals
        timed = late is not None and late.realtime
        if timed:
            out["sync_t_us"], out["command_t_us"] = t_us, np.full(n, np.nan)
        for cob_id, ps in st.pdos.items():
            pdo = ps.pdo
            pos = np.flatnonzero(cob == cob_id)
            per = period_of[pos] + self.shift(pdo)
            ok = (per >= r0) & (per < r1)
            pos, per = pos[ok], per[ok]
            odd = buf["dlc"][pos] != fd_len(pdo.numpy_dtype().itemsize)
            if odd.any():  # the nodes send a PDO at its mapped length: another length is a frame they did not send
                st.interfere(cob_id, per[odd])
                pos, per = pos[~odd], per[~odd]
            if len(per) > 1 and (per[1:] == per[:-1]).any():
                if late is None:  # no lockstep: the last frame of a row is its value
                    last = np.r_[per[1:] != per[:-1], True]
                    pos, per = pos[last], per[last]
                else:
                    pos, per = self._one_per_period(pdo, buf, period_of, pos, per, late, r0)
            got = self._columns(ps, buf, pos, per - r0, r0, n, out)
            if self.hil and pdo.node == "plant" and pdo.trans_type <= 240:
                miss_meas |= ~got
            elif self.hil and pdo.node == "drive" and any(q.startswith("Voltage command.") for q, _ in pdo.signals):
                miss_cmd |= ~got
                if timed:
                    out["command_t_us"][per - r0] = buf["t_us"][pos].astype(np.float64)
        st.missing_measurements += int(miss_meas.sum())
        st.missing_commands += int(miss_cmd.sum())
        st.lost(out["period"][miss_meas | miss_cmd])
        if self.coding is not None:
            decode_codes(out, *self.coding)
        if self.hil:
            with np.errstate(invalid="ignore", over="ignore"):  # non-finite values stay so (and are counted)
                self._park(out)
            self._references(out, r0, r1)
        self._continuity(out)
        st.periods = r1
        return out

    def _syncs(
        self, buf: np.ndarray, period_of: np.ndarray, is_sync: np.ndarray, r0: int, r1: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each row's SYNC counter (-1: a SYNC without one) and time stamp; SYNCs that are not the loop's are
        interference."""
        n = r1 - r0
        cob = buf["cob_id"]
        sync = np.flatnonzero(is_sync)  # the loop's SYNCs (Decoder._genuine_syncs): each starts its period
        mark = self.mark
        if mark.is_sync:  # (a measurement frame of another length is counted with its PDO's columns)
            foreign_sync = np.flatnonzero((cob == mark.cob_id) & ~is_sync)
            fs_per = period_of[foreign_sync]
            self.stats.interfere(mark.cob_id, fs_per[(fs_per >= r0) & (fs_per < r1)])
        sp = period_of[sync]
        keep = (sp >= r0) & (sp < r1)
        sc = np.full(n, np.nan)
        dlc = buf["dlc"][sync[keep]]
        at = mark.counter_at or 0
        sc[sp[keep] - r0] = np.where(dlc > at, buf["data"][sync[keep], at], -1)
        t_us = np.full(n, np.nan)
        t_us[sp[keep] - r0] = buf["t_us"][sync[keep]].astype(np.float64)
        return sc, t_us

    def _columns(
        self,
        ps: PdoStats,
        buf: np.ndarray,
        pos: np.ndarray,
        rows: np.ndarray,
        r0: int,
        n: int,
        out: dict[str, np.ndarray],
    ) -> np.ndarray:
        """One PDO's columns from its frames `pos` (one per row, rows relative to r0) into `out`; the rows
        that got it. Non-finite values are counted per column (a NaN sent is never a lost frame)."""
        st = self.stats
        dt = ps.pdo.numpy_dtype()
        vals = np.ascontiguousarray(buf["data"][pos, : dt.itemsize]).view(dt).reshape(-1)
        got = np.zeros(n, dtype=bool)
        got[rows] = True
        ps.present += int(got.sum())
        bad = np.zeros(n, dtype=bool)
        for name, fmt in ps.pdo.signals:
            col = np.full(n, np.nan)
            col[rows] = vals[name].astype(np.float64)
            if fmt == "f":
                nf = got & ~np.isfinite(col)
                if nf.any():
                    first = r0 + int(np.argmax(nf))
                    if st.first_non_finite_period is None or first < st.first_non_finite_period:
                        st.first_non_finite_period = first
                    cname = column_name(name)
                    st.non_finite[cname] = st.non_finite.get(cname, 0) + int(nf.sum())
                    bad |= nf
            out[column_name(name)] = col
        ps.non_finite += int(bad.sum())
        return got

    # ------------------------------------------------------------------ HIL: one frame per period
    def _late(self, buf: np.ndarray, period_of: np.ndarray, r0: int, r1: int) -> Late:
        # a command may come after the SYNC it was meant for: in real time in any period; in lockstep with a
        # command timeout (0x2003:04 > 0) only in a period whose sample says the one before ended without its
        # command (the plant held and went on): any other second command there is interference
        misaligned = self._misaligned(buf, period_of, r0, r1)
        realtime = self.sdo.plant.get("Run control", "mode") == 1
        late_ok: np.ndarray | None = None
        if realtime or int(self.sdo.plant.get("Run control", "command_timeout_us") or 0) > 0:
            late_ok = self._missed(buf, period_of, r0, r1)
        return Late(realtime, late_ok, misaligned)

    def _one_per_period(
        self,
        pdo: PdoLayout,
        buf: np.ndarray,
        period_of: np.ndarray,
        pos: np.ndarray,
        per: np.ndarray,
        late: Late,
        r0: int,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One frame of a PDO per period (the first is the loop's): of a second one, say what it is and keep
        the frame that gives the period's value."""
        st = self.stats
        dup = np.r_[False, per[1:] == per[:-1]]
        commands = any(q.startswith("Voltage command.") for q, _ in pdo.signals)
        is_cmd = pdo.node == "drive" and pdo.trans_type > 240 and commands
        safe = _safe_state_commands(buf, period_of, pos, per, self.sdo.drive.node_id) if is_cmd else None
        if safe is not None and safe.any():
            # the drive entering its safe state sends 0 V at once, after the period's own command
            # (drive_app.h "Safe states"): that one is applied, the period's command is not
            st.safe_state_commands += int(safe.sum())
            keep = ~np.r_[safe[1:], False]
            pos, per, dup = pos[keep], per[keep], dup[keep] & ~safe[keep]
        if not dup.any():
            return pos, per
        if is_cmd and (late.realtime or (late.late_ok is not None and np.isin(per[dup], late.late_ok).all())):
            # a late command lands in the next period (the plant counts it late, 0x2003 late_commands, and never
            # applies it): the drive's own frame, not interference; the period's own command is the last one
            last = np.r_[per[1:] != per[:-1], True]
            return pos[last], per[last]
        # a PDO twice in a period that holds the next period's sample: the SYNC between them was lost
        # (frames_lost), not a foreign frame (a synchronous drive TPDO is one behind)
        shift = 1 if self.behind(pdo) else 0
        lost = dup & np.isin(per + shift, late.misaligned)
        drop = np.zeros_like(dup)
        if shift:
            per, dup, drop = _late_to_free_row(per, dup & ~lost, r0, late.realtime)
            if late.realtime and late.late_ok is not None:
                # real time: a drive late for its SYNCs answers them in a burst, its trace TPDOs before or after
                # its commands as its steps ran (a TCG-emulated box under load: 2-4 periods at once); where the
                # plant's samples say a period went without its command, those no free row takes are its own
                # frames, late (the period's value is not known: lost); anywhere else a second one is interference
                lost |= dup & (np.isin(per, late.late_ok) | np.isin(per + 1, late.late_ok))
            dup |= lost
        st.interfere(pdo.cob_id, per[dup & ~lost])
        st.lost(per[lost])
        return pos[~(dup | drop)], per[~(dup | drop)]

    def _misaligned(self, buf: np.ndarray, period_of: np.ndarray, r0: int, r1: int) -> np.ndarray:
        """Periods in [r0, r1) holding a measurement of the next period's sample: the SYNC between them was
        lost. Any other sample index in a second measurement (a frame the plant did not send) is not."""
        per, d = _field_bytes(buf, period_of, r0, r1, self.where.sample_index, 2)
        si = d[:, 0].astype(np.int64) | (d[:, 1].astype(np.int64) << 8)
        return np.unique(per[si == (per + 1) % 65536])

    def _missed(self, buf: np.ndarray, period_of: np.ndarray, r0: int, r1: int) -> np.ndarray:
        """Periods in [r0, r1) whose sample's status says the period before ended without its command
        (plant_app.h PLANT_STATUS_MISSED): there the late command of that period may still come."""
        per, d = _field_bytes(buf, period_of, r0, r1, self.where.status, 1)
        return np.unique(per[(d[:, 0] & PLANT_STATUS_MISSED) != 0])

    # ------------------------------------------------------------------ HIL: derived columns
    def _park(self, out: dict[str, np.ndarray]) -> None:
        if "i_a_A" in out and "theta_m_rad" in out:
            ia, ib = out["i_a_A"], out["i_b_A"]
            i_alpha, i_beta = ia, (ia + 2.0 * ib) / SQRT3
            th = self.pole_pairs * out["theta_m_rad"]
            c, s = np.cos(th), np.sin(th)
            out["id_A"] = c * i_alpha + s * i_beta
            out["iq_A"] = -s * i_alpha + c * i_beta
            if "v_alpha_V" in out:
                va, vb = out["v_alpha_V"], out["v_beta_V"]
                out["vd_V"] = c * va + s * vb
                out["vq_V"] = -s * va + c * vb

    def _references(self, out: dict[str, np.ndarray], r0: int, r1: int) -> None:
        """Reference columns from the SDO writes to the drive's References (their period is exact in lockstep)."""
        for name in REFERENCES:
            changes = self.sdo.changes(f"References.{name}")
            before = [v for p, v in changes if p <= r0]
            col = np.full(r1 - r0, before[-1] if before else 0.0)
            for period, value in changes:
                if r0 < period < r1:
                    col[period - r0 :] = value
            out[name] = col

    def _continuity(self, out: dict[str, np.ndarray]) -> None:
        """SYNC counter gaps (CiA 301: 1 .. the overflow value of 0x1019, then 1 again) between the
        periods that carry a counter, and (HIL) sample indices that are not the period's."""
        sc = out["sync_counter"]
        overflow = int(self.sdo.sync_overflow or 240)
        per = out["period"]
        ok = np.isfinite(sc) & (sc >= 0)
        vals, pers = sc[ok], per[ok]
        if self._last_sync >= 0:
            vals = np.concatenate([[self._last_sync], vals])
            pers = np.concatenate([[self._last_sync_period], pers])
        if len(vals) > 1:
            consecutive = np.diff(pers) == 1  # a gap is judged between neighbouring periods only
            expect = np.where(vals[:-1] >= overflow, 1, vals[:-1] + 1)
            gap = (vals[1:] != expect) & consecutive
            self.stats.sync_counter_gaps += int(gap.sum())
            self.stats.lost(pers[1:][gap] - 1)
        if len(vals):
            self._last_sync, self._last_sync_period = int(vals[-1]), int(pers[-1])
        if self.hil and "sample_index" in out:
            si = out["sample_index"]
            good = np.isfinite(si)
            wrong = si[good] != (out["period"][good] % 65536)
            self.stats.sample_index_mismatches += int(wrong.sum())
            self.stats.lost(out["period"][good][wrong])


def _safe_state_commands(
    buf: np.ndarray, period_of: np.ndarray, pos: np.ndarray, per: np.ndarray, drive_id: int
) -> np.ndarray:
    """Of the drive's command frames `pos` (periods `per`), the second ones of a period that are the
    drive's safe-state command: all zero (0 V) in a period whose drive EMCY says it entered its safe
    state (0xFF03 measurement timeout, 0xFF04 plant heartbeat lost)."""
    from bench.emcy import emcy_codes

    codes = emcy_codes("safe_meas_timeout", "safe_heartbeat")
    emcy = np.flatnonzero(buf["cob_id"] == 0x080 + drive_id)
    if len(emcy) == 0:
        return np.zeros(len(pos), dtype=bool)
    code = buf["data"][emcy, 0].astype(np.int64) | (buf["data"][emcy, 1].astype(np.int64) << 8)
    entered = period_of[emcy[np.isin(code, codes)]]
    entered = np.r_[entered, entered - 1]  # on a bus the EMCY, sent after the command, may follow the next SYNC
    zero = ~buf["data"][pos].any(axis=1)
    return np.r_[False, per[1:] == per[:-1]] & zero & np.isin(per, entered)


def _field_bytes(
    buf: np.ndarray, period_of: np.ndarray, r0: int, r1: int, where: tuple[int, int] | None, size: int
) -> tuple[np.ndarray, np.ndarray]:
    """The periods in [r0, r1) of the frames that carry a plant field (`where`: COB-ID, byte offset), and
    the field's `size` bytes of each; nothing when the layout has no such field."""
    if where is None:
        return np.zeros(0, dtype=np.int64), np.zeros((0, size), dtype=np.uint8)
    cob_id, off = where
    pos = np.flatnonzero(buf["cob_id"] == cob_id)
    per = period_of[pos]
    ok = (per >= r0) & (per < r1)
    return per[ok], buf["data"][pos[ok], off : off + size]


def _late_to_free_row(
    per: np.ndarray, dup: np.ndarray, r0: int, realtime: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A synchronous drive TPDO that arrives after the next SYNC is late, not foreign, when the row before
    has none of its own: a transport that reorders (SLCAN through a kernel on several CPUs, a controller
    that sends by priority: the command before the trace TPDOs, and the plant answers the command with the
    next SYNC at once), or a drive late for its SYNC in real time. `per`: the rows of one PDO's frames in
    bus order; `dup[i]`: frame i shares its row with frame i-1. Of such a pair the earlier frame moves to
    the row before when that row is free (before r0 it was emitted with the last chunk: the frame is
    dropped). In real time a drive that missed several SYNCs answers them all at once: a run of m frames in
    a row moves to the m - 1 rows before it when they are all free; in lockstep a run of three is not a
    late pair. Returns the new rows, the duplicates left (interference; in real time maybe late frames:
    _one_per_period) and the frames dropped."""
    drop = np.zeros_like(dup)
    if not dup.any():
        return per, dup, drop
    per, dup = per.copy(), dup.copy()
    has = set(per.tolist())
    starts = np.flatnonzero(~dup & np.r_[dup[1:], False])  # a frame followed by frames of its row
    for a in starts:
        b = a + 1
        while b + 1 < len(dup) and dup[b + 1]:
            b += 1
        m = b - a  # frames a .. b-1 move to the rows before per[b]
        if m > 1 and not realtime:
            continue
        rows = per[b] - np.arange(m, 0, -1)
        if any(int(r) in has for r in rows):
            continue
        for i, r in zip(range(a, b), rows, strict=True):
            if r >= r0:
                per[i] = r
            else:
                drop[i] = True
        dup[a + 1 : b + 1] = False
    return per, dup, drop
