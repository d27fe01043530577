"""What the command line changes in a scenario: `--set KEY=VALUE` (add_set_argument, set_items, apply_overrides; a
refusal it causes blames the override: blame_override) and `--law DIR`, whose law some scenario must select
(unselected_law)."""

from __future__ import annotations

import copy
import difflib
import os
import tomllib
from collections.abc import Mapping, Sequence
from typing import Any

from bench.laws import law_names
from bench.scenario.model import SCENARIO_KEYS, Scenario, ScenarioError
from bench.scenario.parsing import parse
from bench.scenario.settings import RATIOS, param_tables


def add_set_argument(p: Any, help: str) -> None:
    """`--set KEY=VALUE` (repeatable) of the commands that take a scenario's overrides (apply_overrides):
    bench run, sweep, faults; `p` an argparse parser, the values in args.overrides."""
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=help)


def unselected_law(scenarios: list[Scenario], what: str = "the scenario") -> str | None:
    """Under `--law DIR` (bench/law.py sets BENCH_LAW to the folder's law names, comma-separated): a refusal
    when none of these scenarios selects one of the user's laws (controller.controller, at the start or in an
    event), else None."""
    given = [n for n in os.environ.get("BENCH_LAW", "").split(",") if n]
    if not given:
        return None
    name = given[0]
    values = {law_names().index(n) for n in given if n in law_names()}
    for sc in scenarios:
        for st in [*sc.settings, *(x for e in sc.events for x in e.settings)]:
            if st.key == "controller.controller" and int(st.value) in values:
                return None
    which = f"the law {name}" if len(given) == 1 else f"any of the laws {', '.join(given)}"
    return (
        f'--law: {what} does not select {which}: set [controller] controller = "{name}" '
        f"(or --set controller.controller={name})"
    )


def unselected_python_law(sc: Scenario, law: str) -> str | None:
    """Under --py-law: a refusal when the scenario never runs the law the Python class stands in for (its `law`: the
    controller at the start or one an event selects), else None."""
    from bench.scenario.parsing import controller_at_start

    if controller_at_start(sc) == law or law not in law_names():
        return None
    value = law_names().index(law)
    for e in sc.events:
        if any(st.key == "controller.controller" and int(st.value) == value for st in e.settings):
            return None
    return (
        f"--py-law: the class stands in for {law}, which the scenario never selects: set [controller] controller = "
        f'"{law}" (or --set controller.controller={law})'
    )


def set_items(overrides: Mapping[str, Any] | Sequence[str] | str | None) -> list[str]:
    """`--set` items from {"controller.L_hat_ratio": 0.5} (values written as TOML) or ["k=v", ...] or "k=v";
    TypeError names a value TOML cannot hold."""
    from bench.scenario.toml_text import value

    if overrides is None:
        return []
    if isinstance(overrides, str):
        return [overrides]
    if isinstance(overrides, Mapping):
        out = []
        for k, v in overrides.items():
            try:
                out.append(f"{k}={value(v)}")
            except TypeError as exc:
                raise TypeError(f"override {k}: {exc}") from None
        return out
    return [str(o) for o in overrides]


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


def blame_override(raw: dict[str, Any], overrides: list[str], where: str, exc: ScenarioError) -> ScenarioError:
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
    tables = param_tables()
    known = [f"{t}.{k}" for t, params in tables.items() for k in params] + [f"scenario.{k}" for k in SCENARIO_KEYS]
    known += [f"controller.{k}" for k in RATIOS] + ["motor.preset", "drive.preset"]
    if key in known:
        return ""
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.8)
    return f"; did you mean {close[0]}?" if close else ""
