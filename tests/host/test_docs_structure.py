"""What docs/ARCHITECTURE.md states about the structure is checked here, so a stale claim fails (issue 53, item 6):
the plant's machine models it names are the model folders, the C floors it describes are those
tests/host/test_c_folders.py holds, and no hand-written source file is over 400 lines (the standard the docs state).
The circles and arrows themselves: test_c_folders.py, test_c_components.py, test_import_graph.py."""

from __future__ import annotations

import re
import subprocess

from test_c_folders import PLANT_FLOORS

from bench.paths import REPO

ARCH = (REPO / "docs" / "ARCHITECTURE.md").read_text()
MAX_LINES = 400
SOURCES = (
    "bench/*.py",
    "plant_rt/*.[ch]",
    "firmware_shim/*.[ch]",
    "protocols/*.[ch]",
    "protocols/*.py",
    "scripts/*.py",
)


def test_the_architecture_names_every_machine_model_folder() -> None:
    folders = sorted(p.name for p in (REPO / "plant_rt" / "models").iterdir() if p.is_dir())
    row = next(line for line in ARCH.splitlines() if line.startswith("| model / control cores |"))
    named = sorted(set(re.findall(r"`(\w+)`", row)) & set(folders))
    assert named == folders, f"docs/ARCHITECTURE.md names the models {named}, the folders are {folders}"


def test_the_architecture_names_every_floor_of_the_plant() -> None:
    for floor in PLANT_FLOORS:
        assert f"plant_rt/{floor}/" in ARCH, f"docs/ARCHITECTURE.md does not name plant_rt/{floor}/"


def test_no_hand_written_source_file_is_over_400_lines() -> None:
    files = subprocess.run(["git", "ls-files", *SOURCES], cwd=REPO, capture_output=True, text=True, check=True)
    over = []
    for name in files.stdout.split():
        if "/generated/" in name or "/tests/" in name:
            continue
        n = (REPO / name).read_text().count("\n")
        if n > MAX_LINES:
            over.append(f"{name}: {n}")
    assert not over, f"over {MAX_LINES} lines: {over}"
