"""Scenario files (TOML): what to run, checked against the EDS before anything starts.

Layout (every key optional except where noted)::

    [scenario]
    name = "you2019-step"        # required
    description = "..."
    periods = 400                # run length in control periods (required)
    seed = 1                     # ADC-noise seed
    timing = "lockstep"          # lockstep | realtime
    expect = "ok"                # the run status this scenario is meant to end with (or a list):
                                 # ok | tripped | diverged | non_finite | frames_lost |
                                 # node_lost | interference; a
                                 # stability-boundary study says expect = ["diverged", "tripped"]

    [motor]                      # plant.eds "Motor model", after the preset
    preset = "you2019"           # you2019 | yao2020_low | yao2020_high | zhao2022
    Lq_H = 4.54e-3

    [drive]                      # plant.eds "Inverter" and "Sensors", and the lockstep timeout
    preset = "ideal"             # DRIVE_PRESETS: its values first, the section's own keys after and over them
    Vdc_V = 300

    [controller]                 # drive.eds "Controller", "Outer loops", each current law's record (its
                                 # CurrentLaws key: "Online tuning", "Yao 2020 DPCC", ..., a user law's),
                                 # "Safe state" (meas_timeout_periods; clear = 1 in an event: fault reset + enable)
    controller = "deadbeat_you2019"
    L_hat_ratio = 0.5            # ratios to the plant's own values (R_hat_ratio, Ld_hat_ratio,
                                 # Lq_hat_ratio, L_hat_ratio = both, psi_hat_ratio)
    Vmax_V = 139

    [references]                 # drive.eds "References" at period 0
    iq_ref_A = 0.0

    [trace]                      # the drive's synchronous trace TPDOs (drive.eds names, REAL32/integers,
    pdo3 = ["Online tuning.det_A2", "Online tuning.K1_hat_V_A"]    # at most 8 bytes each); without it,
    pdo4 = ["Online tuning.K1_active_V_A", "Online tuning.L_hat_H"]  # the selected law's (default_trace)

    [[faults]]                   # faults on purpose (bench/scenario/faults.py): drop, delay, duplicate,
    kind = "drop"                # corrupt, reorder frames; silence_heartbeat, freeze, kill, reset nodes
    frame = "drive.TPDO1"
    at_period = 200

    [[events]]                   # applied before the current step of period `at_period`
    at_period = 100
    references = { iq_ref_A = 1.0 }
    controller = { enable = 1 }  # any key of the sections above (motor/drive changes hit the plant)

Every value is checked against the EDS: an unknown key names the allowed keys, a value
out of range names the range; nothing starts on a bad scenario.
"""

from __future__ import annotations

import copy
import math
import os
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.eds import Param, enum, params
from bench.eds import load as load_od
from bench.laws import law_info, law_names, law_records
from bench.scenario.faults import Fault, FaultError, parse_faults, refuse_lockstep_stalls
from bench.scenario.trace import TraceError, trace_table

SECTION_OBJECTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "motor": ("plant", ("Motor model",)),
    "drive": ("plant", ("Inverter", "Sensors", "Run control")),
    # the drive's own records and every current law's (drive.eds CurrentLaws, a user law's too)
    "controller": ("drive", ("Controller", "Outer loops", *law_records(), "Safe state")),
    "references": ("drive", ("References",)),
}
# Run-control entries the bench drives itself (scenario.timing sets the mode).
RESERVED = {("Run control", "run_periods"), ("Run control", "trip_clear"), ("Run control", "mode")}
RATIOS = {
    "R_hat_ratio": (("R_hat_ohm", "R_ohm"),),
    "Ld_hat_ratio": (("Ld_hat_H", "Ld_H"),),
    "Lq_hat_ratio": (("Lq_hat_H", "Lq_H"),),
    "L_hat_ratio": (("Ld_hat_H", "Ld_H"), ("Lq_hat_H", "Lq_H")),
    "psi_hat_ratio": (("psi_hat_Wb", "psi_Wb"),),
}
PRESETS = ("you2019", "yao2020_low", "yao2020_high", "zhao2022")
# [drive] presets. "ideal", the papers' simulated drive: no dead time (You 2019 Sec. 5, "the drive losses were ignored
# in the simulation": its 2 us of Table A1) and exact sensors (its 2500-line encoder of Sec. 6; no ADC noise or LSB:
# ASSUMED, as in Yao 2020 Sec. V and Zhao 2022 Sec. 5.1, whose Simulink models give none); the trip level stays on.
DRIVE_PRESETS = {"ideal": {"t_dead_s": 0.0, "encoder_lines": 0, "adc_noise_std_A": 0.0, "adc_lsb_A": 0.0}}
TIMINGS = ("lockstep", "realtime")
SCENARIO_KEYS = ("name", "description", "periods", "seed", "timing", "expect")
# Run statuses (bench/run/verdict/summary.py EXIT_CODES gives each its exit code).
STATUSES = (
    "ok",
    "tripped",
    "diverged",
    "non_finite",
    "frames_lost",
    "node_lost",
    "interference",
    "law_fault",
    "realtime_overrun",
)


class ScenarioError(ValueError):
    """A bad scenario: the message names the file, the key and what is allowed."""


@dataclass(frozen=True)
class Setting:
    """One OD write, or a ratio resolved against the plant's value at configuration time."""

    key: str  # "section.name" as in the file
    param: Param | None  # None for ratio keys
    value: float | int
    ratio_of: tuple[tuple[str, str], ...] = ()  # ((drive param, plant param), ...)


@dataclass
class Event:
    at_period: int
    settings: list[Setting]


@dataclass
class Scenario:
    name: str
    periods: int
    source: str
    description: str = ""
    seed: int = 1
    timing: str = "lockstep"
    preset: str | None = "you2019"
    settings: list[Setting] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    trace: dict[int, tuple[str, ...]] = field(default_factory=dict)  # TPDO number -> entries (parse)
    expect: tuple[str, ...] = ("ok",)
    faults: list[Fault] = field(default_factory=list)  # [[faults]] (bench/scenario/faults.py)
    raw: dict[str, Any] = field(default_factory=dict)

    def event_periods(self) -> list[int]:
        return sorted({e.at_period for e in self.events})


def _param_tables() -> dict[str, dict[str, Param]]:
    return {sec: params(node, objs) for sec, (node, objs) in SECTION_OBJECTS.items()}


def _fmt_range(p: Param) -> str:
    if p.low is None and p.high is None:
        return "any value"
    return f"{p.low:g} .. {p.high:g}"


def _setting(where: str, section: str, key: str, value: Any, tables: dict[str, dict[str, Param]]) -> Setting:
    full = f"{section}.{key}"
    if section == "controller" and key in RATIOS:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0.01 <= float(value) <= 100):
            raise ScenarioError(f"{where}: {full} = {value!r}: a ratio must be a number in 0.01 .. 100")
        return Setting(full, None, float(value), RATIOS[key])
    table = tables[section]
    if key not in table or (table[key].obj, key) in RESERVED:
        allowed = sorted(k for k, p in table.items() if (p.obj, k) not in RESERVED)
        if section == "controller":
            allowed += sorted(RATIOS)
        raise ScenarioError(f"{where}: unknown key {full!r}; allowed in [{section}]: {', '.join(allowed)}")
    p = table[key]
    if isinstance(value, str):
        names = {n: i for i, n in enumerate(p.names)}  # the EDS's ValueNames
        if value not in names:
            choices = f"one of {', '.join(names)}" if names else f"a number ({_fmt_range(p)})"
            raise ScenarioError(f"{where}: {full} = {value!r}: expected {choices}")
        value = names[value]
    if isinstance(value, bool):
        value = int(value)
    if not isinstance(value, (int, float)) or (isinstance(value, float) and not math.isfinite(value)):
        raise ScenarioError(f"{where}: {full} = {value!r}: expected a number ({_fmt_range(p)})")
    if not p.is_float:
        if float(value) != int(value):
            raise ScenarioError(f"{where}: {full} = {value!r}: expected an integer ({_fmt_range(p)})")
        value = int(value)
    if (p.low is not None and value < p.low) or (p.high is not None and value > p.high):
        raise ScenarioError(
            f"{where}: {full} = {value!r} is out of range: allowed {_fmt_range(p)} (from {p.node}.eds {p.obj})"
        )
    return Setting(full, p, value)


def _drive_preset(where: str, values: dict[str, Any]) -> dict[str, Any]:
    """[drive] with its preset expanded (DRIVE_PRESETS): the preset's values first, the section's own after and over."""
    name = values.get("preset")
    if name is None:
        return values
    if not isinstance(name, str) or name not in DRIVE_PRESETS:
        raise ScenarioError(f"{where}: drive.preset = {name!r}: expected one of {', '.join(DRIVE_PRESETS)}")
    return {**DRIVE_PRESETS[name], **{k: v for k, v in values.items() if k != "preset"}}


def add_set_argument(p: Any, help: str) -> None:
    """`--set KEY=VALUE` (repeatable) of the commands that take a scenario's overrides (apply_overrides):
    bench run, sweep, faults; `p` an argparse parser, the values in args.overrides."""
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=help)


def unselected_law(scenarios: list[Scenario], what: str = "the scenario") -> str | None:
    """Under `--law DIR` (bench/law.py sets BENCH_LAW to the law's name): a refusal when none of these
    scenarios selects the user's law (controller.controller, at the start or in an event), else None."""
    name = os.environ.get("BENCH_LAW")
    if not name:
        return None
    value = law_names().index(name) if name in law_names() else -1
    for sc in scenarios:
        for st in [*sc.settings, *(x for e in sc.events for x in e.settings)]:
            if st.key == "controller.controller" and int(st.value) == value:
                return None
    return (
        f'--law: {what} does not select the law {name}: set [controller] controller = "{name}" '
        f"(or --set controller.controller={name})"
    )


def apply_overrides(raw: dict[str, Any], overrides: list[str], where: str) -> dict[str, Any]:
    """`--set a.b=value`: dotted keys following the TOML layout; values parsed as TOML."""
    out = copy.deepcopy(raw)
    for item in overrides:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"--set {item!r}: expected KEY=VALUE, e.g. controller.L_hat_ratio=0.5")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()  # bare words are strings (controller=pi)
        parts = key.strip().split(".")
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ScenarioError(f"--set {item!r}: {part!r} is not a table in {where}")
        node[parts[-1]] = value
    return out


def parse(raw: dict[str, Any], where: str) -> Scenario:
    allowed_top = {"scenario", "events", "faults", "trace", *SECTION_OBJECTS}
    for key in raw:
        if key not in allowed_top:
            raise ScenarioError(f"{where}: unknown table [{key}]; allowed: {', '.join(sorted(allowed_top))}")
    name, periods, seed, timing, expect_list = _head(raw, where)
    tables = _param_tables()
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
    for section in SECTION_OBJECTS:
        values = motor if section == "motor" else raw.get(section, {})
        if not isinstance(values, dict):
            raise ScenarioError(f"{where}: [{section}] must be a table")
        for key, value in (_drive_preset(where, values) if section == "drive" else values).items():
            sc.settings.append(_setting(where, section, key, value, tables))
    sc.events = _events(raw, where, periods, tables)
    sc.events.sort(key=lambda e: e.at_period)
    try:
        sc.trace = trace_table(where, raw["trace"]) if "trace" in raw else default_trace(sc)
        sc.faults = parse_faults(raw.get("faults"), where, periods, timing, seed, tuple(sc.event_periods()))
        refuse_lockstep_stalls(sc.faults, where, timing, sc.expect, lambda k: _value_at(sc, COMMAND_TIMEOUT, k))
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


def _events(raw: dict[str, Any], where: str, periods: int, tables: Any) -> list[Event]:
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
                if section == "motor" and key == "preset":
                    raise ScenarioError(f"{w}: motor.preset cannot change during a run")
                settings.append(_setting(w, section, key, value, tables))
        if not settings:
            raise ScenarioError(f"{w}: an event must change something")
        out.append(Event(at, settings))
    return out


COMMAND_TIMEOUT = "drive.command_timeout_us"  # plant.eds 0x2003:04, set in the scenario's [drive]


def _value_at(sc: Scenario, key: str, period: int) -> float:
    """A setting's value in effect at a period: its EDS default, the scenario's, then its events' up to it."""
    section, name = key.split(".", 1)
    p = _param_tables()[section][name]
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


def bundled(path: Path) -> Path:
    """`path`, or the bench's own scenario of that relative name (scenarios/you2019_step.toml; in a clone also
    examples/...) when this folder has none: the README's commands work from any folder, also with an installed
    package. Says so on stderr (a user's own scenario of that name in another folder must not pass unnoticed)."""
    if path.exists() or path.is_absolute():
        return path
    from bench.paths import REPO

    own = REPO / path
    if not own.is_file():
        return path
    if own not in _SAID:  # once a process: argparse's type and load() both resolve it
        _SAID.add(own)
        print(f"bench: {path} is not in {Path.cwd()}: using the bench's own {own}", file=sys.stderr, flush=True)
    return own


_SAID: set[Path] = set()


def scenario_path(text: str) -> Path:
    """argparse's type of a command's scenario argument (bundled())."""
    return bundled(Path(text))


def load(path: Path, overrides: list[str] | None = None) -> Scenario:
    path = bundled(path)
    where = str(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError(f"{where}: cannot read: {exc.strerror}") from exc
    return loads(text, where, overrides)


def loads(text: str, where: str, overrides: list[str] | None = None) -> Scenario:
    """A scenario from its TOML text (`where` names it in errors): what a sweep sends to its workers,
    which may not share the file system."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: not valid TOML: {exc}") from exc
    if not overrides:
        return parse(raw, where)
    try:
        return parse(apply_overrides(raw, overrides, where), where)
    except ScenarioError as exc:
        raise _blame_override(raw, overrides, where, exc) from None


def _blame_override(raw: dict[str, Any], overrides: list[str], where: str, exc: ScenarioError) -> ScenarioError:
    """A refusal that an override caused names that override (with the nearest known key), not the file: the
    file alone parses, and the first override after which it does not is the one."""
    try:
        parse(raw, where)
    except ScenarioError:
        return exc  # the file itself
    for n in range(1, len(overrides) + 1):
        try:
            parse(apply_overrides(raw, overrides[:n], where), where)
        except ScenarioError as err:
            item = overrides[n - 1]
            text = str(err).removeprefix(f"{where}: ")
            return ScenarioError(f"--set {item} (on {where}): {text}{_nearest(item.partition('=')[0].strip())}")
    return exc


def _nearest(key: str) -> str:
    """ "; did you mean section.key?" for a misspelt override key, or ""."""
    import difflib

    tables = _param_tables()
    known = [f"{t}.{k}" for t, params in tables.items() for k in params] + [f"scenario.{k}" for k in SCENARIO_KEYS]
    known += [f"controller.{k}" for k in RATIOS] + ["motor.preset", "drive.preset"]
    if key in known:
        return ""
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.8)
    return f"; did you mean {close[0]}?" if close else ""
