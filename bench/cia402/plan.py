"""What the CiA 402 master plays and how fast: CST targets from a scenario, and the SYNC cycle.

Targets: the scenario's `references.iq_ref_A` (at period 0 and in its events) becomes the CST
target torque 0x6071 in per mille of the rated torque, computed as iq_ref / rated current (0x6075)
x 1000. For a surface-mounted PMSM at id = 0 the torque is 1.5 p psi iq, proportional to iq, so
per mille of the rated current is per mille of the rated torque when the rated torque is the
torque at the rated current (the drive's EDS defaults: 4 A, 1.26 N m). One scenario period is
one SYNC cycle of the bench.

Cycle: --cycle-ms, or the shortest of 1, 2, 5, 10 ms whose bus load (SYNC, the RPDO, the TPDOs,
the two heartbeats, worst-case bit stuffing: bench.tools.plan) is at most 80 %.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from bench.canbus import classic_frame_bits
from bench.scenario import Scenario

if TYPE_CHECKING:
    from bench.cia402.layout import Layout

CYCLES_MS = (1.0, 2.0, 5.0, 10.0)
CYCLE_RANGE_MS = (1.0, 1000.0)
MAX_LOAD = 0.8
HEARTBEAT_S = 0.1  # the bench's heartbeat (node 0x7F) and, assumed, the drive's
INT16 = (-32768, 32767)
IQ_KEY = "references.iq_ref_A"


class PlanError(ValueError):
    """Bad input: the message says what and why (exit 2)."""


@dataclass(frozen=True)
class Segment:
    start_cycle: int
    end_cycle: int  # exclusive
    iq_ref_A: float
    per_mille: int


@dataclass(frozen=True)
class Frames:
    """Data bytes of the frames of one cycle."""

    sync: int  # 1 with a counter (0x1019 >= 2), else 0
    rpdo: int
    tpdos: tuple[int, ...]

    @classmethod
    def of(cls, layout: Layout) -> Frames:
        return cls(1 if layout.sync_overflow >= 2 else 0, layout.rpdo.size, tuple(p.size for p in layout.tpdos))

    @classmethod
    def reference(cls) -> Frames:
        """Before the drive is read: drive.eds' PDOs (bench/cia402/layout.py)."""
        from bench.cia402.layout import default_layout

        return cls.of(default_layout())


def per_mille(iq_A: float, rated_current_mA: int) -> int:
    return round(iq_A / (rated_current_mA / 1000.0) * 1000.0)


def targets(sc: Scenario, rated_current_mA: int, max_torque_pm: int | None) -> list[Segment]:
    """The reference profile as CST segments; PlanError when a target does not fit INT16 / 0x6072."""
    if rated_current_mA <= 0:
        raise PlanError(f"rated current 0x6075 = {rated_current_mA} mA: must be > 0")
    changes: dict[int, float] = {0: 0.0}
    for s in sc.settings:
        if s.key == IQ_KEY:
            changes[0] = float(s.value)
    for ev in sc.events:
        for s in ev.settings:
            if s.key == IQ_KEY:
                changes[ev.at_period] = float(s.value)
    starts = sorted(changes)
    out: list[Segment] = []
    for i, start in enumerate(starts):
        end = starts[i + 1] if i + 1 < len(starts) else sc.periods
        iq = changes[start]
        pm = per_mille(iq, rated_current_mA)
        if not INT16[0] <= pm <= INT16[1]:
            raise PlanError(
                f"{sc.source}: iq_ref_A = {iq:g} A is {pm} per mille of {rated_current_mA} mA: 0x6071 is INT16"
            )
        if max_torque_pm is not None and abs(pm) > max_torque_pm:
            raise PlanError(
                f"{sc.source}: iq_ref_A = {iq:g} A is {pm} per mille of the rated current {rated_current_mA} mA, "
                f"beyond the drive's max torque 0x6072 = {max_torque_pm} per mille"
            )
        if out and out[-1].per_mille == pm:
            out[-1] = Segment(out[-1].start_cycle, end, out[-1].iq_ref_A, pm)
        else:
            out.append(Segment(start, end, iq, pm))
    return out


def ignored_keys(sc: Scenario) -> list[str]:
    """Scenario keys that mean nothing to a CiA 402 drive in CST (said in the summary, not refused)."""
    out = [s.key for s in sc.settings if s.key != IQ_KEY]
    if sc.preset is not None:
        out.insert(0, "motor.preset")
    for i, ev in enumerate(sc.events):
        out += [f"events[{i}].{s.key}" for s in ev.settings if s.key != IQ_KEY]
    out += [f"faults[{i}]" for i in range(len(sc.faults))]
    if "trace" in sc.raw:
        out.append("trace")
    head = sc.raw.get("scenario", {})
    out += [f"scenario.{k}" for k in ("timing", "seed", "expect") if k in head]
    return out


def cycle_bits(frames: Frames, cycle_s: float) -> float:
    """Worst-case bits on the bus per cycle: SYNC, RPDO, TPDOs, and the share of two heartbeats."""
    bits = classic_frame_bits(frames.sync) + classic_frame_bits(frames.rpdo)
    bits += sum(classic_frame_bits(n) for n in frames.tpdos)
    return bits + 2 * classic_frame_bits(1) * cycle_s / HEARTBEAT_S


def bus_load(frames: Frames, cycle_s: float, bitrate: int) -> float:
    return cycle_bits(frames, cycle_s) / bitrate / cycle_s


def choose_cycle(bitrate: int, cycle_ms: float | None, frames: Frames | None = None) -> tuple[float, float]:
    """(cycle in s, bus load). PlanError for a cycle out of range, or one that overloads the bus."""
    frames = frames or Frames.reference()
    if bitrate <= 0 or bitrate > 1_000_000:
        raise PlanError(f"--bitrate {bitrate}: classic CAN runs at 1 .. 1000000 bit/s")
    if cycle_ms is not None:
        lo, hi = CYCLE_RANGE_MS
        if not lo <= cycle_ms <= hi:
            raise PlanError(f"--cycle-ms {cycle_ms:g}: the SYNC cycle is {lo:g} .. {hi:g} ms")
        load = bus_load(frames, cycle_ms / 1000, bitrate)
        if load > MAX_LOAD:
            raise PlanError(
                f"--cycle-ms {cycle_ms:g}: the cycle's frames load the {bitrate} bit/s bus {load * 100:.0f} % "
                f"(limit {MAX_LOAD * 100:.0f} %); choose a longer cycle or a faster bus"
            )
        return cycle_ms / 1000, load
    for ms in CYCLES_MS:
        load = bus_load(frames, ms / 1000, bitrate)
        if load <= MAX_LOAD:
            return ms / 1000, load
    raise PlanError(
        f"no cycle of {', '.join(f'{c:g}' for c in CYCLES_MS)} ms keeps the {bitrate} bit/s bus under "
        f"{MAX_LOAD * 100:.0f} %: give --cycle-ms"
    )
