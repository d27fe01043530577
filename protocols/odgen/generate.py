"""Every generated file, by name or by path: a node's (render), a build's (generate: the merged EDS files, both
nodes and eds_common.h). The drive's EDS is protocols/eds/drive.eds with the law folders merged into it by
protocols/gen_law.py (law_eds): the papers' (firmware_shim/laws/*/) always, a user's on top."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import eds_reader  # protocols/: gen_od.py puts its folder on sys.path

from . import EDS_DIR, HERE, NODES, OUT_DIR
from .c_types import C_TYPES
from .header import common_header, fields_header, node_header
from .law_table import law_table
from .model import eds_path, load
from .source import node_source


def render(node: str, eds_dir: Path | None = None) -> dict[str, str]:
    """The generated files of a node, by file name (from EDS_DIR's EDS files, or eds_dir's: --law)."""
    model = load(node, eds_dir)
    eds = eds_path(node, eds_dir)
    fields = fields_header(node, model, eds)
    files = {f"od_{node}.h": node_header(node, model), f"od_{node}.c": node_source(node, model)}
    files[f"od_{node}_fields.h"] = fields
    table = law_table(node, model.od, eds_reader.parse(eds))
    if table is not None:
        files["current_law_table.c"] = table
    return files


def law_eds(law: Path | None, out_eds: Path) -> None:
    """The merged EDS files in out_eds: drive.eds with the papers' law folders and a user's (None: none) merged
    (gen_law.py), plant.eds, common.ini."""
    sys.path.insert(0, str(HERE))
    try:
        import gen_law
    finally:
        sys.path.remove(str(HERE))
    text = gen_law.merge_all(EDS_DIR / "drive.eds", law, C_TYPES.keys())
    out_eds.mkdir(parents=True, exist_ok=True)
    (out_eds / "drive.eds").write_text(text)
    for name in ("plant.eds", eds_reader.COMMON):
        (out_eds / name).write_text((EDS_DIR / name).read_text())


def generate(law: Path | None, out_dir: Path | None) -> dict[Path, str] | int:
    """Every generated file by path (under out_dir/eds and out_dir/generated, else protocols/generated and its
    eds/), or gen_od's exit status (2) after a one-line refusal."""
    with tempfile.TemporaryDirectory() as tmp:
        try:
            assert law is None or out_dir is not None  # gen_od.py refuses --law without --out
            eds_dir = Path(tmp) / "eds"
            law_eds(law, eds_dir)
            out = OUT_DIR if out_dir is None else out_dir / "generated"
            files = {
                (OUT_DIR if out_dir is None else out_dir) / "eds" / p.name: p.read_text()
                for p in sorted(eds_dir.iterdir())
            }
            eds_reader.emcy_table(eds_dir, NODES)  # no code or name declared twice
            for node in NODES:
                files |= {out / name: text for name, text in render(node, eds_dir).items()}
            files[out / "eds_common.h"] = common_header(eds_dir)
        except ValueError as exc:  # EdsError, gen_law.LawError
            print(f"gen_od: {exc}", file=sys.stderr)
            return 2
    return files
