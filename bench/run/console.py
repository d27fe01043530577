"""The result of `bench run` (and `bench replay`) printed for a person: the step table, the identified values,
the bus, the EMCYs and notes, the faults, the step cost, a real-time run's timing, and the status line, which
names the first event and its period (bench/run/verdict/summary.py verdict) and why."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.run.sinks import TRACES_FILE


def _ids(by_id: dict[str, int]) -> str:
    return ", ".join(f"{k} x{v}" for k, v in list(by_id.items())[:6]) or "none"


def print_result(out: Path, result: Any) -> None:
    from bench.run.verdict.summary import format_identified, format_table

    s = result.summary
    print(format_table(s))
    print(format_identified(s["identified"]))
    bs = s["bus_stats"]
    nf = bs["non_finite_values"]
    print(
        f"bus: {bs['frames']} frames, {bs['lost_frames']} lost (SYNC gaps {bs['sync_counter_gaps']}, "
        f"missing measurements {bs['missing_measurements']}, missing commands {bs['missing_commands']}), "
        f"plant missed {bs['plant_missed_commands']}, late {bs['plant_late_commands']}"
        + (f"; non-finite values: {', '.join(f'{k} x{v}' for k, v in nf.items())}" if nf else "")
    )
    ff, itf = bs.get("foreign_frames", {}), bs.get("interference", {})
    if ff.get("frames") or itf.get("frames") or bs.get("after_loop_frames"):
        print(
            f"bus: foreign frames {ff.get('frames', 0)} ({_ids(ff.get('by_cob_id', {}))}); interference "
            f"{itf.get('frames', 0)} ({_ids(itf.get('by_cob_id', {}))}); after the loop "
            f"{bs.get('after_loop_frames', 0)}"
        )
    emcy = s.get("emcy") or []
    if emcy:
        shown = ", ".join(f"{e['node']} {e['code']} at period {e['period']}" for e in emcy[:6])
        print(f"EMCY: {len(emcy)}{'+' if len(emcy) >= 100 else ''}: {shown}{' ...' if len(emcy) > 6 else ''}")
    for note in s.get("notes") or []:
        print(f"note: {note}")
    if s.get("faults"):
        from bench.run.verdict.faults import format_faults

        print(format_faults(s["faults"]))
    cost = s.get("step_cost")
    if cost:
        print(
            f"drive step cost ({cost['controller']}, {cost['steps_measured']} steps): mean "
            f"{cost['step_cycles_mean']:.0f}, max {cost['step_cycles_max']:.0f} ticks of its "
            f"{cost['cycle_clock_Hz']:,} Hz counter ({cost['step_mean_s'] * 1e6:.2f} / "
            f"{cost['step_max_s'] * 1e6:.2f} us; on the QEMU image, -icount shift=0: "
            f"{cost['step_mean_s'] * 1e9:.0f} / {cost['step_max_s'] * 1e9:.0f} instructions)"
        )
    if s.get("realtime"):
        print(_realtime_line(s["realtime"]))
    t = s.get("timing", {})
    if t.get("periods_per_s"):
        print(
            f"run: {s['periods']} periods in {t['run_wall_s']:.3f} s ({t['periods_per_s']:,.0f} periods/s, "
            f"decoding included); with configuration {t['wall_s']:.2f} s"
        )
    status = s["status"]
    osc = s.get("oscillating_steps") or []
    reasons: dict[str, Callable[[], str]] = {  # each said only for its status: the others' figures may be None
        "tripped": lambda: (
            f"the plant's over-current trip latched at period {s.get('first_trip_period')} "
            f"(I_trip_A = {s['plant'].get('I_trip_A')}{_reaction(s)})"
        ),
        "diverged": lambda: (
            f"the step at period {osc[0]} never settles: its error still swings over half the step at "
            "the end of its window (an unstable loop held by the voltage limit)"
            if osc
            else f"a phase current of {s['max_phase_current_A']:.3g} A, beyond "
            f"{s['divergence_bound_A']:.3g} A that the inverter can drive through the winding"
        ),
        "non_finite": lambda: f"non-finite values arrived in PDOs: {', '.join(nf)}",
        "frames_lost": lambda: s["stopped"]["message"] if s.get("stopped") else _frames_lost(s),
        "node_lost": lambda: (s.get("stopped") or {}).get("message", ""),
        "interference": lambda: (
            f"{bs.get('interference', {}).get('frames')} frames on the loop's own identifiers that "
            f"the loop did not send ({_ids(bs.get('interference', {}).get('by_cob_id', {}))}), the "
            f"first in period {bs.get('interference', {}).get('first_period')}"
        ),
        "law_fault": lambda: _law_fault(s),
        "realtime_overrun": lambda: _realtime_overrun(s),
        "plant_fault": lambda: _plant_fault(s),
    }
    why = reasons.get(status, lambda: "")()
    at, also = _first_events(s)
    if status == "ok":
        print("status: ok")
    elif result.expected:
        print(f"status: {status}{at} (expected by the scenario): {why}{also}")
    else:
        print(f"status: {status.upper()}{at}: {why} (exit {result.exit_code}){also}")
    if status == "ok" and not result.expected:
        print(f"status: the scenario expected {', '.join(s['expect'])} (exit {result.exit_code})")
    print(f"results in {out}/: {', '.join(_files_written(s, out))}")


def _files_written(s: dict[str, Any], out: Path) -> list[str]:
    """The files summary.json lists (what was written), summary.json first."""
    files = s.get("files")
    if not files:  # a run stopped early whose view helpers were still starting has no recording, no plots
        views = ["run.rrd", "*.svg"] if (out / "run.rrd").exists() else []
        return ["summary.json", TRACES_FILE, "bus.log", *views]
    names = [files.get("log"), files.get("traces"), *files.get("exports", []), files.get("recording")]
    plots = files.get("plots") or []
    shown = ["summary.json", *[n for n in names if n]]
    return shown + (plots if len(plots) <= 3 else [f"{len(plots)} plots (*.svg)"])


def _plant_fault(s: dict[str, Any]) -> str:
    from bench.emcy import emcy_names

    names = emcy_names()
    e = next(
        (e for e in s.get("emcy", []) if e["node"] == "plant" and names.get(int(e["code"], 16)) == "model_fault"), None
    )
    at = f" at period {e['period']}" if e else ""
    return (
        f"the plant's model failed{at} (its FMU's doStep returned an error, EMCY 0xFF20; the plant's log says which): "
        "the inverter was switched off and the model no longer stepped; the frames up to there are kept"
    )


def _law_fault(s: dict[str, Any]) -> str:
    from bench.emcy import emcy_names

    why = {
        "safe_law_output": "a non-finite command or one beyond Vmax_V",
        "safe_overrun": "a step longer than the period",
    }
    names = emcy_names()
    e = next((e for e in s.get("emcy", []) if e["node"] == "drive" and names.get(int(e["code"], 16)) in why), None)
    if e is None:
        return ""
    law = (s.get("identified") or {}).get("controller")
    return (
        f"the drive refused its current law {law} at period {e['period']}: {why[names[int(e['code'], 16)]]} "
        f"(EMCY {e['code']}); it commands 0 V in its safe state from then on"
    )


def _us(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def _realtime_line(rt: dict[str, Any]) -> str:
    """A real-time run's timing in one line: the plant's own figures, then the bus's (summary.json "realtime")."""
    p, bus = rt.get("plant") or {}, rt.get("bus")

    def plant(what: str) -> str:
        return f"p99 {_us(p.get(f'{what}_p99_us'))} max {_us(p.get(f'{what}_max_us'))} us"

    line = (
        f"real time at Ts = {_us(rt.get('period_us'))} us: plant SYNC lateness {plant('sync_lateness')}, "
        f"turnaround {plant('turnaround')}, overruns {p.get('overruns')}, SYNC overruns {p.get('sync_overruns')}"
    )
    floor = rt.get("floor")
    if floor:
        line += f" (the host's floor p99 {floor['p99_us']:g} us)"
    if not bus:
        return line + "; bus: no time stamps"
    lat, tr, iv = bus["sync_lateness_us"], bus["turnaround_us"], bus["sync_interval_us"]
    causes = _causes(rt)
    return (
        f"{line}; bus SYNC lateness p99 {_us(lat['p99'])} max {_us(lat['max'])} us, turnaround p99 {_us(tr['p99'])} "
        f"max {_us(tr['max'])} us, SYNC interval {_us(iv['min'])} .. {_us(iv['max'])} us"
        + (f"; overruns by cause: {causes}" if causes else "")
    )


def _realtime_overrun(s: dict[str, Any]) -> str:
    """'37 overruns in 1000 periods at Ts = 5.0 us: the command was not at the plant by its deadline (12 missed
    their SYNC); worst SYNC lateness 412.3 us at period 18' (the plant's figures, summary.json realtime.plant)."""
    rt = s.get("realtime") or {}
    p = rt.get("plant") or {}
    n, late = p.get("overruns") or 0, p.get("sync_overruns") or 0
    where = f"in {p.get('periods', s.get('periods'))} periods at Ts = {_us(rt.get('period_us'))} us"
    missed = p.get("missed_commands") or 0
    parts = [f"{n} overruns {where}: the command was not at the plant by its deadline ({missed} missed their SYNC)"]
    parts = parts if n else []
    if late:
        parts.append(f"{late} SYNCs more than one period late" + ("" if n else f" {where}"))
    parts.append(f"worst SYNC lateness {_us(p.get('sync_lateness_max_us'))} us at period {p.get('worst_period')}")
    causes = _causes(rt)
    if causes:
        parts.append(f"by cause: {causes}")
    floor = rt.get("floor")
    if floor:
        parts.append(f"the host's floor p99 {floor['p99_us']:g} p99.9 {floor['p99_9_us']:g} us")
    return "; ".join(parts)


def _causes(rt: dict[str, Any]) -> str:
    """'plant_late 3, drive_missing 12' (summary.json realtime.bus.overrun_causes, the non-zero ones)."""
    got = ((rt.get("bus") or {}).get("overrun_causes")) or {}
    return ", ".join(f"{k} {v}" for k, v in got.items() if v)


def _frames_lost(s: dict[str, Any]) -> str:
    """Why frames_lost without a stop: frames missing from periods, and/or fewer periods than the master ran."""
    bs, log = s["bus_stats"], s.get("log") or {}
    parts = [f"{bs['lost_frames']} frames lost"] if bs["lost_frames"] else []
    planned = bs.get("planned_periods")
    if planned and s["periods"] != planned:
        parts.append(f"{s['periods']} periods of the {planned} the master ran")
    if log.get("truncated_line"):
        parts.append(f"the log is truncated (it ends mid-line at line {log['truncated_line']})")
    return "; ".join(parts) or f"{bs['lost_frames']} frames lost"


def _first_events(s: dict[str, Any]) -> tuple[str, str]:
    """(" at period N" of the status's first event, "; also raised: ..." the other raised flags with theirs): the
    status names the event that came first (bench/run/verdict/summary.py verdict)."""
    first = s.get("status_first_period") or {}

    def at(flag: str) -> str:
        return "" if first.get(flag) is None else f" at period {first[flag]}"

    others = [f"{k}{at(k)}" for k in first if k != s["status"]]
    return at(s["status"]), (f"; also raised: {', '.join(others)}" if others else "")


def _reaction(s: dict[str, Any]) -> str:
    """'; the bridge then ...' of a tripped run: what its inverter did once tripped (plant.eds trip_reaction)."""
    from bench.eds import enum

    code = s["plant"].get("trip_reaction")
    names = {v: k for k, v in enum("plant", "Inverter", "trip_reaction").items()}
    what = {
        "active_short_circuit": "shorted the terminals",
        "pulses_off": "switched its pulses off: the diodes carry the currents to zero",
    }
    name = names.get(code) if code is not None else None
    return "" if name is None else f"; the bridge then {what.get(name, name)} (trip_reaction = {name})"
