"""Fault checks in the style of `bench reproduce`: each injects one fault kind into a run of the
loop, runs the same scenario without it, and judges the nodes' reaction against what a real drive
and inverter must do. Every number is measured from the two runs (traces, the fault report, the
EMCYs on the bus); the expectations are the bench's design (docs/FAULTS.md), each stated below. The scenario
the checks run and its variants: bench/faults/scenario.py.

    from bench.faults.checks import run_checks
    for c in run_checks("direct"): print(c.check_id, c.ok, c.measured)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from bench.claims import Run, run_raw
from bench.faults.measure import RECOVERS, at, back, emcys, held, recovered, recovery, settling_bound
from bench.faults.scenario import STEP_AT, Law, base, with_command_timeout, with_fault


@dataclass
class FaultCheck:
    check_id: str
    fault: str  # what was injected
    expectation: str  # what a real drive / inverter must do
    measured: dict[str, Any]
    ok: bool
    bus: str
    details: dict[str, Any] = field(default_factory=dict)
    runs: list[Run] = field(default_factory=list, repr=False, compare=False)  # fault-free first when there is one

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "runs"}


_RUNS: list[Run] = []


def _run(raw: dict[str, Any], bus: str) -> Run:
    r = run_raw(raw, bus)
    _RUNS.append(r)
    return r


def _pair(raw: dict[str, Any], faulted: dict[str, Any], bus: str) -> tuple[Run, Run]:
    return _run(raw, bus), _run(faulted, bus)


def check_drop_command(bus: str, law: Law) -> FaultCheck:
    p = STEP_AT + 1  # the first command after the deadbeat step's large one
    raw = with_command_timeout(base("fc-drop-command", law=law))
    f = {"kind": "drop", "frame": "drive.TPDO1", "at_period": p}
    clean, hit = _pair(raw, with_fault(raw, ["frames_lost"], f), bus)
    h = held(hit)
    rec, n = recovery(hit, clean, p + 1), settling_bound(clean)
    return FaultCheck(
        "drop-command",
        f"the drive's voltage command of period {p} dropped on the bus (the one after the step's large one)",
        "the plant holds the last command for exactly one period (status bit 3), and the loop is within 5 % of "
        "the fault-free trace within its own step's settling periods (2 for a deadbeat law) after the first "
        "sample that shows it",
        {"held_periods": h, **rec, "bound_periods": n},
        h == [p + 1] and n is not None and rec["periods_to_5pct"] <= n,
        bus,
    )


def check_delay_command(bus: str, law: Law) -> FaultCheck:
    p = STEP_AT + 1
    raw = with_command_timeout(base("fc-delay-command", law=law))
    f = {"kind": "delay", "frame": "drive.TPDO1", "at_period": p, "delay_periods": 1}
    clean, hit = _pair(raw, with_fault(raw, ["frames_lost", "ok"], f), bus)
    h = held(hit)
    late = hit.result.summary["counters"]["plant_late_commands"]
    itf = hit.result.summary["bus_stats"]["interference"]["frames"]  # the late command is the drive's own frame
    rec, n = recovery(hit, clean, p + 1), settling_bound(clean)
    return FaultCheck(
        "delay-command",
        f"the command of period {p} delayed by one period",
        "it arrives after the SYNC it was meant for: the plant holds the last command for that one period, counts "
        "the late command, never applies it (the next command has arrived by the following SYNC), and the late "
        "frame is not taken for interference; the loop is "
        "within 5 % of the fault-free trace within its own step's settling periods (2 for a deadbeat law) after "
        "the first sample that shows it",
        {"held_periods": h, "plant_late_commands": late, "interference_frames": itf, **rec, "bound_periods": n},
        h == [p + 1] and late is not None and late >= 1 and itf == 0 and n is not None and rec["periods_to_5pct"] <= n,
        bus,
    )


def check_duplicate_measurement(bus: str, law: Law) -> FaultCheck:
    p = STEP_AT + 2
    raw = base("fc-duplicate-measurement", law=law)
    f = {"kind": "duplicate", "frame": "plant.TPDO2", "at_period": p}
    clean, hit = _pair(raw, with_fault(raw, ["ok"], f), bus)
    late = emcys(hit, "meas_late", "drive")
    same = all(np.array_equal(hit.tr[c], clean.tr[c], equal_nan=True) for c in ("iq_A", "id_A", "vd_V", "vq_V"))
    return FaultCheck(
        "duplicate-measurement",
        f"the plant's sample frame (TPDO2, which triggers the current step) of period {p} sent twice",
        "the drive steps once per sample: the second copy is counted late (EMCY 0xFF02, reason 3 duplicate), "
        "and the currents and voltages are those of the fault-free run, bit for bit",
        {
            "late_emcy_periods": [e["period"] for e in late],
            "late_reasons": [e["data"][4:6] for e in late],
            "traces_equal": same,
        },
        at(late, p) and same and "03" in [e["data"][4:6] for e in late],
        bus,
    )


def check_reorder_measurement(bus: str, law: Law) -> FaultCheck:
    p = STEP_AT + 2
    raw = base("fc-reorder-measurement", law=law)
    f = {"kind": "reorder", "frame": "plant.TPDO1", "at_period": p}
    clean, hit = _pair(raw, with_fault(raw, ["ok"], f), bus)
    late = emcys(hit, "meas_late", "drive")
    rec = recovered(hit, clean, p, 1.0)
    return FaultCheck(
        "reorder-measurement",
        f"the currents frame (TPDO1) of period {p} delivered after the sample frame (TPDO2)",
        "the drive steps on the sample with the last currents it has and says so (EMCY 0xFF02, reason 2: "
        f"TPDO2 without a fresh TPDO1), then the late currents (reason 1); {RECOVERS}",
        {"late_emcy_periods": [e["period"] for e in late], "late_reasons": [e["data"][4:6] for e in late], **rec},
        at(late, p) and back(rec),
        bus,
    )


def check_drop_sync(bus: str, law: Law) -> FaultCheck:
    p = STEP_AT + 5
    raw = base("fc-drop-sync", law=law)
    clean, hit = _pair(raw, with_fault(raw, ["ok"], {"kind": "drop", "frame": "SYNC", "at_period": p}), bus)
    late = emcys(hit, "meas_late", "drive")
    same = all(np.array_equal(hit.tr[c], clean.tr[c], equal_nan=True) for c in ("iq_A", "vq_V"))
    return FaultCheck(
        "drop-sync",
        f"the SYNC of period {p} lost on the drive's side",
        "the drive notices the measurement belongs to a SYNC it did not see (EMCY 0xFF02, reason 4) and still "
        "steps on it: the loop is unchanged",
        {"late_emcy_periods": [e["period"] for e in late], "traces_equal": same},
        len(late) == 1 and at(late, p) and same,
        bus,
    )


def check_short_measurement(bus: str, law: Law) -> FaultCheck:
    p = STEP_AT + 5
    raw = base("fc-short-measurement", law=law)
    f = {"kind": "corrupt", "frame": "plant.TPDO1", "at_period": p, "dlc": 4}
    clean, hit = _pair(raw, with_fault(raw, ["ok"], f), bus)
    length = emcys(hit, "pdo_length", "drive")
    rec = recovered(hit, clean, p, 1.0)
    return FaultCheck(
        "short-measurement",
        f"the currents frame of period {p} sent with DLC 4 instead of 8",
        "the drive refuses the PDO (CiA 301 EMCY 0x8210, PDO not processed: length error), steps with the last "
        f"currents; {RECOVERS}",
        {"length_emcy_periods": [e["period"] for e in length], **rec},
        len(length) == 1 and at(length, p) and back(rec),
        bus,
    )


def check_non_finite_measurement(bus: str, law: Law) -> FaultCheck:
    raw = base("fc-non-finite", law=law)
    raw["events"][0]["references"]["iq_ref_A"] = 1.5  # i_b settles at 1.3 A (the rotor's angle)
    clean = _run(raw, bus)
    # a period where i_b is in [1, 2) A: its float's exponent is 0x7F, and flipping bit 30 makes it 0xFF (inf/NaN)
    ib = clean.tr["i_b_A"]
    where = np.flatnonzero((np.abs(ib) >= 1.0) & (np.abs(ib) < 2.0))
    if len(where) == 0:  # a law that never drives i_b there (open loop, a law of 0 V): nothing to corrupt
        return FaultCheck(
            "non-finite-measurement",
            "bit 30 of i_b_A flipped in the currents frame of the first period with 1 A <= |i_b| < 2 A",
            "a period to corrupt: the 1.5 A step drives i_b into [1, 2) A",
            {"note": "the law never drove |i_b| into [1, 2) A: not judged", "max_i_b_A": float(np.nanmax(np.abs(ib)))},
            False,
            bus,
        )
    p = int(clean.tr["period"][where[0]])
    f = {"kind": "corrupt", "frame": "plant.TPDO1", "at_period": p, "bit": 62}
    hit = _run(with_fault(raw, ["ok"], f), bus)  # the recorder (side a) sees the frame as the plant sent it
    nf = emcys(hit, "non_finite", "drive")
    rejected = int(np.nanmax(hit.tr["Safe_state_non_finite_rejected"]))
    vq_ok = bool(np.all(np.isfinite(hit.tr["vq_V"][hit.tr["period"] >= p])))
    rec = recovered(hit, clean, p, 1.5)
    return FaultCheck(
        "non-finite-measurement",
        f"bit 30 of i_b_A flipped in the currents frame of period {p} (the value becomes non-finite)",
        "the drive rejects the value (steps with the last good current), counts it (0x2209:06) and says so (EMCY "
        "0xFF05); its commands stay finite; " + RECOVERS,
        {"non_finite_emcy_periods": [e["period"] for e in nf], "rejected": rejected, "commands_finite": vq_ok, **rec},
        len(nf) == 1 and at(nf, p) and rejected == 1 and vq_ok and back(rec),
        bus,
    )


def check_measurement_timeout(bus: str, law: Law) -> FaultCheck:
    p, n = STEP_AT + 10, 6
    raw = with_command_timeout(base("fc-meas-timeout", law=law))
    f = {"kind": "drop", "frame": "plant.TPDO2", "at_period": p, "periods": n}
    hit = _run(with_fault(raw, ["frames_lost"], f), bus)
    safe = emcys(hit, "safe_meas_timeout", "drive")
    tr = hit.tr
    after = tr["period"] >= p + n
    reason = tr["Safe_state_reason"]
    return FaultCheck(
        "measurement-timeout",
        f"the sample frame (TPDO2) dropped for {n} periods from period {p}",
        "after 0x2209:01 meas_timeout_periods (3) SYNCs without a measurement the drive enters its safe state "
        "(EMCY 0xFF03), commands zero voltage at once and keeps it (latched until 0x2209:05 clear)",
        {
            "safe_state_emcy_periods": [e["period"] for e in safe],
            "vq_after_V": float(np.nanmax(np.abs(tr["vq_V"][after]))),
            "reason_after": int(np.nanmax(reason[after])),
        },
        [e["period"] for e in safe] == [p + 2]
        and float(np.nanmax(np.abs(tr["vq_V"][after]))) == 0.0
        and int(np.nanmin(reason[after])) == 1,
        bus,
    )


def freeze_timeout_us(bus: str) -> int:
    """The plant's command timeout for the freeze check: 600 ms against the nodes' 1 s heartbeat-consumer time;
    where the bus gives its nodes a longer consumer time (the CAN box: 5 s, BOX_CONSUMER_MS) half of it. A stall
    of the loop longer than the timeout elsewhere in the run holds a command the fault did not cause, the freeze
    plus a stall longer than the consumer time loses the drive: half the consumer time bounds both stalls alike
    (in the box under two busy loops a 0.6 s timeout held period 56 too, issue 52)."""
    from bench.run.bus.buses import choose_bus

    return max(600_000, choose_bus(bus, faults=True).consumer_ms(1000) * 1000 // 2)


def check_freeze_drive(bus: str, law: Law) -> FaultCheck:
    # n x the command timeout (plus up to one heartbeat period) well within the heartbeat consumer time (1 s; the
    # CAN box's 5 s: freeze_timeout_us)
    # that the frozen drive's silence must not reach; each the longest it can be: a loaded machine's stall
    # beyond it elsewhere in the run would hold a command the fault did not cause
    p, n = STEP_AT + 10, 1
    raw = with_command_timeout(base("fc-freeze-drive", law=law), freeze_timeout_us(bus))
    clean, hit = _pair(
        raw, with_fault(raw, ["frames_lost"], {"kind": "freeze", "node": "drive", "at_period": p, "periods": n}), bus
    )
    h = held(hit)
    return FaultCheck(
        "freeze-drive",
        f"the drive frozen for {n} periods from period {p} (it neither runs nor hears)",
        f"the plant holds the last command for exactly those {n} periods (command timeout) and the loop goes on",
        {"held_periods": h, "status": hit.result.status},
        h == list(range(p + 1, p + 1 + n)),
        bus,
    )


def _hb_raw(law: Law, name: str) -> dict[str, Any]:
    # long enough for heartbeats (100 ms) and the consumer time (1 s) on the loop's time: 40 000 x 55 us
    return base(name, periods=40_000, law=law)


def check_heartbeat_loss(bus: str, law: Law) -> FaultCheck:
    p = 5_000  # after the first heartbeats (monitoring starts at the first one, CiA 301)
    raw = _hb_raw(law, "fc-heartbeat-loss")
    f = {"kind": "silence_heartbeat", "node": "plant", "at_period": p, "periods": 30_000}
    hit = _run(with_fault(raw, ["ok"], f), bus)
    ts = hit.result.summary["Ts_s"]
    rep = hit.result.summary["faults"]["injected"][0]
    safe = emcys(hit, "safe_heartbeat", "drive")
    first_drop = rep["first_period"]
    # the last heartbeat the drive heard went out one producer time before the first one dropped
    hb_s, consumer_s = 0.1, 1.0
    react_s = (safe[0]["period"] - first_drop) * ts + hb_s if safe else None
    tr = hit.tr
    after = tr["period"] > (safe[0]["period"] if safe else 1 << 60)
    return FaultCheck(
        "heartbeat-loss",
        f"the plant's heartbeat kept from the drive from period {p} for 30 000 periods",
        "the drive's heartbeat consumer (0x1016, 1 s) times out: EMCY 0x8130 and its safe state (EMCY 0xFF04), "
        "zero voltage, within the consumer time plus one period of the last heartbeat heard",
        {
            "safe_state_emcy_periods": [e["period"] for e in safe],
            "reaction_s": react_s,
            "bound_s": consumer_s + ts,
            "vq_after_V": float(np.nanmax(np.abs(tr["vq_V"][after]))) if after.any() else None,
        },
        bool(safe)
        and react_s is not None
        and react_s <= consumer_s + ts
        and after.any()
        and float(np.nanmax(np.abs(tr["vq_V"][after]))) == 0.0,
        bus,
        {"Ts_s": ts, "first_dropped_heartbeat_period": first_drop},
    )


def check_kill(bus: str, law: Law, node: str) -> FaultCheck:
    p = 5_000
    raw = _hb_raw(law, f"fc-kill-{node}")
    hit = _run(with_fault(raw, ["node_lost"], {"kind": "kill", "node": node, "at_period": p}), bus)
    s = hit.result.summary
    other = "drive" if node == "plant" else "plant"
    lost = emcys(hit, "heartbeat", other)
    safe = emcys(hit, "safe_heartbeat", "drive") if node == "plant" else []
    stopped = s["stopped"] or {}
    ok = s["status"] == "node_lost" and stopped.get("node") == node and bool(lost)
    if node == "plant":
        ok = ok and bool(safe)
    return FaultCheck(
        f"kill-{node}",
        f"the {node} killed at period {p}",
        f"the bench names the {node} lost at once (node_lost, exit 8); the {other} reports the lost heartbeat "
        "(EMCY 0x8130) after its consumer time"
        + (
            "; the drive enters its safe state (EMCY 0xFF04, zero voltage)"
            if node == "plant"
            else "; the plant keeps waiting in lockstep (simulated time stands still without commands)"
        ),
        {
            "status": s["status"],
            "stopped_node": stopped.get("node"),
            "at_period": stopped.get("at_period"),
            f"{other}_heartbeat_emcy": bool(lost),
            "drive_safe_state_emcy": bool(safe),
        },
        ok,
        bus,
    )


def check_reset_drive(bus: str, law: Law) -> FaultCheck:
    p = 5_000
    raw = _hb_raw(law, "fc-reset-drive")
    hit = _run(with_fault(raw, ["node_lost"], {"kind": "reset", "node": "drive", "at_period": p}), bus)
    s = hit.result.summary
    stopped = s["stopped"] or {}
    return FaultCheck(
        "reset-drive",
        f"an NMT reset-node for the drive at period {p} (its application restarts, as after a watchdog reset)",
        "the drive boots to pre-operational with its defaults; the bench names it lost (left OPERATIONAL)",
        {"status": s["status"], "stopped": stopped.get("message")},
        s["status"] == "node_lost" and stopped.get("node") == "drive" and stopped.get("at_period") == p,
        bus,
    )


CHECKS: dict[str, Callable[[str, Law], FaultCheck]] = {
    "drop-command": check_drop_command,
    "delay-command": check_delay_command,
    "duplicate-measurement": check_duplicate_measurement,
    "reorder-measurement": check_reorder_measurement,
    "drop-sync": check_drop_sync,
    "short-measurement": check_short_measurement,
    "non-finite-measurement": check_non_finite_measurement,
    "measurement-timeout": check_measurement_timeout,
    "freeze-drive": check_freeze_drive,
    "heartbeat-loss": check_heartbeat_loss,
    "kill-drive": lambda bus, law: check_kill(bus, law, "drive"),
    "kill-plant": lambda bus, law: check_kill(bus, law, "plant"),
    "reset-drive": check_reset_drive,
}


def run_checks(bus: str = "direct", only: list[str] | None = None, law: Law = ()) -> list[FaultCheck]:
    out = []
    for name in only or list(CHECKS):
        _RUNS.clear()
        c = CHECKS[name](bus, law)
        c.runs = list(_RUNS)
        out.append(c)
    return out
