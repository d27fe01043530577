"""What the plugin keeps for a session and for a test (pytest's stash): the options as resolved, the laws built,
the text the failing test's report shows of each run."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
    view: str = "failed"  # --hil-view: an in-process run's recording and plots drawn for every run, or a failing test's
    bus_problems: dict[str, str | None] = field(default_factory=dict)  # checked buses: their problem or None
    laws: dict[Path, LawBuild] = field(default_factory=dict)  # the session's law builds, by folder


SETTINGS = pytest.StashKey[Settings]()
RUN_TEXTS = pytest.StashKey[list[str]]()  # on a test item: per run of hil_run, what its report shows
RUN_VIEWS = pytest.StashKey[list["LaterView"]]()  # on a test item: its in-process runs' recording and plots, not drawn


@dataclass
class LaterView:
    """An in-process run whose recording and plots are drawn if its test fails (--hil-view=failed): `view` draws
    them (bench/view/deferred.py), then the run's report text, `RUN_TEXTS[text]`, is written again."""

    view: Any  # bench.view.deferred.DeferredView
    run: Any  # its HilRun
    text: int  # its index in RUN_TEXTS
    reproduce: str  # the report's reproduce line, as written
