"""Which SYNC frames are the plant's: the periods of a run are counted by them alone.

A SYNC is the plant's when its counter is the sync_counter of the plant's next measurement PDO
(Measurement.sync_counter, CiA 301 0x1019 counter) and no SYNC nearer to that measurement carries it
too; or, when that measurement was lost, when its counter sits exactly between the plant's SYNCs
before and after it. Any other frame on the SYNC identifier is foreign (bench/run/decode/decoder.py counts it
as interference inside the loop). Written by hand: this is the bench's own policy on a shared bus,
which no CANopen library decides for a recorder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.run.bus.frames import fd_len
from bench.run.decode.layout import BusLayout, layout_from_sdo
from bench.run.decode.sdo_log import SdoLog
from bench.scenario.frames import PERIOD_MARKS

# foreign SYNCs tolerated between the plant's SYNC and its measurement (a plant descheduled for 15 ms in a VM
# while a flood ran at 2 ms saw 4); far fewer than the 240 SYNCs after which the counter repeats
SYNC_LOOKBACK = 32
START_LOOKAHEAD = 4096  # frames searched after a SYNC for the measurement that makes it the loop's first


@dataclass(frozen=True)
class PeriodMark:
    """What starts a period on the bus: the plant's SYNC (CiA 301), or (plant.eds 0x2003:0B period_mark =
    measurement, bench/scenario/frames.py) its compact measurement frame with the SYNC counter inside."""

    cob_id: int
    counter_at: int | None = 0  # byte offset of the SYNC counter in the frame (a SYNC's: 0)
    length: int | None = None  # the measurement frame's length; None: a SYNC (genuine_syncs judges it)

    @property
    def is_sync(self) -> bool:
        return self.length is None

    def steps(self, buf: np.ndarray, overflow: int) -> np.ndarray:
        """Periods each frame of buf starts (0: none), the first mark 1. A measurement frame of the mark's length
        starts as many periods as its SYNC counter moved on from the mark before (0x1019's cycle): a repeated
        counter (a duplicate) or one behind (a late or reordered frame: more than half a cycle on) starts none, a
        gap of n counts starts n (the periods between lost). Without a counter (0x1019 < 2) each starts one."""
        steps = np.zeros(len(buf), dtype=np.int64)
        pos = np.flatnonzero((buf["cob_id"] == self.cob_id) & (buf["dlc"] == self.length))
        if overflow < 2 or self.counter_at is None or len(pos) == 0:
            steps[pos] = 1
            return steps
        counter = buf["data"][pos, self.counter_at].astype(np.int64)
        while True:  # drop the marks that move the counter by 0 or backwards, against the mark kept before them
            d = (np.diff(counter) % overflow) if len(counter) > 1 else np.zeros(0, dtype=np.int64)
            bad = np.flatnonzero((d == 0) | (d > overflow // 2)) + 1
            if len(bad) == 0:
                break
            keep = np.ones(len(pos), dtype=bool)
            keep[bad] = False  # a run of old frames goes one a round: each is judged again against the one kept
            pos, counter = pos[keep], counter[keep]
        steps[pos] = np.r_[1, np.diff(counter) % overflow]
        return steps


def measurement_mark(layout: BusLayout) -> PeriodMark | None:
    """The mark of a plant whose measurement frame marks its periods: the PDO carrying Measurement.sync_counter."""
    meas = plant_field(layout, "Measurement.sync_counter", "B")
    if meas is None:
        return None
    pdo = next(p for p in layout.pdos if p.node == "plant" and p.cob_id == meas[0])
    return PeriodMark(meas[0], meas[1], fd_len(pdo.numpy_dtype().itemsize))


def period_mark(sdo: SdoLog, hil: bool) -> PeriodMark:
    """What starts a period, as the bus set the plant up so far (plant.eds 0x2003:0B period_mark by SDO)."""
    if hil and sdo.plant.get("Run control", "period_mark") == PERIOD_MARKS.index("measurement"):
        mark = measurement_mark(layout_from_sdo(sdo))
        if mark is not None:
            return mark
    return PeriodMark(sdo.sync_cob_id)


def mark_candidates(sdo: SdoLog, hil: bool) -> list[int]:
    """Identifiers that may start the loop: the SYNC's, and (HIL) the plant's TPDOs (a measurement frame as mark)."""
    if not hil:
        return [sdo.sync_cob_id]
    return [sdo.sync_cob_id, *(p.cob_id for p in layout_from_sdo(sdo).pdos if p.node == "plant")]


def plant_field(layout: BusLayout, name: str, fmt: str) -> tuple[int, int] | None:
    """(COB-ID, byte offset) of a plant signal in its PDOs, or None when not mapped (with that format)."""
    for p in layout.pdos:
        off = 0
        for q, f in p.signals:
            if p.node == "plant" and q == name and f == fmt:
                return p.cob_id, off
            off += np.dtype(f).itemsize
    return None


def starts_loop(buf: np.ndarray, at: int, sync_cob_id: int, overflow: int, meas: tuple[int, int] | None) -> bool | None:
    """Is the SYNC at buf[at] the plant's first (the loop's start)? Judged as genuine_syncs judges every
    later one, with the layout as configured so far (meas: COB-ID and byte offset of the plant's
    sync_counter): the plant's next measurement carries its counter, and no SYNC nearer to that
    measurement carries it too. None: the measurement is not in yet. A foreign SYNC before the run (a
    bus that was never quiet) must not start the loop early."""
    if overflow < 2:
        return int(buf["dlc"][at]) == 0
    if int(buf["dlc"][at]) != 1:
        return False
    if meas is None:  # no counter mapped: no way to tell, the first SYNC starts the loop
        return True
    cob = buf["cob_id"]
    end = at + 1 + START_LOOKAHEAD
    after = np.flatnonzero((cob[at + 1 : end] == meas[0]) & (buf["dlc"][at + 1 : end] > meas[1]))
    if len(after) == 0:
        return None if len(buf) < end else False
    m = at + 1 + int(after[0])
    counter = int(buf["data"][m, meas[1]])
    if int(buf["data"][at, 0]) != counter:
        return False
    between = np.flatnonzero((cob[at + 1 : m] == sync_cob_id) & (buf["dlc"][at + 1 : m] == 1))
    return not (buf["data"][at + 1 + between, 0] == counter).any()


def genuine_syncs(buf: np.ndarray, sync_cob_id: int, overflow: int, meas: tuple[int, int] | None) -> np.ndarray:
    """Mask of the plant's own SYNCs in buf: the SYNC's counter is the sync_counter of the plant's
    next measurement PDO. A SYNC with no measurement after it yet is undecided (not a period until
    it is; at the end of the log, foreign). Without a counter (0x1019 = 0), every SYNC of length 0."""
    cob = buf["cob_id"]
    cand = np.flatnonzero(cob == sync_cob_id)
    sync = np.zeros(len(buf), dtype=bool)
    if len(cand) == 0:
        return sync
    dlc = buf["dlc"][cand]
    if overflow < 2 or meas is None:
        sync[cand[dlc == (1 if overflow >= 2 else 0)]] = True
        return sync
    meas_cob, off = meas
    m_pos = np.flatnonzero((cob == meas_cob) & (buf["dlc"] > off))
    counter = np.where(dlc == 1, buf["data"][cand, 0].astype(np.int64), -1)
    meas_counter = buf["data"][m_pos, off].astype(np.int64)
    before = np.searchsorted(cand, m_pos) - 1  # the SYNC candidate just before each measurement
    # The plant sends its measurement right after its SYNC; foreign SYNCs may fall in between: look a
    # few candidates back. Counters repeat only every 240 SYNCs, so an old SYNC never matches.
    done = np.zeros(len(m_pos), dtype=bool)  # each measurement marks one SYNC: the nearest one with its counter
    for back in range(SYNC_LOOKBACK):
        c = before - back
        hit = (c >= 0) & ~done
        hit[hit] = counter[c[hit]] == meas_counter[hit]
        sync[cand[c[hit]]] = True
        done |= hit
        if done.all():  # a clean stream: every measurement found its SYNC right before it
            break
    # A SYNC whose measurement was lost: length 1, its counter right after the previous plant SYNC's and
    # right before the next one's (a period then counted as missing its measurement, not as foreign).
    g = sync[cand]
    gi = np.flatnonzero(g)
    rest = np.flatnonzero(~g & (dlc == 1))
    if len(gi) >= 2 and len(rest):
        k = np.searchsorted(gi, rest)
        ok = (k > 0) & (k < len(gi))
        rest, k = rest[ok], k[ok]
        c, prev, nxt = counter[rest], counter[gi[k - 1]], counter[gi[k]]
        fit = (np.where(prev >= overflow, 1, prev + 1) == c) & (np.where(c >= overflow, 1, c + 1) == nxt)
        sync[cand[rest[fit]]] = True
    return sync  # an undecided tail (no measurement yet) is decided with the next chunk: the carry keeps it
