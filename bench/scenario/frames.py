"""A scenario's [frames] table: which PDO mapping carries the measurement (issue 54's frame sets). Each set is a
PDO mapping the bench writes by SDO (run/loop/configure.py), not another code path in the nodes:

- "default": the plant's TPDO1 {i_a_A, i_b_A} and TPDO2 {theta_m_rad, sync_counter, status, sample_index},
  REAL32 values, two 8-byte frames after each SYNC;
- "compact": one 8-byte frame, TPDO1 {i_a_code, i_b_code, theta_code, sync_counter, status}: the currents as
  signed counts of current_lsb_A, the angle as counts of 1/angle_counts of a revolution (plant.eds and drive.eds
  0x2100:07-09, 0x2104; protocols/coding/meas_coding.h). With the ADC model quantizing and an encoder, the
  bench chooses the ADC's LSB and the encoder's 4 x lines, and the codes carry the sensor models' readings
  exactly; otherwise the reading is rounded to half a count at most. The drive numbers its samples by the SYNC
  counter the frame carries (there is no room for the 16-bit sample index).

- "single_frame" (needs can = "fd"): one 16-byte CAN FD frame, TPDO1 {i_a_A, i_b_A, theta_m_rad, sync_counter,
  status, sample_index}: today's REAL32 values, the two default frames' fields in one.

can = "fd": every PDO of the loop travels in CAN FD frames (plant.eds and drive.eds 0x2105:01 pdo_frame_format;
bit_rate_switch = true, the default, with the data phase at the data bit rate); SDO, NMT, SYNC, EMCY and heartbeat
stay classic frames (not CiA 1301: docs/PHYSICAL_BUS.md), and so does the plant's hold announcement (0x2105:02), which
a master behind a classic-only link (the CAN box's SLCAN bridge) must hear. The values are the same floats or codes:
a run on CAN FD equals the same run on classic frames in every column.

period_mark = "measurement" (with the compact or the single frame): the plant sends no SYNC frame; its one
measurement frame, the SYNC counter inside, marks the period. The plant still counts its SYNCs and runs its
synchronous PDOs on them (co_sync_produce_local): not CiA 301, whose synchronous PDOs follow a SYNC on the bus.
The drive computes on the frame's arrival as always; the trace TPDOs become event-driven, sent when the next
measurement arrives, before that period's step (the state after step k in period k + 1, as the SYNC's trace at
SYNC k + 1: the same rows); the drive's measurement timeout, counted in SYNCs, does not run (no SYNC reaches it).
"""

from __future__ import annotations

from typing import Any

from bench.eds import load, params
from bench.scenario.faults import Fault, FaultError
from bench.scenario.model import FrameSet, ScenarioError

MEASUREMENT_SETS = ("default", "compact", "single_frame")
PERIOD_MARKS = ("sync", "measurement")  # plant.eds 0x2003:0B period_mark's ValueNames
CAN_KINDS = ("classic", "fd")
FRAMES_KEYS = ("measurement", "current_lsb_A", "angle_counts", "period_mark", "can", "bit_rate_switch")
CODING = "Measurement coding"  # plant.eds / drive.eds 0x2104
CAN_FD = "CAN FD"  # plant.eds / drive.eds 0x2105
# The compact frame's mapping: the plant's TPDO1 and the drive's RPDO1, in this order (2 + 2 + 2 + 1 + 1 bytes).
COMPACT_MAP = (
    ("Measurement", "i_a_code"),
    ("Measurement", "i_b_code"),
    ("Measurement", "theta_code"),
    ("Measurement", "sync_counter"),
    ("Measurement", "status"),
)
# The single CAN FD frame's mapping (4 + 4 + 4 + 1 + 1 + 2 = 16 bytes: a CAN FD length, no padding).
SINGLE_FRAME_MAP = (
    ("Measurement", "i_a_A"),
    ("Measurement", "i_b_A"),
    ("Measurement", "theta_m_rad"),
    ("Measurement", "sync_counter"),
    ("Measurement", "status"),
    ("Measurement", "sample_index"),
)


def _limits(name: str) -> tuple[float, float]:
    """The EDS's range of a 0x2104 entry (the scenario's own checker's, bench.eds.params)."""
    p = params("drive", (CODING,))[name]
    assert p.low is not None and p.high is not None, f"drive.eds {CODING}.{name} has no limits"
    return float(p.low), float(p.high)


def parse_frames(raw: Any, where: str) -> FrameSet:
    """[frames] checked: a known set, and the coding's values in the EDS's range."""
    if raw is None:
        return FrameSet()
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where}: [frames] must be a table")
    for key in raw:
        if key not in FRAMES_KEYS:
            raise ScenarioError(f"{where}: unknown key frames.{key}; allowed in [frames]: {', '.join(FRAMES_KEYS)}")
    measurement = raw.get("measurement", "default")
    if measurement not in MEASUREMENT_SETS:
        raise ScenarioError(
            f"{where}: frames.measurement = {measurement!r}: expected one of {', '.join(MEASUREMENT_SETS)}"
        )
    lsb, counts = raw.get("current_lsb_A"), raw.get("angle_counts")
    if (lsb is not None or counts is not None) and measurement != "compact":
        raise ScenarioError(
            f"{where}: frames.current_lsb_A and frames.angle_counts need frames.measurement = 'compact'"
        )
    if lsb is not None:
        lo, hi = _limits("current_lsb_A")
        if isinstance(lsb, bool) or not isinstance(lsb, (int, float)) or not lo <= float(lsb) <= hi:
            raise ScenarioError(f"{where}: frames.current_lsb_A = {lsb!r}: expected a number in {lo:g} .. {hi:g} (A)")
        lsb = float(lsb)
    if counts is not None:
        lo, hi = _limits("angle_counts")
        if isinstance(counts, bool) or not isinstance(counts, int) or not lo <= counts <= hi:
            raise ScenarioError(f"{where}: frames.angle_counts = {counts!r}: expected an integer in {lo:g} .. {hi:g}")
    mark = raw.get("period_mark", "sync")
    if mark not in PERIOD_MARKS:
        raise ScenarioError(f"{where}: frames.period_mark = {mark!r}: expected one of {', '.join(PERIOD_MARKS)}")
    if mark == "measurement" and measurement not in ("compact", "single_frame"):
        raise ScenarioError(
            f"{where}: frames.period_mark = 'measurement' needs frames.measurement = 'compact' or 'single_frame' (the "
            "one frame that carries the whole sample and its SYNC counter marks the period)"
        )
    can, brs = _can(raw, where)
    if measurement == "single_frame" and can != "fd":
        raise ScenarioError(
            f"{where}: frames.measurement = 'single_frame' is 16 bytes: it needs frames.can = 'fd' (classic CAN "
            "frames hold 8; frames.measurement = 'compact' fits them)"
        )
    return FrameSet(measurement, lsb, counts, mark, can, brs)


def _can(raw: dict[str, Any], where: str) -> tuple[str, bool]:
    """frames.can and frames.bit_rate_switch, checked."""
    can = raw.get("can", "classic")
    if can not in CAN_KINDS:
        raise ScenarioError(f"{where}: frames.can = {can!r}: expected one of {', '.join(CAN_KINDS)}")
    brs = raw.get("bit_rate_switch", True)
    if not isinstance(brs, bool):
        raise ScenarioError(f"{where}: frames.bit_rate_switch = {brs!r}: expected true or false")
    if brs is False and can != "fd":  # true, the default, is harmless on classic frames (a scenario switched by --set)
        raise ScenarioError(
            f"{where}: frames.bit_rate_switch = false needs frames.can = 'fd' (classic frames have no data phase)"
        )
    return can, brs


def coding_for(frames: FrameSet, adc_lsb_A: float, encoder_lines: int) -> tuple[float, int]:
    """The compact frame's (current_lsb_A, angle_counts): the scenario's, else the plant's ADC LSB when it
    quantizes (its codes then travel exactly) or the EDS default, and the encoder's counts (4 x lines) when it has
    one that fits 16 bits, else the EDS default (65536)."""
    od = load("drive")[CODING]
    lsb = frames.current_lsb_A
    if lsb is None:
        lsb = float(adc_lsb_A) if adc_lsb_A > 0 else float(od["current_lsb_A"].default)
    counts = frames.angle_counts
    if counts is None:
        cpr = 4 * int(encoder_lines)
        counts = cpr if 0 < cpr <= 65536 else int(od["angle_counts"].default)
    return lsb, counts


def refuse_unsent_frames(faults: list[Fault], frames: FrameSet, where: str) -> None:
    """A frame fault on a frame the scenario's set never sends (the plant's TPDO2 with the compact frame, the SYNC
    with the measurement as the period's mark) could never act: refused, naming the frame that carries it now."""
    one = f"the {frames.measurement} frame (plant.TPDO1)"
    gone = {"plant.TPDO2": f"{one} carries the whole sample"} if frames.one_frame else {}
    if frames.sync_less:
        gone["SYNC"] = f"{one} marks the period"
    for f in faults:
        if f.frame in gone:
            raise FaultError(
                f"{where}: faults[{f.index}] ({f.kind} of {f.frame}): this scenario's [frames] never sends "
                f"{f.frame}: {gone[f.frame]}"
            )


def coding_refusal(lsb_A: float, chosen: str, full_scale_A: float) -> str | None:
    """Why the compact frame's coding cannot carry this plant's readings (None: it can): a step outside the EDS's
    range, or one whose +-32767 counts do not reach the ADC model's full scale (0: none). `chosen`: where the step
    came from. Beyond +-32767 counts a reading is clipped and the plant's status says so (bit 4, clipped)."""
    lo, hi = _limits("current_lsb_A")
    if not lo <= lsb_A <= hi:
        return f"frames.current_lsb_A = {lsb_A:g} ({chosen}): must be in {lo:g} .. {hi:g} A; set frames.current_lsb_A"
    if full_scale_A > 32767 * lsb_A:
        return (
            f"frames.current_lsb_A = {lsb_A:g} A ({chosen}) carries +-{32767 * lsb_A:g} A, less than the ADC model's "
            f"full scale {full_scale_A:g} A (drive.adc_full_scale_A): its readings beyond would be clipped. Set "
            f"frames.current_lsb_A >= {full_scale_A / 32767:.3g} (the codes then round the ADC's readings)"
        )
    return None
