"""The bench's Python modules import one another without a circle (issue 27): every import counts, at the top
of a module, under TYPE_CHECKING or inside a function, since each is an arrow of the structure. A package's
__init__.py is its face: importing bench.run means bench/run/__init__.py."""

from __future__ import annotations

import ast
from pathlib import Path

from bench.paths import REPO

BENCH = REPO / "bench"


def _module(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _targets(path: Path, mod: str, modules: set[str]) -> set[str]:
    """The bench modules this file imports (a name imported from a package that is a module counts as it)."""
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*up, *([base] if base else [])])
            names = [base, *(f"{base}.{a.name}" for a in node.names)]
        else:
            continue
        out |= {n for n in names if n in modules}
    return out - {mod}


def _graph() -> dict[str, set[str]]:
    files = {_module(p): p for p in BENCH.rglob("*.py")}
    return {m: _targets(p, m, set(files)) for m, p in files.items()}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_graph_is_read() -> None:
    g = _graph()
    assert "bench.run.options" in g["bench.run.loop.session"] and "bench.scenario" in g["bench.run.command"]
    assert "bench.run.bus.box.life" in g["bench.run"]  # a face's imports of what it re-exports are arrows too


def test_the_bench_imports_without_a_circle() -> None:
    circles = _circles(_graph())
    assert not circles, "\n".join(" <-> ".join(c) for c in circles)


def test_a_circle_is_found() -> None:
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


# The floors of bench/, lowest first (docs/ARCHITECTURE.md, "The bench's floors"): a module may import its own floor
# (without a circle) and the floors below, never one above. A module's floor is that of its longest listed prefix.
FLOORS: list[tuple[str, tuple[str, ...]]] = [
    (
        "ground",
        (
            "bench",
            "bench.root",
            "bench.paths",
            "bench.stop",
            "bench.eds",
            "bench.canbus",
            "bench.mcu",
            "bench.metrics",
            "bench.laws",
            "bench.law",
            "bench.law_upgrade",
            "bench.extras",
            "bench.signals",
            "bench.emcy",
            "bench.result",
            "bench.law_py",
        ),
    ),
    ("scenario", ("bench.scenario", "bench.run.options", "bench.motor")),
    ("bus and nodes", ("bench.run.bus",)),
    ("configuration and the PDO loop", ("bench.run.loop",)),
    ("frames", ("bench.run.record",)),
    ("decode", ("bench.run.decode",)),
    ("verdict", ("bench.run.verdict",)),
    ("sinks", ("bench.run.sinks", "bench.view")),
    ("a run", ("bench.run",)),
    (
        "studies and masters",
        ("bench.claims", "bench.cia402", "bench.sweep", "bench.replay", "bench.faults", "bench.port_check"),
    ),
    ("reports and tools", ("bench.reproduce", "bench.demo", "bench.tools")),
    (
        "the command line",
        (
            "bench.cli",
            "bench.commands",
            "bench.cli_tools",
            "bench.cli_runs",
            "bench.cli_box",
            "bench.cli_motor",
            "bench.cli_in_process",
            "bench.api",
        ),
    ),
    ("the pytest plugin", ("bench.pytest_plugin",)),
]


def floor_of(module: str) -> int:
    best, floor = -1, -1
    for i, (_, prefixes) in enumerate(FLOORS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best and (p != "bench" or module == "bench"):
                best, floor = len(p), i
    assert floor >= 0, f"{module} is on no floor: add it to FLOORS and to docs/ARCHITECTURE.md"
    return floor


def upward(graph: dict[str, set[str]]) -> list[str]:
    return sorted(
        f"{m} ({FLOORS[floor_of(m)][0]}) -> {t} ({FLOORS[floor_of(t)][0]})"
        for m, ts in graph.items()
        for t in ts
        if floor_of(t) > floor_of(m)
    )


def test_no_import_runs_up_a_floor() -> None:
    arrows = upward(_graph())
    assert not arrows, "\n".join(arrows)


def test_an_upward_import_is_found() -> None:
    assert upward({"bench.run.decode.decoder": {"bench.run.verdict.faults", "bench.eds"}}) == [
        "bench.run.decode.decoder (decode) -> bench.run.verdict.faults (verdict)"
    ]
    assert floor_of("bench.laws") == floor_of("bench.law") == 0 and floor_of("bench.run.pipeline") == 8


def test_the_architecture_shows_every_floor() -> None:
    """docs/ARCHITECTURE.md's floors table has a row per floor of FLOORS, in the same order."""
    text = (REPO / "docs" / "ARCHITECTURE.md").read_text()
    table = text[text.index("### The floors of `bench/`") :]
    rows = [line.split("|")[1].strip() for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    assert rows[1 : len(FLOORS) + 1] == [name for name, _ in FLOORS]


# Faces (issue 53): the modules under a prefix use a package through its face (its __init__.py) only, never a module
# inside it, so that the package can move its inner floors without breaking them. (user prefix, package)
FACES: list[tuple[str, str]] = [("bench.tools", "bench.run")]


def behind_faces(graph: dict[str, set[str]], faces: list[tuple[str, str]] = FACES) -> list[str]:
    return sorted(
        f"{m} -> {t} (use {package}'s face, {package})"
        for user, package in faces
        for m, ts in graph.items()
        if m == user or m.startswith(user + ".")
        for t in ts
        if t.startswith(package + ".")
    )


def test_the_tools_use_the_run_s_face_only() -> None:
    arrows = behind_faces(_graph())
    assert not arrows, "\n".join(arrows)


def test_an_import_behind_a_face_is_found() -> None:
    graph = {
        "bench.tools.perf.vcan": {"bench.run", "bench.run.pipeline", "bench.paths"},
        "bench.tools.doctor": {"bench.run"},
        "bench.reproduce.report": {"bench.run.pipeline"},
    }
    assert behind_faces(graph) == ["bench.tools.perf.vcan -> bench.run.pipeline (use bench.run's face, bench.run)"]


def test_the_run_s_face_names_what_it_imports() -> None:
    """bench/run/__init__.py: each public name resolves to the object of the module its table names; the table,
    __all__ and the face's TYPE_CHECKING imports (the arrows this graph sees) say the same."""
    import importlib

    import bench.run as face

    path = BENCH / "run" / "__init__.py"
    typed: dict[str, tuple[str, str]] = {}
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("bench.run."):
            typed |= {a.asname or a.name: (node.module or "", a.name) for a in node.names}
    assert typed == face._WHERE and sorted(face.__all__) == sorted(face._WHERE)
    for name, (module, attr) in face._WHERE.items():
        assert getattr(face, name) is getattr(importlib.import_module(module), attr), name
