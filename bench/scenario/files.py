"""Scenarios from their files or their text: load (a path, the bench's own scenario of that relative name when the
folder has none: bundled, scenario_path), loads (TOML text) and from_dict (its tables), with `--set` overrides."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path
from typing import Any

from bench.scenario.model import Scenario, ScenarioError
from bench.scenario.overrides import apply_overrides, blame_override
from bench.scenario.parsing import parse


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
    return from_dict(raw, where, overrides)


def from_dict(raw: dict[str, Any], where: str, overrides: list[str] | None = None) -> Scenario:
    """A scenario from its tables as tomllib gives them (a TOML file's layout); a refusal an override caused names
    the override."""
    if not overrides:
        return parse(raw, where)
    try:
        return parse(apply_overrides(raw, overrides, where), where)
    except ScenarioError as exc:
        raise blame_override(raw, overrides, where, exc) from None
