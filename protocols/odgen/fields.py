"""The pieces of od_<node>_fields.h, plain C the cores include: the X-macro field lists of a manufacturer record
(field_list), the enumerations of the entries with ValueNames (enums), the masks of the named bits of a bit-field
entry (bits) and the #defines of EMCY codes (emcy_defines, eds_common.h's too)."""

from __future__ import annotations

import configparser

import canopen
import eds_reader  # protocols/: gen_od.py puts its folder on sys.path
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes
from eds_reader import EmcyCode, value_names

from .c_types import c_ident, default_of

NOT_NUMBERS = (datatypes.DOMAIN, datatypes.VISIBLE_STRING)


def field_list(macro_base: str, obj: ODRecord | ODArray, oname: str, subs: list[ODVariable]) -> str:
    """X-macros of a manufacturer record's values, X(index, subindex, record member, field): its
    parameters (writable: _PARAMS) and its status values (read-only: _STATUS). A node app expands them
    into the tables that copy the record to and from its core's structs, whose fields carry the same
    names (the compiler refuses a name the core does not have): protocols/canopen/co_field_map.h."""
    out = []
    for suffix, writable in (("PARAMS", True), ("STATUS", False)):
        rows = [
            f"    X(0x{v.index:04X}u, 0x{v.subindex:02X}u, {oname}, {c_ident(v.name)}, {default_of(v)})"
            for v in subs
            if v.subindex != 0 and v.data_type not in NOT_NUMBERS and v.writable == writable
        ]
        if rows:
            out.append(
                f"/* 0x{obj.index:04X} {obj.name}, {'parameters' if writable else 'status'}: "
                f"X(index, subindex, record, field, EDS default) */\n#define OD_{macro_base}_{suffix}(X) \\\n"
                + " \\\n".join(rows)
                + "\n"
            )
    defaults = [
        f"#define OD_{macro_base}_{c_ident(v.name).upper()}_DEFAULT {default_of(v)}"
        for v in subs
        if v.subindex != 0 and v.data_type not in NOT_NUMBERS
    ]
    return "\n" + "\n".join(out) + "\n" + "\n".join(defaults) + "\n"


def _variables(od: canopen.ObjectDictionary) -> list[tuple[ODVariable | ODRecord | ODArray, ODVariable]]:
    """Every entry of the OD with its object, in the OD's order."""
    return [(obj, var) for obj in od.values() for var in ([obj] if isinstance(obj, ODVariable) else obj.values())]


def enums(node: str, od: canopen.ObjectDictionary, raw: configparser.ConfigParser) -> list[str]:
    """`enum { OD_<NODE>_<ENTRY>_<NAME> = <value>, ... };` of each entry with ValueNames."""
    out = []
    for obj, var in _variables(od):
        names = value_names(raw, var)
        if names:
            base = f"OD_{node.upper()}_{c_ident(var.name).upper()}"
            rows = ",\n".join(f"    {base}_{n.upper()} = {i}" for i, n in enumerate(names))
            out.append(f"/* 0x{var.index:04X}:{var.subindex:02X} {obj.name}.{var.name} */\nenum {{\n{rows}\n}};\n")
    return out


def bits(node: str, od: canopen.ObjectDictionary, raw: configparser.ConfigParser, source: str) -> list[str]:
    """`#define <NODE>_<ENTRY>_<NAME> 0x<mask>u` of each named bit of a bit-field entry (key BitNames of its section:
    protocols/eds_reader.py), e.g. PLANT_STATUS_HELD 0x08u of plant.eds 0x2100:05 Measurement.status."""
    out = []
    for obj, var in _variables(od):
        names = eds_reader.bit_names(raw, var, source)
        if names:
            base = f"{node.upper()}_{c_ident(var.name).upper()}"
            digits = eds_reader.BIT_WIDTH[var.data_type] // 4
            rows = [f"#define {base}_{n.upper()} 0x{1 << bit:0{digits}X}u" for bit, n in enumerate(names) if n]
            head = f"/* 0x{var.index:04X}:{var.subindex:02X} {obj.name}.{var.name} bits (BitNames of {source}) */"
            out.append("\n".join([head, *rows, ""]))
    return out


def emcy_defines(prefix: str, codes: tuple[EmcyCode, ...], source: str) -> list[str]:
    """`#define <PREFIX>_EMCY_<NAME> 0x<code>u` of each EMCY code of a file, its description as a comment."""
    rows = [
        f"#define {prefix}_EMCY_{c.name.upper()} 0x{c.code:04X}u" + (f" /* {c.description} */" if c.description else "")
        for c in codes
    ]
    return [f"/* EMCY error codes ([{eds_reader.EMCY_SECTION}] of {source}) */", *rows, ""] if rows else []
