"""The C node apps are roots of components (issue 41): no circle of includes or calls in their folders, and a
component never reaches its root.

The graph of a folder: a module is a file stem (drive_cia402.c + drive_cia402.h = drive_cia402); an arrow runs from
a module to another when it includes the other's header, calls a function the other defines, or names a type the
other's header declares (a header's prototypes are no arrow: they declare, they do not call). Read as text (the
folder's own files only; comments and strings are dropped first).
Rules:
  - firmware_shim/shim, plant_rt/node and bench/direct have no circle;
  - the drive app's components (supervision, CiA 402, the law slot, the recorders) reach neither the root
    (drive_app) nor each other: each includes only the cores, the stack, its own header and the shared helpers
    below all of them (drive_od, drive_output, cia402_device), and calls none of the others.
The checker is tested on the drive app's old layout (supervision calling the step), rebuilt in a temporary folder.
"""

from __future__ import annotations

import re
from pathlib import Path

from test_c_layers import find_cycle

from bench.paths import REPO

SHIM = REPO / "firmware_shim" / "shim"
APP_FOLDERS = (SHIM, REPO / "plant_rt" / "node", REPO / "bench" / "direct")
COMPONENTS = ("drive_supervision", "drive_cia402", "drive_law_slot", "drive_recorder")
SHARED = {"drive_od", "drive_output", "cia402_device"}
ROOT = "drive_app"

INCLUDE_RE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)
COMMENT_RE = re.compile(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\])*\"", re.S)
# A function defined at the start of a line (its body's brace on the same or the next line), not static.
DEF_RE = re.compile(r"^(?!static\b)(?:[A-Za-z_][\w \t\*]*?[\s\*])(\w+)\s*\([^;{]*\)\s*\{", re.M)
# static inline functions of a header belong to its module too.
INLINE_RE = re.compile(r"^static\s+inline\s+[\w \t\*]*?[\s\*](\w+)\s*\(", re.M)
TYPEDEF_RE = re.compile(r"\}\s*(\w+_t)\s*;|typedef\s+[^;{}]*?\(\s*\*\s*(\w+)\s*\)|typedef\s+\w[\w\s\*]*\s(\w+_t)\s*;")
WORD_RE = re.compile(r"\b([A-Za-z_]\w*)\b")


def _text(path: Path) -> str:
    return COMMENT_RE.sub(" ", path.read_text())


def owners(folder: Path) -> dict[str, str]:
    """Name -> module: every function a .c file defines (not static), every static inline function and type of a
    header."""
    out: dict[str, str] = {}
    for path in sorted(folder.glob("*.[ch]")):
        text = _text(path)
        names = DEF_RE.findall(text) if path.suffix == ".c" else []
        if path.suffix == ".h":
            names += INLINE_RE.findall(text)
            names += [n for groups in TYPEDEF_RE.findall(text) for n in groups if n]
        for name in names:
            out.setdefault(name, path.stem)
    return out


def use_graph(folder: Path) -> dict[str, set[str]]:
    """Module -> the modules it includes, calls or names a type of (its own module is no arrow)."""
    files = sorted(folder.glob("*.[ch]"))
    local = {p.name for p in files if p.suffix == ".h"}
    own = owners(folder)
    graph: dict[str, set[str]] = {p.stem: set() for p in files}
    for path in files:
        raw = path.read_text()
        for name in INCLUDE_RE.findall(raw):
            if name in local and Path(name).stem != path.stem:
                graph[path.stem].add(Path(name).stem)
        for word in set(WORD_RE.findall(_text(path))):
            target = own.get(word)
            # a header's prototypes declare, they do not use: only the types a header names are its arrows
            if path.suffix == ".h" and not word.endswith("_t"):
                continue
            if target is not None and target != path.stem:
                graph[path.stem].add(target)
    return graph


def component_violations(folder: Path) -> list[str]:
    graph = use_graph(folder)
    bad = []
    for c in COMPONENTS:
        for other in sorted(graph.get(c, set()) - SHARED):
            bad.append(f"component {c} reaches {other}")
    if cycle := find_cycle(graph):
        bad.append(f"circle: {' -> '.join(cycle)}")
    return bad


def test_the_node_apps_folders_have_no_circle() -> None:
    for folder in APP_FOLDERS:
        cycle = find_cycle(use_graph(folder))
        assert cycle is None, f"{folder.relative_to(REPO)}: circle {' -> '.join(cycle or [])}"


def test_drive_components_reach_neither_the_root_nor_each_other() -> None:
    graph = use_graph(SHIM)
    assert set(COMPONENTS) | {ROOT} <= graph.keys()
    assert component_violations(SHIM) == []
    # the root composes every component; the helpers below them reach no component
    assert set(COMPONENTS) <= graph[ROOT]
    for helper in SHARED:
        assert not graph[helper] & (set(COMPONENTS) | {ROOT}), helper


def test_checker_finds_the_old_drive_app_circle(tmp_path: Path) -> None:
    """The layout before issue 41: supervision ran the step (drive_app_step) and called CiA 402, CiA 402 called
    supervision back, and every part took drive_app_t from the root's header."""
    files = {
        "drive_app.h": "typedef struct { int x; } drive_app_t;\nvoid drive_app_step(drive_app_t *app);\n",
        "drive_app.c": '#include "drive_app.h"\nvoid drive_app_step(drive_app_t *app)\n{\n    (void)app;\n}\n',
        "drive_supervision.c": '#include "drive_app.h"\nvoid drive_app_on_measurement(drive_app_t *app)\n{\n'
        "    drive_app_step(app);\n    drive_app_cia402_changed(app);\n}\n",
        "drive_cia402.c": '#include "drive_app.h"\nvoid drive_app_cia402_changed(drive_app_t *app)\n{\n'
        "    drive_app_leave_safe_state(app);\n}\nvoid drive_app_leave_safe_state(drive_app_t *app)\n{\n"
        "    (void)app;\n}\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    graph = use_graph(tmp_path)
    assert graph["drive_supervision"] == {"drive_app", "drive_cia402"}
    bad = component_violations(tmp_path)
    assert "component drive_supervision reaches drive_app" in bad
    assert "component drive_cia402 reaches drive_app" in bad
    # and the circle through the calls alone, without a single include between the two files:
    (tmp_path / "drive_cia402.c").write_text(
        "void drive_app_cia402_changed(int a)\n{\n    drive_app_on_measurement(a);\n}\n"
    )
    (tmp_path / "drive_supervision.c").write_text(
        "void drive_app_on_measurement(int a)\n{\n    drive_app_cia402_changed(a);\n}\n"
    )
    assert find_cycle(use_graph(tmp_path)) in (
        ["drive_cia402", "drive_supervision", "drive_cia402"],
        ["drive_supervision", "drive_cia402", "drive_supervision"],
    )
