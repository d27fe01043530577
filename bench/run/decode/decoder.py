"""Frames -> per-period trace columns, once, chunk by chunk, vectorized.

Alignment (CiA 301 synchronous semantics, docs/ARCHITECTURE.md): the k-th SYNC starts
period k; the plant's measurement TPDOs after it carry the sample i(k); the drive's command
TPDO that follows is v*(k); the drive's synchronous trace TPDOs sent at SYNC k carry its
state after step k-1. So the row of period k is complete only when SYNC k+1 has been seen:
the decoder keeps the frames of the last period of a chunk and decodes them again with the
next one (rows already emitted are not emitted twice; SDO frames are followed once).

Columns are float64 (NaN where no frame carried the value) except `period` (int64); names
carry SI units (bench/signals.py). Which frames were missing and which carried a
non-finite value are counted separately, per PDO: a NaN sent on the bus is never a lost frame.

Foreign frames never crash the decoder and never make periods. A SYNC starts a period only when
it is the plant's: its counter is the one the plant's next measurement PDO carries (Measurement.
sync_counter); any other frame on the SYNC identifier is foreign. Frames on identifiers the loop
does not use are counted by COB-ID; a second frame on one of the loop's own identifiers in a
period, or a foreign SYNC inside the loop, is interference (the nodes may have acted on it: the
run's status says so). What comes after the plant's final hold announcement is after the loop:
counted, never judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bench.eds import default_node_id
from bench.run.bus.frames import FRAME_DTYPE
from bench.run.decode.layout import FMT, BusLayout, PdoLayout
from bench.run.decode.sdo_log import SdoLog
from bench.run.decode.syncs import genuine_syncs, plant_field, starts_loop
from bench.signals import SignalInfo, column_name

SQRT3 = math.sqrt(3.0)
KIND_FOREIGN, KIND_KNOWN, KIND_EMCY = 0, 1, 2  # what an identifier is to the run
REFERENCES = ("iq_ref_A", "id_ref_A")
TPDOS = 4
PLANT_STATUS_MISSED = 0x04  # Measurement.status: the period before this sample ended without its command


def layout_from_sdo(sdo: SdoLog) -> BusLayout:
    """The valid TPDOs of both nodes at this point of the bus traffic (EDS defaults + SDO seen)."""
    layout = BusLayout(sdo.plant.node_id, sdo.drive.node_id, sdo.sync_cob_id)
    for node in (sdo.plant, sdo.drive):
        v = node.values
        for n in range(TPDOS):
            cob = v.get((0x1800 + n, 1))
            count = int(v.get((0x1A00 + n, 0)) or 0)
            if cob is None or int(cob) & 0x80000000 or count == 0:
                continue
            sigs = []
            for i in range(1, count + 1):
                entry = int(v.get((0x1A00 + n, i)) or 0)
                var = node.vars.get((entry >> 16, (entry >> 8) & 0xFF))
                if var is None or var.data_type not in FMT:
                    break
                sigs.append((node.qualname(var.index, var.subindex) or var.name, FMT[var.data_type]))
            else:
                layout.pdos.append(
                    PdoLayout(node.name, f"TPDO{n + 1}", int(cob) & 0x7FF, int(v.get((0x1800 + n, 2)) or 0), sigs)
                )
    return layout


@dataclass
class PdoStats:
    pdo: PdoLayout
    present: int = 0  # periods that got this PDO
    non_finite: int = 0  # periods whose frame carried a NaN or an infinity


@dataclass
class DecodeStats:
    periods: int = 0
    frames: int = 0
    # COB-ID -> frames on identifiers the run does not use (and foreign SYNCs)
    foreign: dict[int, int] = field(default_factory=dict)
    interference: dict[int, int] = field(default_factory=dict)  # COB-ID -> extra frames on the loop's own
    first_interference_period: int | None = None
    first_lost_period: int | None = None  # the first period with a missing frame, a gap or a misaligned sample
    after_loop_frames: int = 0
    sync_counter_gaps: int = 0
    sample_index_mismatches: int = 0
    pdos: dict[int, PdoStats] = field(default_factory=dict)
    non_finite: dict[str, int] = field(default_factory=dict)  # column -> periods with a non-finite value
    first_non_finite_period: int | None = None
    missing_measurements: int = 0  # periods without one of the plant's synchronous measurement PDOs
    missing_commands: int = 0  # periods without the drive's command PDO
    safe_state_commands: int = 0  # the drive's 0 V command sent at once on entering its safe state (drive_app.h)


class Decoder:
    """Feed frames in bus order (any chunk size); get back the rows completed so far."""

    def __init__(self, plant_id: int | None = None, drive_id: int | None = None) -> None:
        """plant_id/drive_id: the nodes' IDs (None: their EDS's NodeID)."""
        self.sdo = SdoLog(
            default_node_id("plant") if plant_id is None else plant_id,
            default_node_id("drive") if drive_id is None else drive_id,
        )
        self.layout: BusLayout | None = None
        self.stats = DecodeStats()
        self.signals: list[SignalInfo] = []
        self.pole_pairs = 1
        self.ts_s = 1.0
        self._carry = np.zeros(0, dtype=FRAME_DTYPE)
        self._base = 0  # period of the carry's first SYNC
        self._emitted = 0  # rows emitted so far
        self._last_sync = -1
        self._last_sync_period = -1
        self.hold_cob_id: int | None = None
        self._cmd_cob: int | None = None
        self._carry_genuine = False  # the carry starts at a SYNC already judged the plant's
        self._nmt_seen = False  # an NMT command went by (a master configuring the nodes) ...
        self._nmt_started = False  # ... and NMT start: the loop's SYNCs come after it
        self._index: tuple[int, int] | None = None  # (COB-ID, byte offset) of Measurement.sample_index
        self._status: tuple[int, int] | None = None  # (COB-ID, byte offset) of Measurement.status
        self._meas: tuple[int, int] | None = None  # (COB-ID, byte offset) of Measurement.sync_counter
        self._known: np.ndarray = self._base_known()
        self._kind = self._kinds()
        self.emcy: list[dict[str, object]] = []

    def _base_known(self) -> np.ndarray:
        """Identifiers a run uses outside its PDOs: NMT, SYNC, EMCY, SDO, heartbeats of both nodes."""
        known = np.zeros(2048, dtype=bool)
        known[0] = True
        for nid in (self.sdo.plant.node_id, self.sdo.drive.node_id):
            for base in (0x080, 0x580, 0x600, 0x700):
                known[base + nid] = True
        self._service = known.copy()

        known[self.sdo.sync_cob_id & 0x7FF] = True
        return known

    # ------------------------------------------------------------------ layout
    def _freeze(self) -> None:
        self.layout = layout_from_sdo(self.sdo)
        # The plant's hold announcement (Run control, event-driven, once per lockstep segment) is the
        # bench's own plumbing, not a signal of the loop: not a trace column.
        hold = [p for p in self.layout.pdos if all(q.startswith("Run control.") for q, _ in p.signals)]
        self.hold_cob_id = hold[0].cob_id if hold else None
        cmd = [
            p
            for p in self.layout.pdos
            if p.node == "drive" and any(q.startswith("Voltage command.") for q, _ in p.signals)
        ]
        self._cmd_cob = cmd[0].cob_id if cmd else None
        self.layout.pdos = [p for p in self.layout.pdos if p not in hold]
        self._known = self._base_known()
        for p in [*self.layout.pdos, *hold]:
            self._known[p.cob_id & 0x7FF] = True
        self._kind = self._kinds()
        self._meas = plant_field(self.layout, "Measurement.sync_counter", "B")
        self._index = plant_field(self.layout, "Measurement.sample_index", "H")
        self._status = plant_field(self.layout, "Measurement.status", "B")
        self.pole_pairs = int(self.sdo.plant.get("Motor model", "pole_pairs") or 1)
        self.ts_s = float(self.sdo.plant.get("Inverter", "Ts_s") or 1.0)
        names: list[SignalInfo] = [SignalInfo.of("sync_counter", "SYNC", "<f4")]
        for pdo in self.layout.pdos:
            self.stats.pdos[pdo.cob_id] = PdoStats(pdo)
            for q, fmt in pdo.signals:
                # float32 holds a REAL32 and an integer of up to 16 bits exactly (and NaN for a missing frame)
                names.append(
                    SignalInfo.of(column_name(q), f"{pdo.node} {pdo.pdo} {q}", "<f4" if fmt in "fbBhH?" else "<f8")
                )
        cols = {s.name for s in names}
        if {"i_a_A", "i_b_A", "theta_m_rad"} <= cols:
            names += [SignalInfo.of(n, "derived (Park transform)") for n in ("id_A", "iq_A")]
            if {"v_alpha_V", "v_beta_V"} <= cols:
                names += [SignalInfo.of(n, "derived (Park transform)") for n in ("vd_V", "vq_V")]
        names += [SignalInfo.of(n, "SDO writes to drive References", "<f4") for n in REFERENCES]
        self.signals = list({s.name: s for s in names}.values())  # a PDO's sync_counter replaces the SYNC's

    # ------------------------------------------------------------------ feeding
    def feed(self, frames: np.ndarray) -> dict[str, np.ndarray] | None:
        if len(frames) == 0:
            return None
        self.stats.frames += len(frames)
        buf = np.concatenate([self._carry, frames]) if len(self._carry) else frames
        new_from = len(self._carry)
        if self.layout is None:
            start = 0
            while True:  # configuration traffic until the first SYNC (whose COB-ID that traffic may set)
                hits = np.nonzero(buf["cob_id"][start:] == self.sdo.sync_cob_id)[0]
                first = start + int(hits[0]) if len(hits) else len(buf)
                self._follow_sdo(buf[start:first], np.zeros(first - start, dtype=np.int64))
                self._count_new(buf[start:first], np.zeros(first - start, dtype=np.int64))
                seg = buf[start:first]
                nmt = seg[(seg["cob_id"] == 0) & (seg["dlc"] == 2)]
                if len(nmt):
                    self._nmt_seen = True
                    self._nmt_started |= bool((nmt["data"][:, 0] == 0x01).any())
                if first == len(buf):
                    self._carry = np.zeros(0, dtype=FRAME_DTYPE)
                    return None
                if buf["cob_id"][first] == self.sdo.sync_cob_id:
                    # a SYNC while the master configures (NMT reset seen, no start yet) is not the loop's
                    starts = not self._nmt_seen or self._nmt_started
                    judged = self._starts_loop(buf, first) if starts else False
                    if judged is None:  # its measurement is not in yet: decide with the next chunk
                        self._carry = buf[first:]
                        return None
                    if judged:
                        break
                    self.stats.foreign[self.sdo.sync_cob_id] = self.stats.foreign.get(self.sdo.sync_cob_id, 0) + 1
                    first += 1
                start = first
            self._freeze()
            buf, new_from = buf[first:], 0
            self._carry_genuine = True  # judged the plant's first SYNC by _starts_loop
        assert self.layout is not None
        sync = self._genuine_syncs(buf)
        if self._carry_genuine:
            sync[0] = True  # buf starts at a plant SYNC (decided with the chunk before)
        period_of = self._base + np.cumsum(sync) - 1  # frames before the carry's SYNC: none (it starts with one)
        self._count_new(buf[new_from:], period_of[new_from:])
        sdo = self.sdo.mask(buf)
        sdo[:new_from] = False
        if sdo.any():
            idx = np.nonzero(sdo)[0]
            self._follow_sdo(buf[idx], period_of[idx] + 1)  # a setting takes effect at the next period
        sync_pos = np.nonzero(sync)[0]
        if len(sync_pos) < 2:  # nothing complete yet
            self._carry = buf
            return None
        # Row k is complete once period k+1 is (the drive's trace of step k comes at SYNC k+1):
        # with SYNC P the last seen, rows below P-1 are; keep the frames from SYNC P-1 on.
        keep_from = int(sync_pos[-2])
        stop = int(period_of[keep_from])
        rows = self._rows(buf, period_of, sync, self._emitted, stop) if stop > self._emitted else None
        self._carry = buf[keep_from:]
        self._carry_genuine = True
        self._base = stop
        return rows

    def finish(self) -> dict[str, np.ndarray] | None:
        """The rows left: the last period's drive trace TPDOs never come (NaN)."""
        if self.layout is None or len(self._carry) == 0:
            return None
        buf = self._carry
        sync = self._genuine_syncs(buf)
        sync[0] |= self._carry_genuine  # the carry starts at a plant SYNC
        if self._cmd_cob is not None and sync.any():
            # the loop ends with the command of its last period (what the plant waits for before it holds):
            # what follows is after the loop (a flood there is counted, and cannot change the verdict)
            last = int(np.flatnonzero(sync)[-1])
            cmd_len = next(p.numpy_dtype().itemsize for p in self.layout.pdos if p.cob_id == self._cmd_cob)
            cmd = np.flatnonzero((buf["cob_id"] == self._cmd_cob) & (buf["dlc"] == cmd_len))
            cmd = cmd[cmd > last]
            if len(cmd):
                end = int(cmd[0]) + 1
                tail = buf["cob_id"][end:].astype(np.int64) & 0x7FF
                after = ~self._service[tail]  # not SDO, NMT, EMCY, heartbeat, nor the hold announcement
                if self.hold_cob_id is not None:
                    after &= tail != self.hold_cob_id
                self.stats.after_loop_frames += int(after.sum())
                buf, sync = buf[:end], sync[:end]
        period_of = self._base + np.cumsum(sync) - 1
        stop = int(period_of[-1]) + 1
        self._carry = np.zeros(0, dtype=FRAME_DTYPE)
        return self._rows(buf, period_of, sync, self._emitted, stop) if stop > self._emitted else None

    def _kinds(self) -> np.ndarray:
        kind = np.where(self._known, KIND_KNOWN, KIND_FOREIGN).astype(np.uint8)
        for nid in (self.sdo.plant.node_id, self.sdo.drive.node_id):
            kind[0x080 + nid] = KIND_EMCY
        return kind

    def _overflow(self) -> int:
        return int(self.sdo.plant.get("Synchronous counter overflow value") or 0)

    def _starts_loop(self, buf: np.ndarray, at: int) -> bool | None:
        meas = plant_field(layout_from_sdo(self.sdo), "Measurement.sync_counter", "B")
        return starts_loop(buf, at, self.sdo.sync_cob_id, self._overflow(), meas)

    def _genuine_syncs(self, buf: np.ndarray) -> np.ndarray:
        assert self.layout is not None
        return genuine_syncs(buf, self.layout.sync_cob_id, self._overflow(), self._meas)

    def _count_new(self, frames: np.ndarray, periods: np.ndarray) -> None:
        """Frames on identifiers the run does not use, by COB-ID, and the EMCYs (each frame once, when new)."""
        cob = frames["cob_id"] & 0x7FF
        kind = self._kind[cob]  # one lookup for both
        if (kind == KIND_EMCY).any():
            self._emcy(frames, periods, np.flatnonzero(kind == KIND_EMCY))
        foreign = kind == KIND_FOREIGN
        if foreign.any():
            ids, n = np.unique(cob[foreign], return_counts=True)
            for i, c in zip(ids.tolist(), n.tolist(), strict=True):
                self.stats.foreign[i] = self.stats.foreign.get(i, 0) + c

    def _emcy(self, frames: np.ndarray, periods: np.ndarray, hit: np.ndarray) -> None:
        """EMCY frames of both nodes (CiA 301: code, error register, 5 bytes manufacturer-specific)."""
        if len(self.emcy) >= 1000:
            return
        names = {0x080 + self.sdo.plant.node_id: "plant", 0x080 + self.sdo.drive.node_id: "drive"}
        cob = frames["cob_id"]
        hit = hit[frames["dlc"][hit] == 8]
        for i in hit[: 1000 - len(self.emcy)].tolist():
            d = bytes(frames["data"][i])
            self.emcy.append(
                {
                    "period": max(0, int(periods[i])),
                    "node": names[int(cob[i])],
                    "code": f"0x{int.from_bytes(d[:2], 'little'):04X}",
                    "error_register": d[2],
                    "data": d[3:8].hex(),
                }
            )

    def _follow_sdo(self, frames: np.ndarray, periods: np.ndarray) -> None:
        m = self.sdo.mask(frames)
        if m.any():
            self.sdo.feed(frames[m], periods[m])

    # ------------------------------------------------------------------ rows
    def _rows(
        self, buf: np.ndarray, period_of: np.ndarray, is_sync: np.ndarray, r0: int, r1: int
    ) -> dict[str, np.ndarray]:
        assert self.layout is not None
        n = r1 - r0
        st = self.stats
        out: dict[str, np.ndarray] = {"period": np.arange(r0, r1, dtype=np.int64)}
        out["t_s"] = out["period"] * self.ts_s
        cob = np.ascontiguousarray(buf["cob_id"])
        data = buf["data"]
        sync = np.flatnonzero(is_sync)  # the plant's SYNCs (_genuine_syncs): each starts its period
        foreign_sync = np.flatnonzero((cob == self.layout.sync_cob_id) & ~is_sync)
        fs_per = period_of[foreign_sync]
        self._interfere(self.layout.sync_cob_id, fs_per[(fs_per >= r0) & (fs_per < r1)])
        sp = period_of[sync]
        keep = (sp >= r0) & (sp < r1)
        sc = np.full(n, np.nan)
        dlc = buf["dlc"][sync[keep]]
        sc[sp[keep] - r0] = np.where(dlc > 0, data[sync[keep], 0], -1)
        out["sync_counter"] = sc
        miss_meas = np.zeros(n, dtype=bool)
        miss_cmd = np.zeros(n, dtype=bool)
        misaligned = self._misaligned(buf, period_of, r0, r1)
        # a command may come after the SYNC it was meant for: in real time in any period; in lockstep with a
        # command timeout (0x2003:04 > 0) only in a period whose sample says the one before ended without its
        # command (the plant held and went on): any other second command there is interference
        realtime = self.sdo.plant.get("Run control", "mode") == 1
        late_ok: np.ndarray | None = None
        if not realtime and int(self.sdo.plant.get("Run control", "command_timeout_us") or 0) > 0:
            late_ok = self._missed(buf, period_of, r0, r1)
        for cob_id, ps in st.pdos.items():
            pdo = ps.pdo
            pos = np.flatnonzero(cob == cob_id)
            per = period_of[pos]
            if pdo.node == "drive" and pdo.trans_type <= 240:
                per = per - 1  # synchronous drive TPDO at SYNC k: state after step k-1
            ok = (per >= r0) & (per < r1)
            pos, per = pos[ok], per[ok]
            dt = pdo.numpy_dtype()
            odd = buf["dlc"][pos] != dt.itemsize
            if odd.any():  # the nodes send a PDO at its mapped length: another length is a frame they did not send
                self._interfere(cob_id, per[odd])
                pos, per = pos[~odd], per[~odd]
            if len(per) > 1:  # one frame per period: a second one is interference (the first is the loop's)
                dup = np.r_[False, per[1:] == per[:-1]]
                if dup.any():
                    is_cmd = pdo.node == "drive" and pdo.trans_type > 240
                    safe = self._safe_state_commands(buf, period_of, pos, per) if is_cmd else None
                    if safe is not None and safe.any():
                        # the drive entering its safe state sends 0 V at once, after the period's own command
                        # (drive_app.h "Safe states"): that one is applied, the period's command is not
                        st.safe_state_commands += int(safe.sum())
                        keep = ~np.r_[safe[1:], False]
                        pos, per, dup = pos[keep], per[keep], dup[keep] & ~safe[keep]
                    if not dup.any():
                        pass
                    elif is_cmd and (realtime or (late_ok is not None and np.isin(per[dup], late_ok).all())):
                        # a late command lands in the next period (the plant counts it late, 0x2003 late_commands,
                        # and never applies it): the drive's own frame, not interference; the period's own
                        # command is the last one
                        last = np.r_[per[1:] != per[:-1], True]
                        pos, per = pos[last], per[last]
                    else:
                        # a PDO twice in a period that holds the next period's sample: the SYNC between them
                        # was lost (frames_lost), not a foreign frame (a synchronous drive TPDO is one behind)
                        shift = 1 if pdo.node == "drive" and pdo.trans_type <= 240 else 0
                        lost = dup & np.isin(per + shift, misaligned)
                        drop = np.zeros_like(dup)
                        if shift:
                            per, dup, drop = _late_to_free_row(per, dup & ~lost, r0)
                            dup |= lost
                        self._interfere(cob_id, per[dup & ~lost])
                        self._lost(per[lost])
                        pos, per = pos[~(dup | drop)], per[~(dup | drop)]
            per = per - r0
            vals = np.ascontiguousarray(data[pos, : dt.itemsize]).view(dt).reshape(-1)
            got = np.zeros(n, dtype=bool)
            got[per] = True
            ps.present += int(got.sum())
            if pdo.node == "plant" and pdo.trans_type <= 240:
                miss_meas |= ~got
            elif pdo.node == "drive" and any(q.startswith("Voltage command.") for q, _ in pdo.signals):
                miss_cmd |= ~got
            bad = np.zeros(n, dtype=bool)
            for name, fmt in pdo.signals:
                col = np.full(n, np.nan)
                col[per] = vals[name].astype(np.float64)
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
        st.missing_measurements += int(miss_meas.sum())
        st.missing_commands += int(miss_cmd.sum())
        self._lost(out["period"][miss_meas | miss_cmd])
        self._derive(out)
        self._references(out, r0, r1)
        self._continuity(out)
        st.periods = r1
        self._emitted = r1
        return out

    def _misaligned(self, buf: np.ndarray, period_of: np.ndarray, r0: int, r1: int) -> np.ndarray:
        """Periods in [r0, r1) holding a measurement of the next period's sample: the SYNC between them was
        lost. Any other sample index in a second measurement (a frame the plant did not send) is not."""
        per, d = _field_bytes(buf, period_of, r0, r1, self._index, 2)
        si = d[:, 0].astype(np.int64) | (d[:, 1].astype(np.int64) << 8)
        return np.unique(per[si == (per + 1) % 65536])

    def _missed(self, buf: np.ndarray, period_of: np.ndarray, r0: int, r1: int) -> np.ndarray:
        """Periods in [r0, r1) whose sample's status says the period before ended without its command
        (plant_app.h PLANT_STATUS_MISSED): there the late command of that period may still come."""
        per, d = _field_bytes(buf, period_of, r0, r1, self._status, 1)
        return np.unique(per[(d[:, 0] & PLANT_STATUS_MISSED) != 0])

    def _lost(self, periods: np.ndarray) -> None:
        if len(periods):
            first = int(periods.min())
            st = self.stats
            if st.first_lost_period is None or first < st.first_lost_period:
                st.first_lost_period = first

    def _safe_state_commands(
        self, buf: np.ndarray, period_of: np.ndarray, pos: np.ndarray, per: np.ndarray
    ) -> np.ndarray:
        """Of the drive's command frames `pos` (periods `per`), the second ones of a period that are the
        drive's safe-state command: all zero (0 V) in a period whose drive EMCY says it entered its safe
        state (0xFF03 measurement timeout, 0xFF04 plant heartbeat lost)."""
        from bench.emcy import emcy_codes

        codes = emcy_codes("safe_meas_timeout", "safe_heartbeat")
        emcy = np.flatnonzero(buf["cob_id"] == 0x080 + self.sdo.drive.node_id)
        if len(emcy) == 0:
            return np.zeros(len(pos), dtype=bool)
        code = buf["data"][emcy, 0].astype(np.int64) | (buf["data"][emcy, 1].astype(np.int64) << 8)
        entered = period_of[emcy[np.isin(code, codes)]]
        entered = np.r_[entered, entered - 1]  # on a bus the EMCY, sent after the command, may follow the next SYNC
        zero = ~buf["data"][pos].any(axis=1)
        return np.r_[False, per[1:] == per[:-1]] & zero & np.isin(per, entered)

    def _interfere(self, cob_id: int, periods: np.ndarray) -> None:
        if len(periods) == 0:
            return
        st = self.stats
        st.interference[cob_id] = st.interference.get(cob_id, 0) + len(periods)
        first = int(periods.min())
        if st.first_interference_period is None or first < st.first_interference_period:
            st.first_interference_period = first

    def _derive(self, out: dict[str, np.ndarray]) -> None:
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite values stay so (and are counted)
            self._park(out)

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
        periods that carry a counter, and sample indices that are not the period's."""
        sc = out["sync_counter"]
        overflow = int(self.sdo.plant.get("Synchronous counter overflow value") or 240)
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
            self._lost(pers[1:][gap] - 1)
        if len(vals):
            self._last_sync, self._last_sync_period = int(vals[-1]), int(pers[-1])
        if "sample_index" in out:
            si = out["sample_index"]
            good = np.isfinite(si)
            wrong = si[good] != (out["period"][good] % 65536)
            self.stats.sample_index_mismatches += int(wrong.sum())
            self._lost(out["period"][good][wrong])


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


def _late_to_free_row(per: np.ndarray, dup: np.ndarray, r0: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A synchronous drive TPDO that arrives after the next SYNC is late, not foreign, when the row before
    has none of its own: a transport that reorders (SLCAN through a kernel on several CPUs, a controller
    that sends by priority: the command before the trace TPDOs, and the plant answers the command with the
    next SYNC at once), or a drive late for its SYNC in real time. `per`: the rows of one PDO's frames in
    bus order; `dup[i]`: frame i shares its row with frame i-1. Of such a pair the earlier frame moves to
    the row before when that row is free (before r0 it was emitted with the last chunk: the frame is
    dropped). Returns the new rows, the duplicates left (interference) and the frames dropped."""
    drop = np.zeros_like(dup)
    second = np.flatnonzero(dup)
    if len(second) == 0:
        return per, dup, drop
    first = second - 1
    row = per[first] - 1
    free = ~np.isin(row, per) & ~dup[first]  # the row before has no frame, and it is a pair, not three
    per, dup = per.copy(), dup.copy()
    move, gone = first[free & (row >= r0)], first[free & (row < r0)]
    per[move] -= 1
    dup[move + 1] = False
    dup[gone + 1] = False
    drop[gone] = True
    return per, dup, drop
