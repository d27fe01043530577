"""The generated headers: od_<node>_fields.h (plain C: names, defaults, enumerations, bits, EMCY codes of a node's
EDS), od_<node>.h (the node's RAM struct, its CANopen object dictionary) and eds_common.h (from common.ini: the
CANopen stack's EMCY codes and the fault injector's sizes)."""

from __future__ import annotations

from pathlib import Path

import eds_reader  # protocols/: gen_od.py puts its folder on sys.path
from eds_reader import EdsError

from . import EDS_DIR, generated_note
from .fields import bits, emcy_defines, enums
from .model import NodeModel


def fields_header(node: str, model: NodeModel, eds: Path) -> str:
    """od_<node>_fields.h: the #defines of indices and sub-indices, the plain records and their field lists,
    the enumerations, the named bits and the node's own EMCY codes."""
    up = node.upper()
    return "\n".join(
        [
            f"/* od_{node}_fields.h - {generated_note(f'{node}.eds')}",
            " * Plain C, no CANopen: the cores include it for the names, defaults and enumerations",
            " * of the EDS (one source), the node app for its copy tables (co_field_map.h), the bits",
            f" * of its bit-field entries (BitNames) and the node's own EMCY codes ({up}_EMCY_*). */",
            f"#ifndef OD_{up}_FIELDS_H",
            f"#define OD_{up}_FIELDS_H",
            "",
            "#include <stdint.h>",
            "",
            *model.defines,
            *model.field_lists,
            *model_records(up, model),
            *enums(node, model.od, model.raw),
            *bits(node, model.od, model.raw, f"{node}.eds"),
            *emcy_defines(up, eds_reader.emcy_codes(eds_reader.parse(eds), str(eds)), f"{node}.eds"),
            f"#endif /* OD_{up}_FIELDS_H */",
            "",
        ]
    )


def node_header(node: str, model: NodeModel) -> str:
    """od_<node>.h: the record types, the communication and manufacturer areas, the RAM struct and the OD."""
    up = node.upper()
    h: list[str] = [
        f"/* od_{node}.h - {generated_note(f'{node}.eds')} */",
        f"#ifndef OD_{up}_H",
        f"#define OD_{up}_H",
        "",
        "#include <stdint.h>",
        '#include "co_od.h"',
        f'#include "od_{node}_fields.h"',
        "",
        f"#define OD_{up}_DEFAULT_NODE_ID {model.od.node_id or 0}u",
        "",
    ]
    h += model.record_types
    h.append("typedef struct {")
    h += [f"    {f}" for f in model.comm_fields]
    h.append(f"}} od_{node}_comm_t;\n")
    h.append("typedef struct {")
    h += [f"    {f}" for f in model.mfr_fields]
    h.append(f"}} od_{node}_mfr_t;\n")
    h.append("/* The communication part comes first: a communication reset restores it alone. */")
    h.append(f"typedef struct {{\n    od_{node}_comm_t comm;\n    od_{node}_mfr_t mfr;\n}} od_{node}_ram_t;\n")
    h.append(f"extern od_{node}_ram_t OD_{up};")
    h.append(f"extern const co_od_t od_{node};\n")
    h += ["", f"#endif /* OD_{up}_H */", ""]
    return "\n".join(h)


def common_header(eds_dir: Path | None = None) -> str:
    """eds_common.h from common.ini: the CANopen stack's own EMCY codes (CO_EMCY_*, co_emcy.h includes it) and the
    fault injector's fixed sizes (FI_*, fault_injector.h). Plain C, no include."""
    path = (eds_dir or EDS_DIR) / eds_reader.COMMON
    if not path.is_file():
        raise EdsError(f"{path}: missing (what both nodes share: the stack's EMCY codes, the fault injector's sizes)")
    raw = eds_reader.parse(path)
    sizes = eds_reader.fault_injector(raw, str(path))
    return "\n".join(
        [
            f"/* eds_common.h - {generated_note(eds_reader.COMMON)}",
            " * Plain C: what both nodes share, the CANopen stack's own EMCY codes (co_emcy.h) and the fault",
            " * injector's fixed sizes (fault_injector.h). */",
            "#ifndef EDS_COMMON_H",
            "#define EDS_COMMON_H",
            "",
            *emcy_defines("CO", eds_reader.emcy_codes(raw, str(path)), eds_reader.COMMON),
            f"/* The fault injector's fixed sizes ([{eds_reader.FAULT_SECTION}] of {eds_reader.COMMON}) */",
            *(f"#define {eds_reader.fault_macro(key)} {value}u" for key, value in sizes.items()),
            "",
            "#endif /* EDS_COMMON_H */",
            "",
        ]
    )


def model_records(up: str, model: NodeModel) -> list[str]:
    """X(name, record type, record member, index, field list) of each machine model's own record ("Model <name>")."""
    rows = "".join(f" \\\n    X({n}, {t}, {m}, 0x{i:04X}u, {f})" for n, t, m, i, f in model.model_records)
    return [
        '/* the machine models\' own records ("Model <name>"): X(name, record type, record member, index, its',
        " * parameters' X-macro list) */",
        f"#define OD_{up}_MODEL_RECORDS(X){rows}",
        "",
    ]
