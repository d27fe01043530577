"""What the plugin keeps for a session and for a test (pytest's stash): the options as resolved, the laws built,
the text the failing test's report shows of each run."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pytest


@dataclass(frozen=True)
class LawBuild:
    """A law folder as the session built it: its build folder, its name, the content it was built from."""

    folder: Path  # the user's law folder (absolute)
    out: Path  # its build (bench/law.py build_folder): BENCH_BUILD_DIR of its runs
    name: str  # law.eds's CurrentLaws= (its first law: the one a hil_run selects)
    digest: str  # bench.law.digest of the folder when built
    names: str = ""  # every law of CurrentLaws=, comma-separated (BENCH_LAW of its runs)


@dataclass
class Settings:
    """The session's --hil-* options (command line over ini over default)."""

    bus: str
    law: Path | None
    out: Path
    bus_option: str = "--hil-bus"  # where the bus was chosen, as messages name it
    require: bool = False  # --hil-require: a test whose hil marker asks for what is missing fails, not skips
    isolate: bool = False  # --hil-isolate: every run a `bench run` process of its own (else direct runs in process)
    bus_problems: dict[str, str | None] = field(default_factory=dict)  # checked buses: their problem or None
    laws: dict[Path, LawBuild] = field(default_factory=dict)  # the session's law builds, by folder


SETTINGS = pytest.StashKey[Settings]()
RUN_TEXTS = pytest.StashKey[list[str]]()  # on a test item: per run of hil_run, what its report shows
