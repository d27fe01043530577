"""A scenario's TOML tables parsed and checked (parse): the [scenario] head, the [motor]/[drive]/[controller]/
[references] settings (bench/scenario/settings.py), the [[events]], the [trace] (or the starting law's default
trace) and the [[faults]]; with what a parsed scenario answers about itself (controller_at_start, value_at)."""

from __future__ import annotations

from typing import Any

from bench.eds import Param, enum
from bench.eds import load as load_od
from bench.laws import law_info
from bench.scenario.faults import FaultError, parse_faults, refuse_lockstep_stalls
from bench.scenario.frames import parse_frames, refuse_unsent_frames
from bench.scenario.model import SCENARIO_KEYS, STATUSES, TIMINGS, Event, Scenario, ScenarioError
from bench.scenario.presets import PRESETS, drive_preset
from bench.scenario.settings import SECTION_OBJECTS, param_tables, setting
from bench.scenario.trace import TraceError, trace_table

COMMAND_TIMEOUT = "drive.command_timeout_us"  # plant.eds 0x2003:04, set in the scenario's [drive]


def parse(raw: dict[str, Any], where: str) -> Scenario:
    allowed_top = {"scenario", "events", "faults", "trace", "frames", *SECTION_OBJECTS}
    for key in raw:
        if key not in allowed_top:
            raise ScenarioError(f"{where}: unknown table [{key}]; allowed: {', '.join(sorted(allowed_top))}")
    name, periods, seed, timing, expect_list = _head(raw, where)
    tables = param_tables()
    sc = Scenario(
        name=name,
        periods=periods,
        source=where,
        description=str(raw["scenario"].get("description", "")),
        seed=seed,
        timing=timing,
        raw=raw,
        expect=tuple(expect_list),
    )
    motor = dict(raw.get("motor", {}))
    preset = motor.pop("preset", "you2019")
    if preset is not None and preset not in PRESETS:
        raise ScenarioError(f"{where}: motor.preset = {preset!r}: expected one of {', '.join(PRESETS)}")
    sc.preset = preset
    folder = motor.pop("folder", None)
    fmu = motor.pop("fmu", None)
    if folder is not None and fmu is not None:
        raise ScenarioError(f"{where}: [motor] takes a folder (a flux map) or an fmu, not both")
    if fmu is not None:
        from bench.motor.settings import fmu_settings

        sc.motor_fmu, own = fmu_settings(where, fmu, preset, motor, tables)
        sc.settings.extend(own)
    if folder is not None:
        from bench.motor.settings import folder_settings

        sc.motor_folder, own = folder_settings(where, folder, tables)
        sc.settings.extend(own)  # before the scenario's own [motor] keys, which come after and over them
    for section in SECTION_OBJECTS:
        values = motor if section == "motor" else raw.get(section, {})
        if not isinstance(values, dict):
            raise ScenarioError(f"{where}: [{section}] must be a table")
        for key, value in (drive_preset(where, values) if section == "drive" else values).items():
            sc.settings.append(setting(where, section, key, value, tables))
    sc.events = _events(raw, where, periods, tables)
    sc.frames = parse_frames(raw.get("frames"), where)
    sc.events.sort(key=lambda e: e.at_period)
    if sc.motor_folder is not None:  # the trip level, and what the trip does at the run's speed (events included)
        from bench.motor.settings import check_range

        note = check_range(where, sc.motor_folder, _trip_level(sc), sc)
        sc.trip_note = None if note is None else note.text
    try:
        sc.trace = trace_table(where, raw["trace"]) if "trace" in raw else default_trace(sc)
        sc.faults = parse_faults(raw.get("faults"), where, periods, timing, seed, tuple(sc.event_periods()))
        refuse_lockstep_stalls(
            sc.faults, where, timing, sc.expect, lambda k: value_at(sc, COMMAND_TIMEOUT, k), sc.frames.one_frame
        )
        refuse_unsent_frames(sc.faults, sc.frames, where)
    except (FaultError, TraceError) as exc:
        raise ScenarioError(str(exc)) from None
    return sc


def _head(raw: dict[str, Any], where: str) -> tuple[str, int, int, str, list[str]]:
    """[scenario]: name, periods, seed, timing and the statuses it expects, each checked."""
    head = raw.get("scenario")
    if not isinstance(head, dict):
        raise ScenarioError(f"{where}: missing [scenario] table with at least name and periods")
    for key in head:
        if key not in SCENARIO_KEYS:
            raise ScenarioError(f"{where}: unknown key scenario.{key}; allowed: {', '.join(SCENARIO_KEYS)}")
    name = head.get("name")
    if not isinstance(name, str) or not name:
        raise ScenarioError(f"{where}: scenario.name must be a non-empty string")
    periods = head.get("periods")
    if isinstance(periods, bool) or not isinstance(periods, int) or not 1 <= periods <= 100_000_000:
        raise ScenarioError(f"{where}: scenario.periods = {periods!r}: expected an integer in 1 .. 100000000")
    seed = head.get("seed", 1)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= 0xFFFFFFFF:
        raise ScenarioError(f"{where}: scenario.seed = {seed!r}: expected an integer in 0 .. 4294967295")
    timing = head.get("timing", "lockstep")
    if timing not in TIMINGS:
        raise ScenarioError(f"{where}: scenario.timing = {timing!r}: expected one of {', '.join(TIMINGS)}")
    expect = head.get("expect", "ok")
    expect_list = [expect] if isinstance(expect, str) else expect
    if not isinstance(expect_list, list) or not expect_list or any(e not in STATUSES for e in expect_list):
        raise ScenarioError(
            f"{where}: scenario.expect = {expect!r}: expected one of {', '.join(STATUSES)} or a list of them"
        )
    return name, periods, seed, timing, expect_list


def _events(raw: dict[str, Any], where: str, periods: int, tables: dict[str, dict[str, Param]]) -> list[Event]:
    """[[events]]: each at a period of the run, changing something (not the motor preset)."""
    out: list[Event] = []
    events = raw.get("events", [])
    if not isinstance(events, list):
        raise ScenarioError(f"{where}: events must be an array of tables ([[events]])")
    for i, ev in enumerate(events):
        w = f"{where}: events[{i}]"
        if not isinstance(ev, dict):
            raise ScenarioError(f"{w}: must be a table")
        at = ev.get("at_period")
        if isinstance(at, bool) or not isinstance(at, int) or not 0 <= at < periods:
            raise ScenarioError(f"{w}.at_period = {at!r}: expected an integer in 0 .. {periods - 1}")
        settings = []
        for section, values in ev.items():
            if section == "at_period":
                continue
            if section not in SECTION_OBJECTS or not isinstance(values, dict):
                raise ScenarioError(
                    f"{w}: unknown key {section!r}; an event holds at_period and tables {', '.join(SECTION_OBJECTS)}"
                )
            for key, value in values.items():
                if section == "motor" and key in ("preset", "folder", "fmu"):
                    raise ScenarioError(f"{w}: motor.{key} cannot change during a run")
                settings.append(setting(w, section, key, value, tables))
        if not settings:
            raise ScenarioError(f"{w}: an event must change something")
        out.append(Event(at, settings))
    return out


def _trip_level(sc: Scenario) -> float:
    """The plant's over-current trip level at the start: the last drive.I_trip_A written (a motor folder's, then the
    scenario's own), else its motor preset's."""
    for s in reversed(sc.settings):
        if s.key == "drive.I_trip_A":
            return float(s.value)
    if sc.preset is None:
        return value_at(sc, "drive.I_trip_A", 0)
    from bench.scenario.presets import motor_preset

    return float(motor_preset(sc.preset).values["I_trip_A"])


def value_at(sc: Scenario, key: str, period: int) -> float:
    """A setting's value in effect at a period: its EDS default, the scenario's, then its events' up to it."""
    section, name = key.split(".", 1)
    p = param_tables()[section][name]
    var = load_od(p.node)[p.index]
    value = float((var[p.subindex] if p.subindex else var).default or 0)
    for s in [*sc.settings, *(s for e in sc.events if e.at_period <= period for s in e.settings)]:
        if s.key == key:
            value = float(s.value)
    return value


def controller_at_start(sc: Scenario) -> str:
    """The law the drive runs from period 0 (drive.eds Controller.controller by its ValueNames): the
    scenario's [controller] setting, then its period-0 events (in the order the bench writes them), else
    the EDS default."""
    value = int(load_od("drive")["Controller"]["controller"].default)
    for s in [*sc.settings, *(s for e in sc.events if e.at_period == 0 for s in e.settings)]:
        if s.param is not None and (s.param.node, s.param.obj, s.param.name) == ("drive", "Controller", "controller"):
            value = int(s.value)
    return {v: k for k, v in enum("drive", "Controller", "controller").items()}[value]


def default_trace(sc: Scenario) -> dict[int, tuple[str, ...]]:
    """The trace TPDOs of a scenario without [trace]: the live quantities of the law it starts with
    (its record's Trace key in drive.eds, read by bench/laws.py). An event that switches laws later
    leaves the mapping as it is: the PDOs are mapped once, before the run."""
    return dict(law_info(controller_at_start(sc)).trace)
