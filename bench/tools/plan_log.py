"""`bench plan --from-log RUN/bus.log`: the frames a run sent, replayed onto a simulated physical CAN bus.

Each frame's length on the wire is exact (bench.tools.wire: its real identifier and payload, stuffed, its CRC
computed), or the worst case of bench/canbus.py's formula with ``worst=True``. The periods start at each SYNC;
the frames before the first SYNC (the configuration by SDO, NMT, boot-up) and those after the last period's loop
frames (the teardown) are left out and counted. Each period is simulated on its own from an idle bus:

* the SYNC is queued at the period start (t = 0); every frame that is neither the SYNC nor a TPDO of the plant
  or the drive (heartbeat, EMCY, SDO, NMT) is queued at the period start too (the worst case for the loop);
* the plant's TPDOs are queued when the SYNC has ended plus the plant's transmit latency;
* the drive's TPDOs when the last plant TPDO it consumes (its RPDOs' COB-IDs) has ended plus the drive's latency;
* arbitration: whenever the bus is idle, the pending frame with the lowest identifier goes; a frame once started
  is not interrupted (an overrun does not carry into the next period: each period says what it needs).

Per period: the bus time (SYNC start to the end of the period's last frame), the end of the causal chain (SYNC
-> the plant TPDOs the drive consumes -> the drive TPDOs the plant consumes) and whether it comes before the
next SYNC (Ts), and the load (the frames' wire time / Ts). Over the run: p50, p99 and max, how many periods miss
the deadline and how many exceed the load limit. Which identifiers are the SYNC, the plant's and the drive's
comes from the EDS files at the run's node-IDs (summary.json "node_ids" when it records them, else the EDS's).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import can
import numpy as np

from bench.tools.plan_periods import LogPlanError, kind_of, loop_ids, read_periods, run_node_ids
from bench.tools.wire import WireBits, classic_stream, exact_bits, worst_bits


@dataclass
class PeriodResult:
    index: int
    frames: int
    bus_time_s: float
    chain_end_s: float
    load: float
    fits: bool  # the chain ends before the next SYNC (and the period has its command)
    has_command: bool = True  # a drive TPDO the plant consumes was in the period (else the chain ends earlier)


@dataclass
class Stats:
    p50: float
    p99: float
    max: float


@dataclass
class LogPlan:
    log: str
    bitrate: float
    data_bitrate: float | None
    fd: bool
    ts_s: float
    ts_from: str
    max_load: float
    latency_s: dict[str, float]
    worst_case_stuffing: bool
    node_ids: dict[str, int]
    node_ids_from: str
    frames: int
    left_out_before: int
    left_out_after: int
    bus_time_s: Stats
    chain_end_s: Stats
    load: Stats
    extra_tpdos: int  # TPDOs per period (median) that the other node does not consume: the trace PDOs
    measurement_frames: int  # plant TPDOs the drive consumes per period (median): 2 by default, 1 compact
    mark: str  # what starts each period: "SYNC", or the plant's measurement frame ("mark (0x190)") without SYNCs
    overruns: int  # periods whose chain ends after the next SYNC
    over_load: int  # periods above max_load
    longer_than_ts: int = 0  # periods whose frames take longer than Ts: on the real bus a backlog grows each period
    no_command: int = 0  # periods without a command frame (a lost one): never counted as fitting
    periods: list[PeriodResult] = field(default_factory=list)
    formula_s: float | None = None  # bench plan's worst-case formula on the EDS PDO set + extra_tpdos, same bus,
    frame_set: str = "default"  # and the measurement frame set the log shows (measurement_frames)

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2)


class WireCache:
    """Each distinct frame's wire bits, computed once. On a CAN FD bus the PDOs of a classic run's log are simulated
    as CAN FD frames with the bit-rate switch, its other frames (SYNC, SDO, NMT, heartbeat, EMCY) as classic frames:
    what the same run sends with frames.can = "fd" (0x2105 switches the PDOs only). A log that holds CAN FD frames is
    simulated as sent (`as_sent`)."""

    def __init__(self, fd: bool, worst: bool, as_sent: bool = False) -> None:
        self.fd, self.worst, self.as_sent = fd, worst, as_sent
        self._bits: dict[tuple[int, bool, bool, bool, bytes], WireBits] = {}

    def bits(self, m: can.Message, pdo: bool = True) -> WireBits:
        if m.is_remote_frame:  # CAN FD has no remote frame: a classic one on either bus, its RTR bit and DLC as sent
            return self._remote(m)
        fd = m.is_fd or (self.fd and pdo and not self.as_sent)
        brs = m.bitrate_switch if m.is_fd else fd  # a classic frame of a classic log rides an FD bus with BRS
        key = (m.arbitration_id, m.is_extended_id, fd, brs, data := bytes(m.data))
        if key not in self._bits:
            if self.worst:
                self._bits[key] = worst_bits(len(data), fd, m.is_extended_id, brs)
            else:
                self._bits[key] = exact_bits(m.arbitration_id, data, fd, m.is_extended_id, brs)
        return self._bits[key]

    def _remote(self, m: can.Message) -> WireBits:
        key = (m.arbitration_id, m.is_extended_id, False, False, b"remote %d" % m.dlc)
        if key not in self._bits:
            exact = classic_stream(m.arbitration_id, b"", m.is_extended_id, True, m.dlc)
            self._bits[key] = worst_bits(0, False, m.is_extended_id, False) if self.worst else exact.wire()
        return self._bits[key]


@dataclass
class PeriodSim:
    bus_time_s: float  # SYNC start to the end of the period's last frame
    chain_end_s: float  # end of the last command (else measurement, else SYNC) frame
    busy_s: float  # the frames' wire time
    order: list[tuple[int, float, float]]  # (frame index, start, end) in the order sent


def simulate_period(frames: list[tuple[int, float]], kinds: list[str], latency: dict[str, float]) -> PeriodSim:
    """One period on an idle bus from the SYNC's start (t = 0; a period without a SYNC: the plant's frames queued
    at its latency). `frames`: (identifier, wire time s) in log order;
    `kinds`: "sync", "measurement" (a plant TPDO the drive consumes), "plant", "command" (a drive TPDO the plant
    consumes), "drive" or "other". `latency`: "plant", "drive" transmit latency, s."""
    ready: list[float | None] = [0.0 if k in ("sync", "other") else None for k in kinds]
    if "sync" not in kinds:  # no SYNC frame ([frames] period_mark): the plant's period starts its measurement
        plant = latency["plant"]
        ready = [plant if k in ("measurement", "plant") else r for k, r in zip(kinds, ready, strict=True)]
    waiting = sum(1 for k in kinds if k == "measurement")
    t, busy, order = 0.0, 0.0, []
    ends: dict[str, float] = {}
    left = set(range(len(frames)))

    def release(node: str, at: float) -> None:
        for j in left:
            if (kinds[j] in ("measurement", "plant")) == (node == "plant") and kinds[j] not in ("sync", "other"):
                ready[j] = at + latency[node]

    while left:
        avail = [i for i in left if (r := ready[i]) is not None and r <= t]
        if not avail:
            later = [r for i in left if (r := ready[i]) is not None]
            if not later:  # a measurement that never came (lost): the drive's frames go now (+ its latency)
                release("plant", t)
                release("drive", t)
                continue
            t = min(later)
            continue
        i = min(avail, key=lambda j: (frames[j][0], j))  # arbitration: the lowest identifier wins
        left.discard(i)
        order.append((i, t, t + frames[i][1]))
        t += frames[i][1]
        busy += frames[i][1]
        ends[kinds[i]] = t
        if kinds[i] == "sync" and "sync_done" not in ends:
            ends["sync_done"] = t
            release("plant", t)
        if kinds[i] == "measurement":
            waiting -= 1
        if (kinds[i] == "measurement" and waiting == 0) or (kinds[i] == "sync" and waiting == 0):
            release("drive", t)
    chain = ends.get("command", ends.get("measurement", ends.get("sync", 0.0)))
    return PeriodSim(t, chain, busy, order)


def _stats(values: np.ndarray) -> Stats:
    return Stats(float(np.percentile(values, 50)), float(np.percentile(values, 99)), float(values.max()))


def check_inputs(
    bitrate: float, data_bitrate: float | None, ts_s: float, latency: dict[str, float], max_load: float
) -> None:
    """Every input in its range (bench plan's checks, and the latencies): a ValueError naming the field, its
    value and the allowed range."""
    from bench.tools.plan import check_inputs as check_bus

    check_bus(bitrate, ts_s, data_bitrate is not None, data_bitrate, max_load, 0, 1)
    for node, lat in latency.items():
        if node not in ("plant", "drive") or not (math.isfinite(lat) and 0 <= lat <= 1.0):
            raise LogPlanError(f"--latency-us = {node}={lat * 1e6:g}: must be plant=US or drive=US, 0 <= US <= 1e6")


def _frame_set(frames: int, longest: int) -> str:
    """The measurement frame set a log shows: two frames, default; one of 8 bytes, compact; one longer, the
    single CAN FD frame."""
    if frames != 1:
        return "default"
    return "compact" if longest <= 8 else "single_frame"


def simulate(
    log: Path,
    bitrate: float,
    data_bitrate: float | None,
    ts_s: float,
    latency: dict[str, float] | None = None,
    max_load: float = 0.8,
    worst: bool = False,
    ts_from: str = "given",
) -> LogPlan:
    """Replay a run's bus.log onto a simulated bus (CAN FD with bit-rate switch when data_bitrate is given);
    `latency`: each node's transmit latency, s (plant, drive; default 0); `worst`: worst-case stuffing."""
    lat = {"plant": 0.0, "drive": 0.0, **(latency or {})}
    check_inputs(bitrate, data_bitrate, ts_s, lat, max_load)
    if not log.is_file():
        raise LogPlanError(f"{log}: no such file")
    fd = data_bitrate is not None
    plant_id, drive_id, ids_from = run_node_ids(log)
    ids = loop_ids(plant_id, drive_id)
    cut = read_periods(log, ids)
    sent_fd = any(m.is_fd for p in cut.periods for m in p)
    if not fd and sent_fd:
        raise LogPlanError(f"{log} holds CAN FD frames: a classic bus cannot carry them (give --fd --data-bitrate)")
    wire = WireCache(fd, worst, as_sent=sent_fd)
    results, extra, meas, meas_bytes = [], [], [], 0
    for n, frames in enumerate(cut.periods):
        kinds = [kind_of(m, ids) for m in frames]
        extra.append(sum(1 for k in kinds if k in ("plant", "drive")))
        meas.append(kinds.count("measurement"))
        meas_bytes = max([meas_bytes] + [len(m.data) for m, k in zip(frames, kinds, strict=True) if k == "measurement"])
        timed = [
            (m.arbitration_id, wire.bits(m, k not in ("sync", "other")).time_s(bitrate, data_bitrate))
            for m, k in zip(frames, kinds, strict=True)
        ]
        sim = simulate_period(timed, kinds, lat)
        cmd = "command" in kinds
        fits = cmd and sim.chain_end_s <= ts_s and sim.bus_time_s <= ts_s
        results.append(PeriodResult(n, len(frames), sim.bus_time_s, sim.chain_end_s, sim.busy_s / ts_s, fits, cmd))
    bus = np.array([r.bus_time_s for r in results])
    chain = np.array([r.chain_end_s for r in results])
    load = np.array([r.load for r in results])
    return LogPlan(
        log=str(log),
        bitrate=bitrate,
        data_bitrate=data_bitrate,
        fd=fd,
        ts_s=ts_s,
        ts_from=ts_from,
        max_load=max_load,
        latency_s=lat,
        worst_case_stuffing=worst,
        node_ids={"plant": plant_id, "drive": drive_id},
        node_ids_from=ids_from,
        frames=cut.frames,
        left_out_before=cut.before,
        left_out_after=cut.after,
        bus_time_s=_stats(bus),
        chain_end_s=_stats(chain),
        load=_stats(load),
        extra_tpdos=int(np.median(extra)),
        measurement_frames=int(np.median(meas)),
        frame_set=_frame_set(int(np.median(meas)), meas_bytes),
        mark="SYNC" if cut.mark == ids.sync else f"mark (0x{cut.mark:03X})",
        overruns=int((chain > ts_s).sum()),
        over_load=int((load > max_load).sum()),
        longer_than_ts=int((bus > ts_s).sum()),
        no_command=sum(not r.has_command for r in results),
        periods=results,
    )


def format_log_plan(plan: LogPlan) -> str:
    """The simulation as text, bench plan's worst-case formula for the same bus beside it when it is known."""
    us = 1e6
    fd = f"CAN FD {plan.bitrate / 1e6:g}/{(plan.data_bitrate or 0) / 1e6:g} Mbit/s (bit-rate switch)"
    bus = fd if plan.fd else f"classic CAN {plan.bitrate / 1e6:g} Mbit/s"
    lines = [
        f"bus: {bus}; Ts = {plan.ts_s * us:.2f} us ({plan.ts_from}); transmit latency plant "
        f"{plan.latency_s['plant'] * us:g} us, drive {plan.latency_s['drive'] * us:g} us; "
        f"{'worst-case' if plan.worst_case_stuffing else 'exact'} bit stuffing",
        f"log: {plan.log}: {plan.frames} frames; {plan.left_out_before} before the first SYNC (configuration) and "
        f"{plan.left_out_after} after the last period's loop frames (teardown) left out; {len(plan.periods)} periods "
        f"(node-IDs plant 0x{plan.node_ids['plant']:02X}, drive 0x{plan.node_ids['drive']:02X}, {plan.node_ids_from})",
        f"{'per period':<28}{'p50':>10}{'p99':>10}{'max':>10}",
    ]
    for name, s, scale in (
        ("bus time (us)", plan.bus_time_s, us),
        (f"{plan.mark.split(' ')[0]}->command end (us)", plan.chain_end_s, us),
        ("load (% of Ts)", plan.load, 100.0),
    ):
        lines.append(f"{name:<28}{s.p50 * scale:>10.2f}{s.p99 * scale:>10.2f}{s.max * scale:>10.2f}")
    n = len(plan.periods)
    lines.append(
        f"the command comes after the next {plan.mark} in {plan.overruns} of {n} periods; the load exceeds "
        f"{plan.max_load * 100:.0f}% in {plan.over_load} of {n}"
    )
    if plan.longer_than_ts:
        lines.append(
            f"the frames of a period take longer than Ts in {plan.longer_than_ts} of {n} periods: each is simulated "
            "from an idle bus; on the real bus the backlog would grow from period to period"
        )
    if plan.no_command:
        lines.append(f"{plan.no_command} of {n} periods have no command frame (lost?): none of them counts as fitting")
    if plan.formula_s is not None:
        lines.append(
            f"bench plan's formula (worst-case stuffing; the EDS PDO set, {plan.frame_set} measurement frame set, + "
            f"{plan.extra_tpdos} trace PDOs): {plan.formula_s * us:.2f} us per period"
        )
    worst = sorted(plan.periods, key=lambda r: -r.bus_time_s)[:3]
    lines.append(
        "longest periods: " + ", ".join(f"#{r.index} {r.bus_time_s * us:.1f} us ({r.frames} frames)" for r in worst)
    )
    return "\n".join(lines)
