"""`bench plan`: does the configured PDO set fit a real-time period on a given bus?

Frame lengths use the worst case of bit stuffing:

* Classic CAN, 11-bit identifier, n data bytes:
  ``47 + 8n`` bits on the wire plus at most ``floor((34 + 8n - 1) / 4)`` stuff bits
  (stuffing covers SOF .. CRC, 34 + 8n bits). 8 bytes: 135 bits.
* CAN FD, 11-bit identifier, bit-rate switch: the arbitration phase (SOF, ID, RRS, IDE,
  FDF, res, BRS: 17 bits, up to 4 stuff bits) and the tail (CRC delimiter, ACK, ACK
  delimiter, EOF, IFS: 13 bits) run at the nominal rate; ESI, DLC, data, stuff count (4),
  CRC (17 bits up to 16 data bytes, else 21) and its fixed stuff bits run at the data rate,
  with up to ``floor((5 + 8n - 1) / 4)`` dynamic stuff bits.

The PDO set per control period is read from the EDS files with `canopen`: the SYNC
(with counter when 0x1019 >= 2), every valid TPDO of the plant and the drive with its
mapped length, plus the optional trace PDOs. The frames of one period are causally
chained (SYNC -> measurement -> command), so the period must hold all of them; a
period "fits" when the bus load stays at or below ``max_load`` (default 0.8), leaving
room for the controller's computation and other traffic.

This is the plan before a run. The frames a run actually sent, with each frame's exact length, arbitration and
the nodes' latencies, are simulated by bench.tools.plan_log (`bench plan --from-log RUN/bus.log`); the worst-case
lengths here are bench.tools.wire.worst_bits, derived there from the frame's fields.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field

import canopen

from bench.canbus import classic_frame_bits, fd_frame_bits
from bench.eds import default_node_id
from bench.paths import EDS_DIR
from bench.scenario.frames import COMPACT_MAP, MEASUREMENT_SETS, PERIOD_MARKS, SINGLE_FRAME_MAP


@dataclass
class FrameUse:
    what: str
    data_bytes: int
    per_period: float  # frames per control period (trace PDOs may be decimated)
    bits: int  # worst-case bits of one frame on the wire
    time_s: float  # worst-case wire time of one frame


@dataclass
class Plan:
    bitrate: float
    data_bitrate: float | None
    fd: bool
    ts_s: float
    max_load: float
    frame_set: str = "default measurement frame set"  # [frames] (bench/scenario/frames.py), in words
    frames: list[FrameUse] = field(default_factory=list)
    bits_per_period: float = 0.0
    time_per_period_s: float = 0.0
    bus_load: float = 0.0
    fits: bool = False
    fastest_period_s: float = 0.0
    advice: list[str] = field(default_factory=list)

    def to_json(self) -> str:
        d = asdict(self)
        return json.dumps(d, indent=2)


def pdo_set(
    trace_pdos: int = 0, trace_decimation: int = 1, frames: str = "default", period_mark: str = "sync"
) -> list[tuple[str, int, float]]:
    """(what, data bytes, frames per period) of one control period, from the EDS files; `frames`: the scenario's
    measurement set ([frames] measurement, bench/scenario/frames.py): "compact" and "single_frame" map the plant's
    TPDO1 as COMPACT_MAP / SINGLE_FRAME_MAP and leave its TPDO2 off, as the bench does by SDO; `period_mark`
    "measurement": no SYNC frame."""
    if frames not in MEASUREMENT_SETS:
        raise _bad("--frames", frames, f"one of {', '.join(MEASUREMENT_SETS)}")
    if period_mark not in PERIOD_MARKS or (period_mark == "measurement" and frames == "default"):
        marks = ", ".join(PERIOD_MARKS)
        raise _bad("--period-mark", period_mark, f"one of {marks} (measurement with --frames compact or single_frame)")
    out: list[tuple[str, int, float]] = []
    plant = canopen.import_od(str(EDS_DIR / "plant.eds"), node_id=default_node_id("plant"))
    drive = canopen.import_od(str(EDS_DIR / "drive.eds"), node_id=default_node_id("drive"))
    ov = plant["Synchronous counter overflow value"].default or 0
    if period_mark == "sync":
        out.append(("SYNC (plant)", 1 if ov >= 2 else 0, 1.0))
    one_map = {"compact": COMPACT_MAP, "single_frame": SINGLE_FRAME_MAP}.get(frames)
    one_bits = sum(len(plant[obj][name]) for obj, name in one_map) if one_map else 0
    for name, od in (("plant", plant), ("drive", drive)):
        for n in range(4):
            comm, mapping = od[0x1800 + n], od[0x1A00 + n]
            cob = comm[1].default
            if cob & 0x80000000 or (one_map and name == "plant" and n == 1):
                continue
            count = mapping[0].default
            bits = sum((mapping[i].default & 0xFF) for i in range(1, count + 1))
            what = f"{name} TPDO{n + 1} (0x{cob & 0x7FF:03X})"
            if one_map and name == "plant" and n == 0:
                bits, what = one_bits, what + f" {frames}" + (", mark" if period_mark == "measurement" else "")
            out.append((what, bits // 8, 1.0))
    for i in range(trace_pdos):
        out.append((f"trace PDO {i + 1}", 8, 1.0 / trace_decimation))
    return out


def _bad(field: str, value: object, allowed: str) -> ValueError:
    return ValueError(f"{field} = {value}: must be {allowed}")


def check_inputs(
    bitrate: float,
    ts_s: float,
    fd: bool,
    data_bitrate: float | None,
    max_load: float,
    trace_pdos: int,
    trace_decimation: int,
) -> None:
    """Every input in its range (a ValueError naming the field, its value and the allowed range);
    NaN and infinities are out of every range."""
    top = 12e6 if fd else 1e6
    if not (math.isfinite(bitrate) and 0 < bitrate <= top + 1e-9):
        raise _bad("--bitrate", f"{bitrate:g}", f"in (0, {top:g}] bit/s for {'CAN FD' if fd else 'classic CAN'}")
    if fd and (data_bitrate is None or not (math.isfinite(data_bitrate) and 0 < data_bitrate <= 12e6)):
        raise _bad("--data-bitrate", data_bitrate, "in (0, 12e6] bit/s with --fd")
    if not (math.isfinite(ts_s) and ts_s > 0):
        raise _bad("--ts", f"{ts_s:g}", "a finite period > 0 s (e.g. 55e-6)")
    if not (math.isfinite(max_load) and 0 < max_load <= 1):
        raise _bad("--max-load", f"{max_load:g}", "in (0, 1]")
    if trace_pdos < 0:
        raise _bad("--trace-pdos", trace_pdos, ">= 0")
    if trace_decimation < 1:
        raise _bad("--trace-decimation", trace_decimation, ">= 1")


def make_plan(
    bitrate: float,
    ts_s: float,
    fd: bool = False,
    data_bitrate: float | None = None,
    max_load: float = 0.8,
    trace_pdos: int = 0,
    trace_decimation: int = 1,
    frames: str = "default",
    period_mark: str = "sync",
) -> Plan:
    check_inputs(bitrate, ts_s, fd, data_bitrate, max_load, trace_pdos, trace_decimation)
    if frames == "single_frame" and not fd:
        raise _bad("--frames", frames, "default or compact on classic CAN (single_frame is 16 bytes: give --fd)")
    set_name = f"{frames} measurement frame set" + ("" if period_mark == "sync" else ", no SYNC: it marks the period")
    plan = Plan(bitrate, data_bitrate if fd else None, fd, ts_s, max_load, set_name)
    for what, n, per in pdo_set(trace_pdos, trace_decimation, frames, period_mark):
        if fd and what.startswith("SYNC"):  # the bench's SYNC stays a classic frame on a CAN FD bus (0x2105)
            bits = classic_frame_bits(n)
            plan.frames.append(FrameUse(what, n, per, bits, bits / bitrate))
        elif fd:
            nominal, data = fd_frame_bits(n)
            plan.frames.append(
                FrameUse(what, n, per, nominal + data, nominal / bitrate + data / (data_bitrate or bitrate))
            )
        else:
            bits = classic_frame_bits(n)
            plan.frames.append(FrameUse(what, n, per, bits, bits / bitrate))
    plan.time_per_period_s = sum(f.time_s * f.per_period for f in plan.frames)
    plan.bits_per_period = sum(f.bits * f.per_period for f in plan.frames)
    plan.bus_load = plan.time_per_period_s / ts_s
    plan.fits = plan.bus_load <= max_load
    plan.fastest_period_s = plan.time_per_period_s / max_load
    if not plan.fits:
        plan.advice.append(
            f"the PDO set needs {plan.time_per_period_s * 1e6:.1f} us of bus time per period: "
            f"{plan.bus_load * 100:.0f}% of Ts = {ts_s * 1e6:.1f} us (limit {max_load * 100:.0f}%)"
        )
        plan.advice.append(f"real time on this bus needs Ts >= {plan.fastest_period_s * 1e6:.1f} us")
        plan.advice.append(
            "or run lockstep (the default): the plant waits for each command, so any period "
            "is emulated exactly, only slower than real time"
        )
        if period_mark == "sync":
            if frames == "default" and fd:
                one = make_plan(bitrate, ts_s, fd, data_bitrate, max_load, trace_pdos, trace_decimation, "single_frame")
                plan.advice.append(
                    f"or the measurement's REAL32 values in one 16-byte CAN FD frame ([frames] measurement = "
                    f'"single_frame"; --frames single_frame): {one.time_per_period_s * 1e6:.1f} us per period '
                    f"({'fits' if one.fits else 'still does not fit'}; fastest {one.fastest_period_s * 1e6:.1f} us)"
                )
            if frames == "default":
                small = make_plan(bitrate, ts_s, fd, data_bitrate, max_load, trace_pdos, trace_decimation, "compact")
                plan.advice.append(
                    f'or the compact measurement frame ([frames] measurement = "compact"; --frames compact): one '
                    f"frame instead of two, {small.time_per_period_s * 1e6:.1f} us per period "
                    f"({'fits' if small.fits else 'still does not fit'}; fastest {small.fastest_period_s * 1e6:.1f} us)"
                )
            least = make_plan(
                bitrate, ts_s, fd, data_bitrate, max_load, trace_pdos, trace_decimation, "compact", "measurement"
            )
            plan.advice.append(
                f'or the compact frame as the period\'s mark, no SYNC frame ([frames] period_mark = "measurement"; '
                f"--frames compact --period-mark measurement): {least.time_per_period_s * 1e6:.1f} us per period "
                f"({'fits' if least.fits else 'still does not fit'}; fastest {least.fastest_period_s * 1e6:.1f} us)"
            )
        if not fd:
            fd_plan = make_plan(bitrate, ts_s, True, 5e6, max_load, trace_pdos, trace_decimation, frames, period_mark)
            plan.advice.append(
                f"or CAN FD at {bitrate / 1e6:g}/5 Mbit/s: {fd_plan.time_per_period_s * 1e6:.1f} us "
                f"per period ({'fits' if fd_plan.fits else 'still does not fit'}; fastest "
                f"{fd_plan.fastest_period_s * 1e6:.1f} us)"
            )
        if trace_pdos:
            plan.advice.append("or fewer / more decimated trace PDOs (--trace-pdos, --trace-decimation)")
    return plan


def format_plan(plan: Plan) -> str:
    lines = [
        f"bus: {'CAN FD' if plan.fd else 'classic CAN'} {plan.bitrate / 1e6:g} Mbit/s"
        + (f", data phase {plan.data_bitrate / 1e6:g} Mbit/s" if plan.fd and plan.data_bitrate else "")
        + f"; control period Ts = {plan.ts_s * 1e6:.2f} us",
        f"frames per period ({plan.frame_set}; worst-case bit stuffing):",
    ]
    for f in plan.frames:
        lines.append(
            f"  {f.what:<28} {f.data_bytes:2d} bytes x {f.per_period:g}  {f.bits:4d} bits  {f.time_s * 1e6:7.2f} us"
        )
    lines.append(f"bits per period: {plan.bits_per_period:.0f}")
    lines.append(f"bus time per period: {plan.time_per_period_s * 1e6:.2f} us; bus load {plan.bus_load * 100:.1f}%")
    lines.append(
        f"fits in real time: {'yes' if plan.fits else 'NO'} (max load {plan.max_load * 100:.0f}%); "
        f"fastest period: {plan.fastest_period_s * 1e6:.2f} us"
    )
    lines += [f"  - {a}" for a in plan.advice]
    return "\n".join(lines)
