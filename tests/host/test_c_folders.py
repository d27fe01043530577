"""Every C folder of the project, from a list computed here (not kept by hand), has no circle of includes or calls
inside it; and the folders of the plant (plant_rt/) and of the drive's firmware (firmware_shim/) stand on floors:
no folder reaches one above it, and no two folders reach each other (issue 53: the plant's machine models).

The graph is test_c_components.py's, over a whole tree: a module is a file stem in its folder; an arrow runs from a
module to another when it includes the other's header, calls a function the other defines, or names a type the
other's header declares. Read as text (comments and strings dropped). Tests and generated files are not rooms.
The checker is tested on the plant's old layout (the machine block and the flux-map model calling each other).
"""

from __future__ import annotations

import re
from pathlib import Path

from test_c_components import DEF_RE, INCLUDE_RE, INLINE_RE, TYPEDEF_RE, WORD_RE, _text, use_graph
from test_c_layers import find_cycle

from bench.paths import REPO

TREES = ("firmware_shim", "plant_rt", "protocols", "bench/direct")
NOT_ROOMS = ("tests", "generated", "fuzz")
# The floors of the plant's folders, bottom up: the shared types and blocks, the machine models (siblings may use
# one another, without a circle), the API that chooses a model, the host glue and tools, the CANopen node.
PLANT_FLOORS = {"blocks": 0, "models": 1, "core": 2, "fmu": 3, "node": 4, "tools": 5}
# A prototype in a header: a function a folder declares and another folder defines is a seam (the firmware's
# drive_port.h, one implementation per target): a call to it reaches the declaring header, not the implementation.
# A variable a .c file defines for others (a model's descriptor: `const plant_model_desc_t plant_model_x = {`).
VAR_RE = re.compile(r"^(?!static\b)(?:const\s+)?\w+_t\s+(\w+)\s*=", re.M)
PROTO_RE = re.compile(r"^(?!static\b)(?:[A-Za-z_][\w \t\*]*?[\s\*])(\w+)\s*\([^;{]*\)\s*;", re.M)


def c_folders() -> list[Path]:
    """Every folder of the C trees with a .c or .h file of its own, but tests, generated code and fuzz drivers."""
    out = set()
    for tree in TREES:
        for path in (REPO / tree).rglob("*.[ch]"):
            rel = path.parent.relative_to(REPO)
            if not set(rel.parts) & set(NOT_ROOMS):
                out.add(path.parent)
    return sorted(out)


def tree_graph(root: Path) -> dict[str, set[str]]:
    """'folder/module' -> the modules (of any folder of the tree) it includes, calls or names a type of."""
    files = [p for p in sorted(root.rglob("*.[ch]")) if not set(p.relative_to(root).parts) & set(NOT_ROOMS)]

    def key(p: Path) -> str:
        return f"{p.parent.relative_to(root).as_posix()}/{p.stem}"

    headers = {p.name: key(p) for p in files if p.suffix == ".h"}
    own: dict[str, str] = {}
    declared: dict[str, str] = {}
    for p in files:
        text = _text(p)
        if p.suffix == ".h":
            for name in PROTO_RE.findall(text):
                declared.setdefault(name, key(p))
        names = DEF_RE.findall(text) + VAR_RE.findall(text) if p.suffix == ".c" else INLINE_RE.findall(text)
        if p.suffix == ".h":
            names += [n for groups in TYPEDEF_RE.findall(text) for n in groups if n]
        for name in names:
            own.setdefault(name, key(p))
    for name, header in declared.items():  # defined in another folder than declared: the seam is the header
        if name in own and own[name].rsplit("/", 1)[0] != header.rsplit("/", 1)[0]:
            own[name] = header
    graph: dict[str, set[str]] = {key(p): set() for p in files}
    for p in files:
        me = key(p)
        for inc in INCLUDE_RE.findall(p.read_text()):
            target = headers.get(Path(inc).name)
            if target is not None and target != me:
                graph[me].add(target)
        for word in set(WORD_RE.findall(_text(p))):
            if p.suffix == ".h" and not word.endswith("_t"):
                continue  # a header's prototypes declare, they do not use
            target = own.get(word)
            if target is not None and target != me:
                graph[me].add(target)
    return graph


def folder_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Folder -> the folders its modules reach."""
    out: dict[str, set[str]] = {}
    for module, targets in graph.items():
        here = module.rsplit("/", 1)[0]
        out.setdefault(here, set())
        out[here] |= {t.rsplit("/", 1)[0] for t in targets} - {here}
    return out


def upward_arrows(folders: dict[str, set[str]], floors: dict[str, int]) -> list[str]:
    """Arrows from a folder to one on a higher floor (a folder's floor is its first part's)."""
    bad = []
    for src, targets in sorted(folders.items()):
        for dst in sorted(targets):
            if floors[dst.split("/")[0]] > floors[src.split("/")[0]]:
                bad.append(f"{src} -> {dst}")
    return bad


def test_the_list_of_c_folders_is_whole() -> None:
    """The computed list holds the folders each tree has today (a folder moved out of it would go unchecked)."""
    rel = {f.relative_to(REPO).as_posix() for f in c_folders()}
    assert {"plant_rt/blocks", "plant_rt/core", "plant_rt/models/dq_linear", "plant_rt/models/flux_map",
            "plant_rt/node", "firmware_shim/core", "firmware_shim/shim", "protocols/canopen",
            "bench/direct"} <= rel  # fmt: skip
    assert all(f.startswith(TREES) for f in rel)


def test_no_c_folder_has_a_circle_inside() -> None:
    for folder in c_folders():
        cycle = find_cycle(use_graph(folder))
        assert cycle is None, f"{folder.relative_to(REPO)}: circle {' -> '.join(cycle or [])}"


def test_plant_folders_stand_on_floors_without_a_circle() -> None:
    graph = tree_graph(REPO / "plant_rt")
    assert find_cycle(graph) is None, f"plant_rt: circle {' -> '.join(find_cycle(graph) or [])}"
    folders = folder_graph(graph)
    assert {f.split("/")[0] for f in folders} <= PLANT_FLOORS.keys(), sorted(folders)
    assert upward_arrows(folders, PLANT_FLOORS) == []
    assert find_cycle(folders) is None, f"plant_rt folders: circle {' -> '.join(find_cycle(folders) or [])}"
    # the API chooses among the models; every model folder stands on the blocks
    models = {f for f in folders if f.startswith("models/")}
    assert len(models) >= 3 and models <= folders["core"]
    assert all("blocks" in folders[m] for m in models)


def test_firmware_folders_have_no_circle() -> None:
    folders = folder_graph(tree_graph(REPO / "firmware_shim"))
    assert find_cycle(folders) is None, f"firmware_shim folders: circle {' -> '.join(find_cycle(folders) or [])}"


def test_checker_finds_the_old_plant_circle(tmp_path: Path) -> None:
    """The layout before issue 53: plant_machine.c chose the model by `if` and called the flux-map model's
    preparation; plant_machine_fluxmap.c called the machine block's angle helpers back; all in plant_rt/core."""
    core = tmp_path / "core"
    core.mkdir()
    (core / "plant_machine.h").write_text("typedef struct { int k; } plant_state_t;\n")
    (core / "plant_machine.c").write_text(
        '#include "plant_machine.h"\nint plant_machine_resync_angle(plant_state_t *s)\n{\n    return s->k;\n}\n'
        "int plant_machine_prepare(plant_state_t *s)\n{\n    return plant_machine_flux_prepare(s);\n}\n"
    )
    (core / "plant_machine_fluxmap.c").write_text(
        '#include "plant_machine.h"\nint plant_machine_flux_prepare(plant_state_t *s)\n{\n'
        "    return plant_machine_resync_angle(s);\n}\n"
    )
    assert find_cycle(use_graph(core)) in (
        ["plant_machine", "plant_machine_fluxmap", "plant_machine"],
        ["plant_machine_fluxmap", "plant_machine", "plant_machine_fluxmap"],
    )
    # the same two files in two folders: a circle of folders, and an arrow up from a floor below
    models = tmp_path / "models" / "flux_map"
    models.mkdir(parents=True)
    (core / "plant_machine_fluxmap.c").rename(models / "plant_machine_fluxmap.c")
    folders = folder_graph(tree_graph(tmp_path))
    assert folders == {"core": {"models/flux_map"}, "models/flux_map": {"core"}}
    assert find_cycle(folders) is not None
    assert upward_arrows(folders, PLANT_FLOORS) == ["models/flux_map -> core"]
