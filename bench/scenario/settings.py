"""A scenario's values checked against the EDS: which table writes which records (SECTION_OBJECTS), the entries
the bench drives itself (RESERVED), the [controller] ratios (RATIOS), and one key = value turned into a Setting
(setting: name, type and range from the EDS, ValueNames for text)."""

from __future__ import annotations

import math
from typing import Any

from bench.eds import Param, model_records, params
from bench.laws import law_records
from bench.scenario.model import ScenarioError, Setting

SECTION_OBJECTS: dict[str, tuple[str, tuple[str, ...]]] = {
    # the motor model's record and each machine model's own (plant.eds "Model <name>": plant_rt/models/<name>/)
    "motor": ("plant", ("Motor model", *model_records())),
    "drive": ("plant", ("Inverter", "Sensors", "Run control")),
    # the drive's own records and every current law's (drive.eds CurrentLaws, a user law's too)
    "controller": ("drive", ("Controller", "Outer loops", *law_records(), "Safe state")),
    "references": ("drive", ("References",)),
}
# Run-control entries the bench drives itself (scenario.timing sets the mode, [frames] the period mark).
RESERVED = {
    ("Run control", "run_periods"),
    ("Run control", "trip_clear"),
    ("Run control", "mode"),
    ("Run control", "period_mark"),  # [frames] period_mark (bench/scenario/frames.py)
}
RATIOS = {
    "R_hat_ratio": (("R_hat_ohm", "R_ohm"),),
    "Ld_hat_ratio": (("Ld_hat_H", "Ld_H"),),
    "Lq_hat_ratio": (("Lq_hat_H", "Lq_H"),),
    "L_hat_ratio": (("Ld_hat_H", "Ld_H"), ("Lq_hat_H", "Lq_H")),
    "psi_hat_ratio": (("psi_hat_Wb", "psi_Wb"),),
}


def param_tables() -> dict[str, dict[str, Param]]:
    """The EDS entries of each table of a scenario, by key."""
    return {sec: params(node, objs) for sec, (node, objs) in SECTION_OBJECTS.items()}


def _fmt_range(p: Param) -> str:
    if p.low is None and p.high is None:
        return "any value"
    return f"{p.low:g} .. {p.high:g}"


def _ratio(where: str, full: str, key: str, value: Any) -> Setting:
    """A [controller] ratio (RATIOS): a number in 0.01 .. 100, resolved against the plant at configuration."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0.01 <= float(value) <= 100):
        raise ScenarioError(f"{where}: {full} = {value!r}: a ratio must be a number in 0.01 .. 100")
    return Setting(full, None, float(value), RATIOS[key])


def setting(where: str, section: str, key: str, value: Any, tables: dict[str, dict[str, Param]]) -> Setting:
    """`section.key = value` as an OD write, checked: a known key, a number (or one of its ValueNames) in range."""
    full = f"{section}.{key}"
    if section == "controller" and key in RATIOS:
        return _ratio(where, full, key, value)
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
