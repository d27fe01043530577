"""Frames -> per-period trace columns, once, chunk by chunk, vectorized.

Alignment (CiA 301 synchronous semantics, docs/ARCHITECTURE.md): the k-th SYNC starts
period k; the plant's measurement TPDOs after it carry the sample i(k); the drive's command
TPDO that follows is v*(k); the drive's synchronous trace TPDOs sent at SYNC k carry its
state after step k-1. So the row of period k is complete only when SYNC k+1 has been seen:
the decoder keeps the frames of the last period of a chunk and decodes them again with the
next one (rows already emitted are not emitted twice; SDO frames are followed once). How the
frames of a period make its row: bench/run/decode/rows.py.

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

The teardown: the master of a run (bench/run/loop/session.py; not the CiA 402 master's) ends it with NMT Stop to
its nodes (bench/run/loop/session.py). From that
command on, every frame is the teardown's: counted (DecodeStats.teardown_frames) and its EMCYs listed apart
(Decoder.teardown_emcy, summary.json "teardown"), never a row, an EMCY of the run or a cause of its status.
A node stopped while the other still runs may miss its heartbeats (its consumer fires after 1 s), and an alarm
of the teardown is not one of the run.

Profiles: "hil" (the default) is the above, the project's plant and drive. "cia402" is the bench as the
CiA 402 master of a drive (`bench run --drive-profile cia402`): no plant node, no lockstep; the bench
produces SYNC as the drive's 0x1005/0x1019 say and every such SYNC from the first one starts a period; the
rows are the drive's TPDOs and the RPDOs the master set up by SDO (rows.py says how they align).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from canopen.nmt import NMT_COMMANDS

from bench.eds import default_node_id
from bench.run.bus.frames import FRAME_DTYPE, fd_len, join
from bench.run.decode.coding import decoded_names
from bench.run.decode.counts import DecodeStats, PdoStats
from bench.run.decode.layout import BusLayout, layout_from_sdo
from bench.run.decode.rows import REFERENCES, Rows, Where
from bench.run.decode.sdo_log import SdoLog
from bench.run.decode.syncs import PeriodMark, genuine_syncs, mark_candidates, period_mark, plant_field, starts_loop
from bench.scenario.frames import CODING
from bench.signals import SignalInfo, column_name

__all__ = ["DecodeStats", "Decoder", "PdoStats", "Profile", "layout_from_sdo"]

Profile = Literal["hil", "cia402"]
KIND_FOREIGN, KIND_KNOWN, KIND_EMCY = 0, 1, 2  # what an identifier is to the run
# the master's command that begins a run's teardown (CiA 301 NMT Stop: a STOPPED node sends no PDO and no EMCY)
TEARDOWN_NMT = NMT_COMMANDS["STOPPED"]


class Decoder:
    """Feed frames in bus order (any chunk size); get back the rows completed so far."""

    def __init__(
        self,
        plant_id: int | None = None,
        drive_id: int | None = None,
        profile: Profile = "hil",
        drive_eds: Path | None = None,
    ) -> None:
        """plant_id/drive_id: the nodes' IDs (None: their EDS's NodeID); profile "cia402": no plant node (plant_id
        is not used), the bench the drive's master; drive_eds: the drive's EDS when it is not drive.eds."""
        self.hil = profile == "hil"
        self.sdo = SdoLog(
            (default_node_id("plant") if plant_id is None else plant_id) if self.hil else None,
            default_node_id("drive") if drive_id is None else drive_id,
            drive_eds,
        )
        self.layout: BusLayout | None = None
        self.stats = DecodeStats()
        self.signals: list[SignalInfo] = []
        self.pole_pairs = 1
        self.ts_s = 1.0
        self._carry = np.zeros(0, dtype=FRAME_DTYPE)
        self._base = 0  # period of the carry's first SYNC
        self._emitted = 0  # rows emitted so far
        self._rows: Rows | None = None  # set with the layout
        self.hold_cob_id: int | None = None
        self._cmd_cob: int | None = None
        self._carry_genuine = False  # the carry starts at a SYNC already judged the plant's
        self._nmt_seen = False  # an NMT command went by (a master configuring the nodes) ...
        self._nmt_started = False  # ... and NMT start: the loop's SYNCs come after it
        self._meas: tuple[int, int] | None = None  # (COB-ID, byte offset) of Measurement.sync_counter
        self._mark: PeriodMark | None = None  # what starts a period (frozen with the layout)
        self._known: np.ndarray = self._base_known()
        self._kind = self._kinds()
        self.emcy: list[dict[str, object]] = []
        self.teardown_emcy: list[dict[str, object]] = []  # EMCYs after the teardown's NMT Stop: not the run's
        self.teardown_from_us: int | None = None  # the time stamp of the teardown's NMT Stop, once seen

    def _base_known(self) -> np.ndarray:
        """Identifiers a run uses outside its PDOs: NMT, SYNC, EMCY, SDO, heartbeats of the nodes."""
        known = np.zeros(2048, dtype=bool)
        known[0] = True
        for nid in self.sdo.nodes:
            for base in (0x080, 0x580, 0x600, 0x700):
                known[base + nid] = True
        self._service = known.copy()

        known[self.sdo.sync_cob_id & 0x7FF] = True
        return known

    # ------------------------------------------------------------------ layout
    def _freeze(self, t0_us: int) -> None:
        """The layout as the bus set it up by the loop's first SYNC (at t0_us): the PDOs, the signals."""
        self.layout = layout = layout_from_sdo(self.sdo, master_rpdos=not self.hil)
        # The plant's hold announcement (Run control, event-driven, once per lockstep segment) is the
        # bench's own plumbing, not a signal of the loop: not a trace column.
        hold = [p for p in layout.pdos if all(q.startswith("Run control.") for q, _ in p.signals)]
        self.hold_cob_id = hold[0].cob_id if hold else None
        cmd = [
            p for p in layout.pdos if p.node == "drive" and any(q.startswith("Voltage command.") for q, _ in p.signals)
        ]
        self._cmd_cob = cmd[0].cob_id if cmd and self.hil else None
        layout.pdos = [p for p in layout.pdos if p not in hold]
        self._known = self._base_known()
        for p in [*layout.pdos, *hold]:
            self._known[p.cob_id & 0x7FF] = True
        self._kind = self._kinds()
        self._meas = plant_field(layout, "Measurement.sync_counter", "B")
        self._mark = period_mark(self.sdo, self.hil)
        where = Where(
            plant_field(layout, "Measurement.sample_index", "H"), plant_field(layout, "Measurement.status", "B")
        )
        if self.hil:
            self.pole_pairs = int(self.sdo.plant.get("Motor model", "pole_pairs") or 1)
            self.ts_s = float(self.sdo.plant.get("Inverter", "Ts_s") or 1.0)
        self._rows = Rows(layout, self.sdo, self.stats, self.hil, where, self.ts_s, self.pole_pairs, t0_us)
        self._rows.mark = self._mark
        names: list[SignalInfo] = [SignalInfo.of("sync_counter", "SYNC", "<f4")]
        for pdo in layout.pdos:
            self.stats.pdos[pdo.cob_id] = PdoStats(pdo)
            for q, fmt in pdo.signals:
                # float32 holds a REAL32 and an integer of up to 16 bits exactly (and NaN for a missing frame)
                names.append(
                    SignalInfo.of(column_name(q), f"{pdo.node} {pdo.pdo} {q}", "<f4" if fmt in "fbBhH?" else "<f8")
                )
        cols = {s.name for s in names}
        coded = decoded_names(cols) if self.hil else []
        if coded:  # the compact measurement frame: its codes decoded with the plant's coding (0x2104)
            names += [SignalInfo.of(n, "decoded from the compact frame (Measurement coding)", "<f4") for n in coded]
            cols |= set(coded)
            plant = self.sdo.plant
            lsb, counts = plant.get(CODING, "current_lsb_A"), plant.get(CODING, "angle_counts")
            od = plant.od[CODING]  # a value the log never set: the EDS's, as the nodes had it
            self._rows.coding = (
                float(od["current_lsb_A"].default if lsb is None else lsb),
                int(od["angle_counts"].default if counts is None else counts),
            )
        if self.hil and {"i_a_A", "i_b_A", "theta_m_rad"} <= cols:
            names += [SignalInfo.of(n, "derived (Park transform)") for n in ("id_A", "iq_A")]
            if {"v_alpha_V", "v_beta_V"} <= cols:
                names += [SignalInfo.of(n, "derived (Park transform)") for n in ("vd_V", "vq_V")]
        if self.hil:
            names += [SignalInfo.of(n, "SDO writes to drive References", "<f4") for n in REFERENCES]
        self.signals = list({s.name: s for s in names}.values())  # a PDO's sync_counter replaces the SYNC's

    # ------------------------------------------------------------------ feeding
    def feed(self, frames: np.ndarray, last: bool = False) -> dict[str, np.ndarray] | None:
        """The rows these frames complete. `last`: no frame follows but `finish`'s, which makes every row
        still open at once (one pass over the rows instead of two: a short run's decoding is mostly that)."""
        if len(frames) == 0:
            return None
        self.stats.frames += len(frames)
        if self.teardown_from_us is None:
            cut = teardown_start(frames, tuple(self.sdo.nodes))
            if cut is None:
                return self._feed(frames, last)
            self.teardown_from_us = int(frames["t_us"][cut])
            rows = self._feed(frames[:cut], last) if cut else None
            frames = frames[cut:]
        else:
            rows = None
        self._teardown(frames)
        return rows

    def _teardown(self, frames: np.ndarray) -> None:
        """Frames of the teardown: counted, their EMCYs listed apart, each with how long after the NMT Stop it
        came (no period: the run's periods have ended)."""
        self.stats.teardown_frames += len(frames)
        cob = frames["cob_id"] & 0x7FF
        self._count_foreign(cob, self._kind[cob])  # the bus's foreign traffic, wherever it comes
        hit = np.flatnonzero(self._kind[cob] == KIND_EMCY)
        hit = hit[frames["dlc"][hit] == 8][: max(0, 1000 - len(self.teardown_emcy))]
        if len(hit) == 0:
            return
        after_s = (frames["t_us"][hit].astype(np.int64) - (self.teardown_from_us or 0)) / 1e6
        zero = np.zeros(len(frames), dtype=np.int64)
        for e, dt in zip(emcy_records(frames, zero, hit, self._names(), len(hit)), after_s.tolist(), strict=True):
            self.teardown_emcy.append({**e, "period": None, "after_stop_s": dt})

    def _feed(self, frames: np.ndarray, last: bool) -> dict[str, np.ndarray] | None:
        if len(frames) == 0:
            return None
        buf = join([self._carry, frames]) if len(self._carry) else frames
        new_from = len(self._carry)
        if self.layout is None:
            first = self._loop_start(buf)
            if first is None:
                return None
            self._freeze(int(buf["t_us"][first]))
            buf, new_from = buf[first:], 0
            self._carry_genuine = True  # judged the plant's first SYNC by _starts_loop
        assert self._rows is not None
        steps = self._period_steps(buf)
        if self._carry_genuine:
            steps[0] = 1  # buf starts at a plant SYNC (decided with the chunk before)
        sync = steps > 0
        period_of = self._base + np.cumsum(steps) - 1  # frames before the carry's SYNC: none (it starts with one)
        self._count_new(buf[new_from:], period_of[new_from:])
        sdo = self.sdo.mask(buf)
        sdo[:new_from] = False
        if sdo.any():
            idx = np.nonzero(sdo)[0]
            self._follow_sdo(buf[idx], period_of[idx] + 1)  # a setting takes effect at the next period
        sync_pos = np.nonzero(sync)[0]
        if len(sync_pos) < 2 or last:  # nothing complete yet, or all of it is finish's
            self._carry = buf
            return None
        # Row k is complete once period k+1 is (the drive's trace of step k comes at SYNC k+1):
        # with SYNC P the last seen, rows below P-1 are; keep the frames from SYNC P-1 on (CiA 402: from
        # SYNC P-2, whose period holds the RPDO of row P-1).
        stop = int(period_of[sync_pos[-2]])
        keep_from = int(sync_pos[max(0, len(sync_pos) - (2 if self.hil else 3))])
        rows = self._make_rows(buf, period_of, sync, stop) if stop > self._emitted else None
        self._carry = buf[keep_from:]
        self._carry_genuine = True
        self._base = int(period_of[keep_from])
        return rows

    def _loop_start(self, buf: np.ndarray) -> int | None:
        """Follow the configuration traffic up to the loop's first SYNC (whose COB-ID that traffic may set):
        its index in buf, or None when it is not in (the carry keeps what is still to be judged)."""
        start = scan = 0  # the configuration followed up to start; candidates looked for from scan
        while True:
            hits = np.nonzero(np.isin(buf["cob_id"][scan:], mark_candidates(self.sdo, self.hil)))[0]
            first = scan + int(hits[0]) if len(hits) else len(buf)
            self._follow_sdo(buf[start:first], np.zeros(first - start, dtype=np.int64))
            self._count_new(buf[start:first], np.zeros(first - start, dtype=np.int64))
            seg = buf[start:first]
            nmt = seg[(seg["cob_id"] == 0) & (seg["dlc"] == 2)]
            if len(nmt):
                self._nmt_seen = True
                self._nmt_started |= bool((nmt["data"][:, 0] == 0x01).any())
            if first == len(buf):
                self._carry = buf[:0]
                return None
            mark, start, scan = period_mark(self.sdo, self.hil), first, first + 1  # not taken: the next segment's
            if not mark.is_sync and buf["cob_id"][first] == mark.cob_id:
                if (not self._nmt_seen or self._nmt_started) and buf["dlc"][first] == mark.length:
                    return first  # the plant's first measurement frame after NMT start: the loop's first period
            elif buf["cob_id"][first] == self.sdo.sync_cob_id and mark.is_sync:
                # HIL: a SYNC while the master configures (NMT reset seen, no start yet) is not the loop's
                starts = not self._nmt_seen or self._nmt_started or not self.hil
                judged = self._starts_loop(buf, first) if starts else False
                if judged is None:  # its measurement is not in yet: decide with the next chunk
                    self._carry = buf[first:]
                    return None
                if judged:
                    return first
                self.stats.foreign[self.sdo.sync_cob_id] = self.stats.foreign.get(self.sdo.sync_cob_id, 0) + 1
                start = scan  # a foreign SYNC is counted here, not again with the next segment

    def finish(self) -> dict[str, np.ndarray] | None:
        """The rows left: the last period's drive trace TPDOs never come (NaN)."""
        if self.layout is None or len(self._carry) == 0:
            return None
        buf = self._carry
        steps = self._period_steps(buf)
        if self._carry_genuine:
            steps[0] = 1  # the carry starts at a plant SYNC
        sync = steps > 0
        if self._cmd_cob is not None and sync.any():
            # the loop ends with the command of its last period (what the plant waits for before it holds):
            # what follows is after the loop (a flood there is counted, and cannot change the verdict)
            last = int(np.flatnonzero(sync)[-1])
            cmd_len = next(fd_len(p.numpy_dtype().itemsize) for p in self.layout.pdos if p.cob_id == self._cmd_cob)
            cmd = np.flatnonzero((buf["cob_id"] == self._cmd_cob) & (buf["dlc"] == cmd_len))
            cmd = cmd[cmd > last]
            if len(cmd):
                end = int(cmd[0]) + 1
                tail = buf["cob_id"][end:].astype(np.int64) & 0x7FF
                after = ~self._service[tail]  # not SDO, NMT, EMCY, heartbeat, nor the hold announcement
                if self.hold_cob_id is not None:
                    after &= tail != self.hold_cob_id
                self.stats.after_loop_frames += int(after.sum())
                buf, sync, steps = buf[:end], sync[:end], steps[:end]
        period_of = self._base + np.cumsum(steps) - 1
        stop = int(period_of[-1]) + 1
        self._carry = buf[:0]
        return self._make_rows(buf, period_of, sync, stop) if stop > self._emitted else None

    def _make_rows(self, buf: np.ndarray, period_of: np.ndarray, sync: np.ndarray, stop: int) -> dict[str, np.ndarray]:
        """The rows not emitted yet, up to `stop` (exclusive)."""
        assert self._rows is not None
        out = self._rows.make(buf, period_of, sync, self._emitted, stop)
        self._emitted = stop
        return out

    def _kinds(self) -> np.ndarray:
        kind = np.where(self._known, KIND_KNOWN, KIND_FOREIGN).astype(np.uint8)
        for nid in self.sdo.nodes:
            kind[0x080 + nid] = KIND_EMCY
        return kind

    def _overflow(self) -> int:
        return int(self.sdo.sync_overflow or 0)

    def _starts_loop(self, buf: np.ndarray, at: int) -> bool | None:
        meas = plant_field(layout_from_sdo(self.sdo), "Measurement.sync_counter", "B")
        return starts_loop(buf, at, self.sdo.sync_cob_id, self._overflow(), meas)

    def _period_steps(self, buf: np.ndarray) -> np.ndarray:  # a plant SYNC starts one; a mark: PeriodMark.steps
        assert self.layout is not None and self._mark is not None
        if not self._mark.is_sync:
            return self._mark.steps(buf, self._overflow())
        return genuine_syncs(buf, self.layout.sync_cob_id, self._overflow(), self._meas).astype(np.int64)

    def _count_new(self, frames: np.ndarray, periods: np.ndarray) -> None:
        """Frames on identifiers the run does not use, by COB-ID, and the EMCYs (each frame once, when new)."""
        cob = frames["cob_id"] & 0x7FF
        kind = self._kind[cob]  # one lookup for both
        if (kind == KIND_EMCY).any():
            self._emcy(frames, periods, np.flatnonzero(kind == KIND_EMCY))
        self._count_foreign(cob, kind)

    def _count_foreign(self, cob: np.ndarray, kind: np.ndarray) -> None:
        foreign = kind == KIND_FOREIGN
        if foreign.any():
            ids, n = np.unique(cob[foreign], return_counts=True)
            for i, c in zip(ids.tolist(), n.tolist(), strict=True):
                self.stats.foreign[i] = self.stats.foreign.get(i, 0) + c

    def _names(self) -> dict[int, str]:
        return {0x080 + nid: node.name for nid, node in self.sdo.nodes.items()}

    def _emcy(self, frames: np.ndarray, periods: np.ndarray, hit: np.ndarray) -> None:
        """EMCY frames of the nodes (CiA 301: code, error register, 5 bytes manufacturer-specific)."""
        if len(self.emcy) < 1000:
            self.emcy.extend(emcy_records(frames, periods, hit, self._names(), 1000 - len(self.emcy)))

    def _follow_sdo(self, frames: np.ndarray, periods: np.ndarray) -> None:
        m = self.sdo.mask(frames)
        if m.any():
            self.sdo.feed(frames[m], periods[m])


def teardown_start(frames: np.ndarray, node_ids: tuple[int, ...]) -> int | None:
    """The index of the master's NMT Stop to all nodes or to one of the run's (`node_ids`) in these frames, the
    teardown's first frame. A Stop to another node (another master's on a shared bus) is not this run's end."""
    to = frames["data"][:, 1]
    ours = (to == 0) | np.isin(to, np.asarray(node_ids, dtype=np.uint8))
    hit = np.flatnonzero((frames["cob_id"] == 0) & (frames["dlc"] == 2) & (frames["data"][:, 0] == TEARDOWN_NMT) & ours)
    return int(hit[0]) if len(hit) else None


def emcy_records(
    frames: np.ndarray, periods: np.ndarray, hit: np.ndarray, names: dict[int, str], room: int
) -> list[dict[str, object]]:
    """EMCY frames of the nodes (CiA 301: code, error register, 5 bytes manufacturer-specific), at most `room`."""
    cob = frames["cob_id"]
    hit = hit[frames["dlc"][hit] == 8]
    out: list[dict[str, object]] = []
    for i in hit[: max(0, room)].tolist():
        d = bytes(frames["data"][i])
        out.append(
            {
                "period": max(0, int(periods[i])),
                "node": names[int(cob[i])],
                "code": f"0x{int.from_bytes(d[:2], 'little'):04X}",
                "error_register": d[2],
                "data": d[3:8].hex(),
            }
        )
    return out
