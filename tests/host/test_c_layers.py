"""The CANopen slave is layered like CANopenNode: the node composes the services, no service
knows the node, and no two modules of protocols/canopen/ include each other.

The include lines of protocols/canopen/*.c and *.h are read; a module is a file stem
(co_pdo.c + co_pdo.h = co_pdo). Two rules:
  - a service (co_pdo*, co_sdo*, co_emcy*, co_od*) does not reach co_node.h, directly or
    through another header;
  - the module graph has no cycle (co_node -> co_pdo -> co_node was the old one).
The checker itself is tested on the old layout, rebuilt in a temporary folder.

The controller cores (firmware_shim/core/*.c, *.h) and each paper's law folder (firmware_shim/laws/*/) have
no include cycle either (issue 26: the
Yao 2020 DPCC and its identification included each other; the shared model, configuration and
state are now in yao2020_model, below both).
"""

from __future__ import annotations

import re
from pathlib import Path

from bench.paths import REPO

CANOPEN = REPO / "protocols" / "canopen"
CORE = REPO / "firmware_shim" / "core"
LAWS = REPO / "firmware_shim" / "laws"  # the papers' law folders
SERVICE_PREFIXES = ("co_pdo", "co_sdo", "co_emcy", "co_od")
NODE = "co_node"
INCLUDE_RE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)


def module_graph(folder: Path) -> dict[str, set[str]]:
    """Module -> modules it includes (only headers of `folder`; a module's own header is no edge)."""
    files = sorted(folder.glob("*.[ch]"))
    local = {p.name for p in files if p.suffix == ".h"}
    graph: dict[str, set[str]] = {p.stem: set() for p in files}
    for path in files:
        for name in INCLUDE_RE.findall(path.read_text()):
            stem = Path(name).stem
            if name in local and stem != path.stem:
                graph[path.stem].add(stem)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return path[path.index(n) :] + [n]
            if n not in state and (found := visit(n)):
                return found
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (found := visit(m)):
            return found
    return None


def reaches(graph: dict[str, set[str]], start: str, target: str) -> list[str] | None:
    """An include chain start -> ... -> target, or None."""
    seen, stack = {start}, [[start]]
    while stack:
        chain = stack.pop()
        for n in sorted(graph.get(chain[-1], ())):
            if n == target:
                return chain + [n]
            if n not in seen:
                seen.add(n)
                stack.append(chain + [n])
    return None


def layering_violations(folder: Path) -> list[str]:
    graph = module_graph(folder)
    bad = []
    for m in sorted(graph):
        if m.startswith(SERVICE_PREFIXES) and (chain := reaches(graph, m, NODE)):
            bad.append(f"service {m} includes the node: {' -> '.join(chain)}")
    if cycle := find_cycle(graph):
        bad.append(f"include cycle: {' -> '.join(cycle)}")
    return bad


def test_canopen_services_do_not_include_the_node_and_nothing_is_circular() -> None:
    assert (CANOPEN / "co_node.h").exists()
    assert layering_violations(CANOPEN) == []


def test_every_service_has_its_own_header() -> None:
    for service in ("co_pdo", "co_sdo_server", "co_emcy", "co_od"):
        assert (CANOPEN / f"{service}.h").exists(), service
        assert f'#include "{service}.h"' in (CANOPEN / f"{service}.c").read_text(), service


def test_checker_finds_the_old_cycle(tmp_path: Path) -> None:
    """The layout before issue 13: the services' prototypes in co_node.h, the services
    including co_node.h and calling back into co_node.c."""
    old = {
        "co_frame.h": [],
        "co_od.h": [],
        "co_od.c": ["co_od.h"],
        "co_node.h": ["co_frame.h", "co_od.h"],
        "co_node.c": ["co_node.h"],
        "co_pdo.c": ["co_node.h"],
        "co_sdo_server.c": ["co_node.h"],
        "co_membus.h": ["co_frame.h", "co_node.h"],
        "co_membus.c": ["co_membus.h"],
    }
    for name, includes in old.items():
        (tmp_path / name).write_text("".join(f'#include "{h}"\n' for h in includes) + "#include <string.h>\n")
    # The old cycle ran through the services' prototypes in co_node.h, so it shows as services
    # including the node:
    bad = layering_violations(tmp_path)
    assert "service co_pdo includes the node: co_pdo -> co_node" in bad
    assert "service co_sdo_server includes the node: co_sdo_server -> co_node" in bad
    # A half-way state (service headers, but a service still including the node) is also a cycle:
    (tmp_path / "co_pdo.h").write_text('#include "co_od.h"\n')
    (tmp_path / "co_node.h").write_text('#include "co_od.h"\n#include "co_pdo.h"\n')
    (tmp_path / "co_pdo.c").write_text('#include "co_pdo.h"\n#include "co_node.h"\n')
    assert any(v.startswith("include cycle: co_node -> co_pdo -> co_node") for v in layering_violations(tmp_path))


def test_checker_on_synthetic_graphs() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"x": {"y"}, "y": {"y"}}) == ["y", "y"]
    assert reaches({"s": {"h"}, "h": {"co_node"}}, "s", "co_node") == ["s", "h", "co_node"]


def test_controller_cores_have_no_include_cycle() -> None:
    graph = module_graph(CORE)
    assert find_cycle(graph) is None, f"include cycle: {' -> '.join(find_cycle(graph) or [])}"
    for folder in sorted(LAWS.iterdir()):  # each paper's law folder
        law = module_graph(folder)
        assert find_cycle(law) is None, f"{folder.name}: include cycle: {' -> '.join(find_cycle(law) or [])}"
        graph |= law
    assert {"yao2020_dpcc", "yao2020_identification", "yao2020_model"} <= graph.keys()
    # Yao 2020: model <- identification <- dpcc; neither the identification nor the RLS
    # baseline reaches the DPCC.
    assert reaches(graph, "yao2020_identification", "yao2020_dpcc") is None
    assert reaches(graph, "yao2020_rls", "yao2020_dpcc") is None
    assert reaches(graph, "yao2020_dpcc", "yao2020_model") == ["yao2020_dpcc", "yao2020_model"]


def test_checker_finds_the_old_yao2020_cycle(tmp_path: Path) -> None:
    """The layout before issue 26: the DPCC's types and model helpers in yao2020_dpcc.h, which
    the identification's header included, and yao2020_dpcc.c calling the identification."""
    old = {
        "dq_math.h": [],
        "yao2020_dpcc.h": [],
        "yao2020_dpcc.c": ["yao2020_dpcc.h", "dq_math.h", "yao2020_identification.h"],
        "yao2020_identification.h": ["yao2020_dpcc.h"],
        "yao2020_identification.c": ["yao2020_identification.h"],
        "yao2020_rls.h": [],
        "yao2020_rls.c": ["yao2020_rls.h", "yao2020_dpcc.h"],
    }
    for name, includes in old.items():
        (tmp_path / name).write_text("".join(f'#include "{h}"\n' for h in includes) + "#include <math.h>\n")
    assert find_cycle(module_graph(tmp_path)) == ["yao2020_dpcc", "yao2020_identification", "yao2020_dpcc"]
