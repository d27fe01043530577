"""What the verdict needs from the trace chunks as they pass (Pipeline feeds it), and the verdict itself: the
largest phase current and the first period beyond the divergence bound, the first trip, the plant's status
bits, a real-time run's SYNC and command time stamps (bench/run/verdict/realtime.py), then the status flags, the
first period of each and the run's status."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.eds import bits
from bench.emcy import emcy_codes
from bench.run.decode.decoder import Decoder
from bench.run.verdict import realtime
from bench.run.verdict.faults import StatusWatch
from bench.run.verdict.summary import divergence_bound_A, plant_values, verdict

# The drive's EMCYs of a safe state its current law caused (status law_fault): its command non-finite or
# beyond Vmax_V (0xFF06), a step longer than the period on a bare-metal target (0xFF07).
LAW_FAULT_EMCY = frozenset(emcy_codes("safe_law_output", "safe_overrun"))
# The plant's EMCY of a model that failed (status plant_fault): an FMU's doStep returned an error.
PLANT_FAULT_EMCY = frozenset(emcy_codes("model_fault"))
# The plant's inverter trip latched (Measurement.status, plant.eds BitNames)
STATUS_TRIP = bits("plant", "Measurement", "status")["trip"]


class LoopWatch:
    def __init__(self) -> None:
        self.max_phase_A = 0.0
        self.bound_A: float | None = None
        self.first_trip_period: int | None = None
        self.first_beyond_bound_period: int | None = None
        self.status = StatusWatch()  # the plant's status bits per period (held, missed, trip)
        self.timing = realtime.BusTiming()  # a real-time run's SYNC and command time stamps per period
        # the overview's timing series of a real-time run (realtime.envelopes), set by judge()
        self.timing_envelopes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.first_periods: dict[str, int | None] = {}  # each raised status flag's first period (judge)

    def begin(self, dec: Decoder) -> None:
        self.bound_A = divergence_bound_A(plant_values(dec))  # the plant as configured

    def add(self, chunk: dict[str, np.ndarray]) -> None:
        self.timing.add(chunk)
        phase = [
            np.abs(np.nan_to_num(chunk[c], nan=0.0, posinf=0.0, neginf=0.0)) for c in ("i_a_A", "i_b_A") if c in chunk
        ]
        if phase:
            a = np.maximum.reduce(phase)  # the larger phase current of each period
            self.max_phase_A = max(self.max_phase_A, float(a.max()))
            if self.bound_A is not None and self.first_beyond_bound_period is None and a.max() > self.bound_A:
                self.first_beyond_bound_period = int(chunk["period"][int(np.argmax(a > self.bound_A))])
        if "status" in chunk:
            self.status.add(chunk["period"], chunk["status"])
        if self.first_trip_period is None and "status" in chunk:
            st = chunk["status"]
            hit = np.nonzero(np.isfinite(st) & ((np.nan_to_num(st).astype(np.int64) & STATUS_TRIP) != 0))[0]
            if len(hit):
                self.first_trip_period = int(chunk["period"][hit[0]])

    def judge(
        self,
        dec: Decoder,
        steps: list[dict[str, Any]],
        bstats: dict[str, Any],
        stopped: dict[str, Any] | None,
        expect: tuple[str, ...],
    ) -> tuple[str, int, bool, dict[str, bool], list[int]]:
        """(status, exit code, expected, status flags, oscillating steps' periods). `bstats` gets planned_periods,
        and in a real-time run "realtime": summary.json's realtime block (realtime.block), which build_summary
        moves to the top level."""
        trip_active = dec.sdo.plant.get("Run control", "trip_active")
        # A loop that never settles and still swings over half its step at the end of the window
        # oscillates (an unstable loop held by the voltage limit): diverged, though bounded.
        swinging = [
            s
            for s in steps
            if s["periods_to_settle"] is None and (s["tail_peak_to_peak_A"] or 0.0) > 0.5 * abs(s["to_A"] - s["from_A"])
        ]
        oscillating = [s["at_period"] for s in swinging]
        # The periods the master ran (its run_periods writes, in the log): a log with fewer (cut short, a
        # recorder that lost the end) or more is not the run, unless the run stopped early.
        planned = sum(int(v) for _, v in dec.sdo.changes("Run control.run_periods", node="plant") if 0 < v < 0xFFFFFFFF)
        bstats["planned_periods"] = planned or None
        short = bool(planned) and dec.stats.periods != planned and not stopped
        # The drive refused its law (a non-finite or beyond-Vmax_V command; a step longer than the period on a
        # bare-metal target) and entered its safe state: its EMCY, the first one's period
        law_faults = [e["period"] for e in dec.emcy if e["node"] == "drive" and int(e["code"], 16) in LAW_FAULT_EMCY]
        plant_faults = [
            e["period"] for e in dec.emcy if e["node"] == "plant" and int(e["code"], 16) in PLANT_FAULT_EMCY
        ]
        bound = self.bound_A
        rt = self._realtime(dec)
        if rt is not None:
            bstats["realtime"] = rt
        flags = {
            "law_fault": bool(law_faults),
            "plant_fault": bool(plant_faults),
            "non_finite": bool(bstats["non_finite_values"]),
            "diverged": (bound is not None and self.max_phase_A > bound) or bool(oscillating),
            "tripped": self.first_trip_period is not None or bool(trip_active),
            "frames_lost": bstats["lost_frames"] > 0 or short or bool(stopped and stopped["status"] == "frames_lost"),
            "node_lost": bool(stopped and stopped["status"] == "node_lost"),
            "interference": bstats["interference"]["frames"] > 0,
        }
        first = {
            "law_fault": min(law_faults) if law_faults else None,
            "plant_fault": min(plant_faults) if plant_faults else None,
            "non_finite": dec.stats.first_non_finite_period,
            "tripped": self.first_trip_period,
            "diverged": self.first_beyond_bound_period
            if self.first_beyond_bound_period is not None
            else swing_seen_from(swinging, self.first_trip_period),
            "interference": bstats["interference"]["first_period"],
            # a log shorter than the run its master ran (cut, a recorder that lost the end): from where it ends
            "frames_lost": dec.stats.first_lost_period
            if dec.stats.first_lost_period is not None or not short
            else dec.stats.periods,
        }
        if rt is not None:  # a real-time run: the plant counted overruns (a lockstep run's flags stay as they were)
            flags["realtime_overrun"] = realtime.overran(rt)
            first["realtime_overrun"] = realtime.first_overrun(rt, dec.stats.first_lost_period)
        if stopped:
            at = stopped.get("at_period")
            first[stopped["status"]] = at if at is not None else dec.stats.periods
        status, code, expected = verdict(flags, expect, first)
        # each raised flag's first period (summary.json "status_first_period"): the status is the earliest
        self.first_periods = {k: first.get(k) for k, v in flags.items() if v}
        return status, code, expected, flags, oscillating

    def _realtime(self, dec: Decoder) -> dict[str, Any] | None:
        """A real-time run's block (None in lockstep), with the bus view when the chunks carried time stamps; the
        overview's timing series with it."""
        if not realtime.is_realtime(dec):
            return None
        if not self.timing:
            return realtime.block(dec, None)
        segs = realtime.segments(dec)
        pp = self.timing.per_period(segs)
        rt = realtime.block(dec, realtime.bus_view(pp, segs))
        assert rt is not None
        self.timing_envelopes = realtime.envelopes(pp, rt["plant"])
        return rt


def swing_seen_from(swinging: list[dict[str, Any]], trip: int | None) -> int | None:
    """The period an oscillation counts from in the order of events, over the steps that swing (judge): its
    step's period (an unstable loop swings from its step on), unless the plant tripped inside the step's window
    before the last fifth of it where the swing is measured (stats.StepTracker): after a trip the inverter no
    longer applies the loop's command, and the swing seen then is the trip's doing; it counts from that fifth's
    first period. So a trip at period 370 followed by swings is "tripped", with "diverged" in the flags."""
    seen = []
    for s in swinging:
        tail = s["at_period"] + s["window_periods"] - max(1, s["window_periods"] // 5)
        seen.append(tail if trip is not None and s["at_period"] <= trip < tail else s["at_period"])
    return min(seen) if seen else None
