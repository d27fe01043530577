"""Read the golden frame vectors of protocols/vectors/frames.txt."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from bench.paths import VECTORS_DIR


@dataclass(frozen=True)
class Frame:
    cob_id: int
    data: bytes

    @classmethod
    def parse(cls, text: str) -> Frame:
        cob, _, hexdata = text.strip().partition("#")
        return cls(int(cob, 16), bytes.fromhex(hexdata))


@dataclass
class Vector:
    name: str
    node: str = ""
    node_id: int = 0
    operational: bool = False
    steps: list[tuple[str, Frame]] = field(default_factory=list)  # ('>', frame) master, ('<', frame) slave


def load_vectors(path: Path | None = None) -> dict[str, Vector]:
    vectors: dict[str, Vector] = {}
    cur: Vector | None = None
    for raw in (path or VECTORS_DIR / "frames.txt").read_text().splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("vector "):
            cur = Vector(line.split()[1])
            vectors[cur.name] = cur
        elif cur is None:
            raise ValueError(f"frames.txt: '{line}' before the first 'vector' line")
        elif line.startswith("node "):
            _, node, nid = line.split()
            cur.node, cur.node_id = node, int(nid, 0)
        elif line == "nmt operational":
            cur.operational = True
        elif line[0] in "<>":
            cur.steps.append((line[0], Frame.parse(line[1:])))
        else:
            raise ValueError(f"frames.txt: cannot parse '{line}'")
    return vectors
