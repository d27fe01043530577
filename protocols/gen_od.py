#!/usr/bin/env python3
"""Generate the C object dictionary of a node from its EDS file.

The EDS files in protocols/eds/ are the single source of truth of the CANopen
contract. This generator reads them with python `canopen` (the same reader the
bench uses) and writes protocols/generated/od_<node>.h/.c: a RAM struct holding
every value, its EDS defaults, a sorted entry table (access, PDO mapping,
node-ID relative defaults, LowLimit/HighLimit ranges) and #defines for the
indices and sub-indices the node code uses.

    python protocols/gen_od.py            # regenerate all
    python protocols/gen_od.py --check    # exit 1 if a generated file is stale
    python protocols/gen_od.py --law DIR --out OUTDIR   # a user's law (protocols/gen_law.py):
        # OUTDIR/eds/{drive,plant}.eds merged with DIR/law.eds, OUTDIR/generated/ from them

User laws' records live in 0x2400..0x24FF (reserved; docs/ARCHITECTURE.md, "A law from your own folder").

The EMCY codes come from the EDS too: a node's own from its [EmergencyCodes] section
(`#define <NODE>_EMCY_<NAME>` in od_<node>_fields.h), the CANopen stack's own from the
shared protocols/eds/common.ini, with the fault injector's table size
(`CO_EMCY_<NAME>`, `FI_MAX_RULES`: protocols/generated/eds_common.h).

So do the masks of a bit-field entry's bits, named by the key BitNames of its section
(`#define <NODE>_<ENTRY>_<BIT>` in od_<node>_fields.h: PLANT_STATUS_* of Measurement.status).

The EDS files are read through protocols/eds_reader.py, the bench's reader too (what
`canopen` ignores: REAL32 limits, ValueNames, BitNames, EMCY codes). The generator stands on its own
(python with `canopen`, nothing of the bench): firmware builds can run it anywhere.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(
    0, str(HERE)
)  # the EDS reader and odgen/ beside this file, however it is run (script, runpy, importlib)
try:
    import eds_reader
    from eds_reader import EdsError, EmcyCode, float_limits, section_of, value_names
    from odgen import EDS_DIR, NODES, OUT_DIR
    from odgen.c_types import C_TYPES, DT_NAMES, c_ident
    from odgen.generate import generate, law_eds, render
    from odgen.header import common_header as render_common
    from odgen.law_table import LAW_ENUM, OPEN_LOOP, law_table
    from odgen.model import STRING_MIN_CAPACITY, Entry, NodeModel, load
finally:
    sys.path.remove(str(HERE))

__all__ = [  # what this module has always offered its importers (the tests), now from odgen/
    "C_TYPES",
    "DT_NAMES",
    "EDS_DIR",
    "LAW_ENUM",
    "NODES",
    "OPEN_LOOP",
    "OUT_DIR",
    "STRING_MIN_CAPACITY",
    "EdsError",
    "EmcyCode",
    "Entry",
    "NodeModel",
    "c_ident",
    "eds_reader",
    "float_limits",
    "generate",
    "law_eds",
    "law_table",
    "load",
    "main",
    "render",
    "render_common",
    "section_of",
    "value_names",
]


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="exit 1 if a generated file differs from the EDS")
    ap.add_argument(
        "--law",
        type=Path,
        default=None,
        metavar="DIR",
        help="a user's current law: its folder's law.eds (one record in 0x2400..0x24FF) merged into drive.eds "
        "(protocols/gen_law.py); needs --out",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="OUTDIR",
        help="write OUTDIR/eds/*.eds (the EDS files used) and OUTDIR/generated/ instead of protocols/generated",
    )
    return ap


def _write(files: dict[Path, str], check: bool) -> list[str]:
    """Write each file that differs (or, with check, write nothing); the stale files' paths."""
    stale = []
    for path, text in files.items():
        if check:
            if not path.exists() or path.read_text() != text:
                stale.append(str(path))
        elif not path.exists() or path.read_text() != text:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            shown = path.resolve().relative_to(HERE.parent) if path.resolve().is_relative_to(HERE.parent) else path
            print(f"gen_od: wrote {shown}")
    return stale


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.law is not None and args.out is None:
        print("gen_od: --law needs --out OUTDIR (protocols/generated is the plain drive's)", file=sys.stderr)
        return 2
    files = generate(args.law, args.out)
    if isinstance(files, int):
        return files
    stale = _write(files, args.check)
    if stale:
        print("gen_od: stale generated files (run `python protocols/gen_od.py`): " + ", ".join(stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
