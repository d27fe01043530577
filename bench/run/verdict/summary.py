"""summary.json of a run, and its verdict: built from what the decoder and the statistics
saw on the bus (the same for `bench run` and `bench replay` of its log).

Status (one word, and a distinct exit code for each bad one):
  ok           nothing below
  non_finite   a NaN or an infinity arrived in a PDO (a frame that arrived is never "lost")
  diverged     a phase current beyond what the inverter can drive through the winding
               (2 x (2/3 Vdc + back-EMF) / R): the loop ran away with the plant's trip off
  tripped      the plant's over-current trip latched (Measurement.status bit 0, or trip_active)
  frames_lost  a SYNC counter gap, a period without its measurement or command, a wrong sample index,
               or a lockstep loop that stalled with both nodes alive
  node_lost    a node died or went silent mid-run (process exit, heartbeat timeout, left OPERATIONAL,
               EMCY 0x8130 from the other): the run stopped there, named the node, kept what it had
  interference a frame the loop did not send on one of its own identifiers (a second SYNC producer, a
               duplicate measurement or command): the nodes may have acted on it
  law_fault    the drive refused its current law's command (non-finite or beyond Vmax_V) or, on a bare-metal
               target, its step overran the period: EMCY safe_law_output / safe_overrun, its safe state
  realtime_overrun  a real-time run whose plant counted overruns (plant.eds "Realtime timing": a command not at
               the plant by the next SYNC deadline, or a SYNC more than a period late); before frames_lost at the
               same period: in real time a command that misses its period is also missing from it
  plant_fault  the plant's own model failed (an FMU's doStep returned an error: EMCY model_fault 0xFF20); the
               plant switched its inverter off and stopped stepping the model; the frames up to there are kept
A real-time run's summary has a "realtime" block: the plant's timing record and the bus-side timing
(bench/run/verdict/realtime.py); a lockstep run's has none.
A scenario may expect a bad status (scenario.expect); the run then passes when it gets it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bench.canbus import classic_frame_bits, fd_frame_bits
from bench.eds import enum
from bench.laws import law_info, law_names
from bench.run.bus.frames import FDF, is_fd
from bench.run.decode.decoder import Decoder
from bench.run.loop.reads import CONTROLLER_VALUES, PLANT_VALUES, STEP_COST
from bench.scenario import STATUSES

SCHEMA_VERSION = 2
EXIT_CODES = {
    "ok": 0,
    "tripped": 3,
    "diverged": 4,
    "non_finite": 5,
    "frames_lost": 6,
    "node_lost": 8,
    "interference": 9,
    "law_fault": 10,
    "realtime_overrun": 11,
    "plant_fault": 12,
}
EXIT_EXPECTATION_NOT_MET = 7
assert set(EXIT_CODES) == set(STATUSES)
# at the same period, the root cause first
PRIORITY = (
    "plant_fault",
    "node_lost",
    "interference",
    "non_finite",
    "law_fault",
    "diverged",
    "tripped",
    "realtime_overrun",
    "frames_lost",
)


def _num(v: float | None) -> float | int | None:
    if v is None:
        return None
    return int(v) if float(v).is_integer() and abs(v) < 2**53 else float(v)


def step_cost(dec: Decoder) -> dict[str, Any] | None:
    """The drive's step cost as read at the end of the run (None when it was not read, or has no counter):
    cycles of its counter and, from its clock, seconds. On the QEMU image (-icount shift=0) one second of
    virtual time is 10^9 instructions (bench/mcu.py)."""
    _, obj, names = STEP_COST
    v = {n: dec.sdo.drive.get(obj, n) for n in names}
    clock = v["cycle_clock_Hz"]
    if not clock or v["step_cycles_mean"] is None:
        return None
    return {
        **{n: _num(x) for n, x in v.items()},
        "controller": law_name(dec.sdo.drive.get("Controller", "controller") or 0),
        "step_mean_s": float(v["step_cycles_mean"]) / float(clock),
        "step_max_s": float(v["step_cycles_max"] or 0) / float(clock),
    }


def law_name(value: float | None, eds: Path | None = None) -> str | None:
    """The law's value name of a Controller.controller value (None: not read, or not a value)."""
    names = law_names(eds)
    return names[int(value)] if value is not None and 0 <= int(value) < len(names) else None


def identified(dec: Decoder, eds: Path | None = None) -> dict[str, Any]:
    """Per-law results (its record's Results, bench/laws.py); a value whose ValidIf entry is zero is
    None, with that entry's NotApplicableNote; a law without results (no record, or `Results.<law>=` empty: the
    PI) says it identifies nothing."""
    kind = law_name(dec.sdo.drive.get("Controller", "controller"), eds) or "unknown"
    out: dict[str, Any] = {"controller": kind}
    info = law_info(kind, eds) if kind != "unknown" else None
    if info is None or info.record is None or not info.results:
        out["paper"] = info.source if info is not None else None
        out["note"] = f"not applicable: the {kind} controller identifies nothing"
        return out
    out["paper"] = info.source
    obj = info.record
    vals = {s: _num(dec.sdo.drive.get(obj, s)) for s in info.results}
    off = {c for c in dict.fromkeys(info.valid_if.values()) if not _num(dec.sdo.drive.get(obj, c))}
    for s in vals:
        if info.valid_if.get(s) in off:
            vals[s] = None
    notes = [info.notes[c] for c in sorted(off, key=list(info.valid_if.values()).index) if c in info.notes]
    if notes:
        out["note"] = "; ".join(notes)
    out.update(vals)
    return out


def plant_values(dec: Decoder) -> dict[str, float | int | None]:
    return {s: _num(dec.sdo.plant.get(obj, s)) for obj, subs in PLANT_VALUES for s in subs}


def divergence_bound_A(plant: dict[str, Any]) -> float | None:
    R, vdc = plant.get("R_ohm"), plant.get("Vdc_V")
    if not R or not vdc:
        return None
    emf = 0.0
    if plant.get("mech_mode") == enum("plant", "Motor model", "mech_mode")["imposed_speed"]:
        emf = (
            abs(plant.get("omega_imposed_rad_s") or 0.0) * (plant.get("pole_pairs") or 1) * (plant.get("psi_Wb") or 0.0)
        )
    return 2.0 * (2.0 / 3.0 * vdc + emf) / R


def bus_stats(dec: Decoder, bits_total: int) -> dict[str, Any]:
    st = dec.stats
    n = max(1, st.periods)

    cont = {
        "sync_counter_gaps": st.sync_counter_gaps,
        "missing_measurements": st.missing_measurements,
        "missing_commands": st.missing_commands,
        "sample_index_mismatches": st.sample_index_mismatches,
    }
    ts = dec.ts_s

    def by_id(d: dict[int, int]) -> dict[str, int]:
        top = sorted(d.items(), key=lambda kv: -kv[1])
        out = {f"0x{k:03X}": v for k, v in top[:32]}
        if len(top) > 32:
            out["others"] = sum(v for _, v in top[32:])
        return out

    return {
        "frames": st.frames,
        "frames_per_period": st.frames / n,
        "lost_frames": sum(cont.values()),
        **cont,
        "foreign_frames": {"frames": sum(st.foreign.values()), "by_cob_id": by_id(st.foreign)},
        "interference": {
            "frames": sum(st.interference.values()),
            "by_cob_id": by_id(st.interference),
            "first_period": st.first_interference_period,
        },
        "after_loop_frames": st.after_loop_frames,
        "non_finite_values": dict(st.non_finite),
        "plant_missed_commands": _num(dec.sdo.plant.get("Run control", "missed_commands")),
        "plant_late_commands": _num(dec.sdo.plant.get("Run control", "late_commands")),
        "drive_lost_measurements": _num(dec.sdo.drive.get("Drive status", "lost_measurements")),
        "drive_late_measurements": _num(dec.sdo.drive.get("Drive status", "late_measurements")),
        "bits_per_period_worst_case": bits_total / n,
        "bus_load_1Mbit_at_Ts": bits_total / n / 1e6 / ts,
    }


def frame_bits(frames: np.ndarray) -> int:
    """Worst-case bits of these frames (by length): a classic frame's on a classic CAN bus; a CAN FD frame's (in a
    run with CAN FD PDOs) both phases' bits, as `bench plan` counts them. summary.json's bus_load_1Mbit_at_Ts then
    takes both phases at 1 Mbit/s (CAN FD without the bit-rate switch); the time on a bus with a data phase depends
    on the two rates: `bench plan --from-log` gives it."""
    fd = frames["flags"] & FDF != 0 if is_fd(frames) else np.zeros(len(frames), dtype=bool)
    counts = np.bincount(frames["dlc"][~fd], minlength=9)[:9]
    bits = sum(int(c) * classic_frame_bits(d) for d, c in enumerate(counts))
    fd_counts = np.bincount(frames["dlc"][fd], minlength=65)
    return int(bits + sum(int(c) * sum(fd_frame_bits(d)) for d, c in enumerate(fd_counts) if c))


def verdict(
    flags: dict[str, Any], expect: tuple[str, ...], first: dict[str, int | None] | None = None
) -> tuple[str, int, bool]:
    """(status, exit code, expected) from the flags a run raised: the one that happened first (a
    divergence that trips, then sends NaN, is "diverged"); at the same period, PRIORITY's order."""
    first = first or {}
    raised = [s for s in PRIORITY if flags.get(s)]
    raised.sort(key=lambda s: (first.get(s) if first.get(s) is not None else float("inf"), PRIORITY.index(s)))
    status = raised[0] if raised else "ok"
    if status in expect:
        return status, 0, True
    return status, EXIT_CODES[status] if status != "ok" else EXIT_EXPECTATION_NOT_MET, False


def build_summary(
    dec: Decoder,
    *,
    scenario: str,
    bus: str,
    status: str,
    expected: bool,
    expect: tuple[str, ...],
    flags: dict[str, bool],
    stopped: dict[str, Any] | None,
    first_trip_period: int | None,
    oscillating: list[int],
    max_phase_A: float,
    bound_A: float | None,
    steps: list[dict[str, Any]],
    bstats: dict[str, Any],
    timing: dict[str, float],
    links: dict[str, dict[str, Any]],
) -> dict[str, Any]:
    """summary.json (without "faults"): the verdict, the steps, what the bus showed of both nodes; a real-time
    run's "realtime" block, which LoopWatch.judge left in `bstats` (it has the chunks' time stamps)."""
    ctl = dec.sdo.drive
    rt = bstats.pop("realtime", None)
    out = {
        "schema_version": SCHEMA_VERSION,
        "scenario": scenario,
        "bus": bus,
        "node_ids": {st.name: st.node_id for st in dec.sdo.states},  # the nodes' IDs on the bus (bench plan reads them)
        "status": status,
        "status_expected": expected,
        "expect": list(expect),
        "status_flags": flags,
        "stopped": stopped,
        "emcy": dec.emcy[:100],
        # from the master's NMT Stop that ends the run on: its frames and EMCYs, never judged (decoder.py)
        "teardown": {"frames": dec.stats.teardown_frames, "emcy": dec.teardown_emcy[:100]},
        "first_trip_period": first_trip_period,
        "first_non_finite_period": dec.stats.first_non_finite_period,
        "oscillating_steps": oscillating,
        "max_phase_current_A": max_phase_A,
        "divergence_bound_A": bound_A,
        "periods": dec.stats.periods,
        "Ts_s": dec.ts_s,
        "steps": steps,
        "identified": identified(dec),
        "step_cost": step_cost(dec),
        "plant": plant_values(dec),
        "controller": {n: ctl.get("Controller", n) for n in CONTROLLER_VALUES},
        "counters": {
            "plant_missed_commands": dec.sdo.plant.get("Run control", "missed_commands"),
            "plant_late_commands": dec.sdo.plant.get("Run control", "late_commands"),
            "plant_period_index": dec.sdo.plant.get("Run control", "period_index"),
            "plant_outside_map_periods": dec.sdo.plant.get("Run control", "outside_map_periods"),
            "drive_current_steps": ctl.get("Drive status", "current_steps"),
            "drive_lost_measurements": ctl.get("Drive status", "lost_measurements"),
            "drive_late_measurements": ctl.get("Drive status", "late_measurements"),
        },
        "settings": [
            {"period": w.period, "node": w.node, "name": w.name, "value": w.value}
            for w in dec.sdo.writes
            if w.period > 0
        ],
        "bus_stats": bstats,
        "timing": timing,
        # each SocketCAN interface (kind, state, bit rate, error counters) before and after the run
        "can_links": links,
    }
    if rt is not None:
        out["realtime"] = rt
    return out


def format_table(summary: dict[str, Any]) -> str:
    """The step table; the tuning column (Online tuning.enable, as the bus showed it) when the run switched it on."""
    tuned = any(s.get("tuning_on") for s in summary.get("steps", []))
    lines = [
        f"{'step':<8}{'at':>7}{'from->to A':>14}{'settle':>8}{'overshoot':>16}{'ss err A':>11}"
        + (f"{'tuning':>8}" if tuned else "")
    ]
    for s in summary["steps"]:
        settle = "-" if s["periods_to_settle"] is None else str(s["periods_to_settle"])
        lines.append(
            f"{s['signal']:<8}{s['at_period']:>7}{s['from_A']:>7.2f}->{s['to_A']:<6.2f}{settle:>8}"
            f"{s['overshoot_A']:>9.3f} A {s['overshoot_pct']:>4.1f}%{s['steady_state_error_A']:>11.2e}"
            + (f"{('on' if s.get('tuning_on') else 'off'):>8}" if tuned else "")
        )
    if not summary["steps"]:
        lines.append("(no reference step in this run)")
    return "\n".join(lines)


def format_identified(ident: dict[str, Any]) -> str:
    values = {k: v for k, v in ident.items() if k not in ("controller", "paper", "note")}
    if not values:
        return f"identified: {ident.get('note', 'not applicable')}"
    parts = []
    for k, v in values.items():
        if v is None:
            parts.append(f"{k} n/a")
        elif isinstance(v, float):
            parts.append(f"{k} {v:.6g}")
        else:
            parts.append(f"{k} {v}")
    who = f"{ident['paper']}, {ident['controller']}" if ident.get("paper") else str(ident.get("controller"))
    line = f"identified ({who}): " + ", ".join(parts)
    return line + (f"\n  ({ident['note']})" if ident.get("note") else "")
