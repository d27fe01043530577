"""od_<node>.c: a node's RAM struct, its EDS defaults and its sorted entry table (co_od_entry_t: access, PDO
mapping, node-ID relative defaults, LowLimit/HighLimit ranges), bound into the node's co_od_t."""

from __future__ import annotations

from canopen.objectdictionary import datatypes

from . import generated_note
from .c_types import DT_NAMES, c_float, default_literal
from .model import Entry, NodeModel


def entry_row(up: str, e: Entry) -> str:
    """One row of a node's entry table (co_od_entry_t): index, subindex, type, flags, size, value, limits."""
    var = e.var
    flags = []
    if var.access_type in ("ro", "rw", "rwr", "rww", "const"):
        flags.append("CO_ODF_READ")
    if var.access_type in ("wo", "rw", "rwr", "rww"):
        flags.append("CO_ODF_WRITE")
    if var.pdo_mappable:
        flags.append("CO_ODF_PDO")
    if var.relative:
        flags.append("CO_ODF_NODEID")
    if e.low is not None:
        flags.append("CO_ODF_LIMITS")
    if var.data_type == datatypes.VISIBLE_STRING:
        size = str(e.capacity)
    elif var.data_type == datatypes.DOMAIN:
        size = "0"
    else:
        size = f"sizeof(OD_{up}.{e.field})"
    if e.low is None:
        lim = "{.i = 0}, {.i = 0}"
    elif var.data_type == datatypes.REAL32:
        lim = f"{{.f = {c_float(float(e.low))}}}, {{.f = {c_float(float(e.high))}}}"  # type: ignore[arg-type]
    else:
        lim = f"{{.i = {int(e.low)}}}, {{.i = {int(e.high)}}}"  # type: ignore[arg-type]
    ptr = f"OD_{up}.{e.field}" if var.data_type == datatypes.VISIBLE_STRING else f"&OD_{up}.{e.field}"
    return (
        f"    {{0x{var.index:04X}u, 0x{var.subindex:02X}u, {DT_NAMES[var.data_type]}, "
        f"{' | '.join(flags) or '0'}, {size}, {ptr}, {lim}}}, /* {var.name} */"
    )


def node_source(node: str, model: NodeModel) -> str:
    """od_<node>.c: the RAM struct OD_<NODE>, its defaults, the entry table and the co_od_t od_<node>."""
    up = node.upper()
    c: list[str] = [
        f"/* od_{node}.c - {generated_note(f'{node}.eds')} */",
        f'#include "od_{node}.h"',
        "",
        f"od_{node}_ram_t OD_{up};",
        "",
    ]
    c.append(f"static const od_{node}_ram_t defaults = {{")
    for e in model.entries:
        lit = default_literal(e.var)
        if lit is not None:
            c.append(f"    .{e.field} = {lit},")
    c.append("};\n")
    c.append("static const co_od_entry_t entries[] = {")
    c += [entry_row(up, e) for e in model.entries]
    c.append("};\n")
    c.append(
        f"const co_od_t od_{node} = {{entries, (uint16_t)(sizeof entries / sizeof entries[0]), &OD_{up}, "
        f"&defaults, sizeof(od_{node}_comm_t), sizeof(od_{node}_ram_t)}};"
    )
    c.append("")
    return "\n".join(c)
