"""What the plugin keeps for a session and for a test (pytest's stash): the options as resolved, the text the
failing test's report shows of each run."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pytest


@dataclass
class Settings:
    """The session's --hil-* options (command line over ini over default)."""

    bus: str
    law: Path | None
    out: Path
    bus_option: str = "--hil-bus"  # where the bus was chosen, as messages name it
    bus_problems: dict[str, str | None] = field(default_factory=dict)  # checked buses: their problem or None


SETTINGS = pytest.StashKey[Settings]()
RUN_TEXTS = pytest.StashKey[list[str]]()  # on a test item: per run of hil_run, what its report shows
