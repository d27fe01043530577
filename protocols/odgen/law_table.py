"""current_law_table.c: the registry of the current laws (firmware_shim/core/current_law.h), from the drive's EDS:
the values of Controller.controller and the records whose CurrentLaws key names them."""

from __future__ import annotations

import configparser

import canopen
from canopen.objectdictionary import ODRecord
from eds_reader import EdsError, value_names  # protocols/: gen_od.py puts its folder on sys.path

from . import generated_note
from .c_types import C_TYPES, c_ident, default_of, record_type

LAW_ENUM = ("Controller", "controller")  # the entry whose ValueNames name the current laws
OPEN_LOOP = "open_loop"  # value 0 of that entry: the drive app's own open loop, not a law


def law_records(
    od: canopen.ObjectDictionary, raw: configparser.ConfigParser, names: tuple[str, ...]
) -> dict[str, ODRecord]:
    """The record of each law that has one: the record whose EDS section names the law in its CurrentLaws key."""
    records: dict[str, ODRecord] = {}
    for obj in od.values():
        sec = f"{obj.index:04X}"
        if isinstance(obj, ODRecord) and raw.has_option(sec, "CurrentLaws"):
            for law in (n.strip() for n in raw.get(sec, "CurrentLaws").split(",")):
                if law not in names:
                    raise EdsError(f"[{sec}] {obj.name}: CurrentLaws names {law!r}, not a value of {LAW_ENUM}")
                records[law] = obj
    return records


def _record_defaults(node: str, records: dict[str, ODRecord]) -> list[str]:
    """The EDS defaults of each law record (x<index>_defaults), each checked to fit CURRENT_LAW_RECORD_BYTES."""
    out: list[str] = []
    done: set[int] = set()
    for obj in records.values():
        if obj.index in done:
            continue
        done.add(obj.index)
        rtype = record_type(node, obj.name)
        rows = [f"    .{c_ident(v.name)} = {default_of(v)}," for v in obj.values() if v.data_type in C_TYPES]
        out.append(f"static const {rtype} x{obj.index:04X}_defaults = {{\n" + "\n".join(rows) + "\n};")
        out.append(
            f'_Static_assert(sizeof({rtype}) <= CURRENT_LAW_RECORD_BYTES, "record 0x{obj.index:04X} {obj.name} '
            f'exceeds CURRENT_LAW_RECORD_BYTES (current_law.h)");'
        )
    return out


def law_table(node: str, od: canopen.ObjectDictionary, raw: configparser.ConfigParser) -> str | None:
    """The registry of the current laws (firmware_shim/core/current_law.h): one row per value of
    Controller.controller but open_loop, bound to the descriptor `current_law_<value name>` its C file
    defines and to the record whose EDS section names it in its CurrentLaws key (its parameters and
    status), with that record's EDS defaults. Plain C: the cores link it."""
    if LAW_ENUM[0] not in od.names:
        return None
    names = value_names(raw, od[LAW_ENUM[0]][LAW_ENUM[1]])
    records = law_records(od, raw, names)
    out = [
        f"/* current_law_table.c - {generated_note(f'{node}.eds')}",
        " * The current laws the drive can select (Controller.controller), each with its EDS record. */",
        '#include "current_law.h"',
        "",
        *_record_defaults(node, records),
        "",
    ]
    laws = [n for n in names if n != OPEN_LOOP]
    out += [f"extern const current_law_t current_law_{n};" for n in laws]
    out.append("")
    out.append("const current_law_entry_t current_law_table[] = {")
    for n in laws:
        value = names.index(n)
        obj = records.get(n)
        if obj is None:
            out.append(f"    {{{value}u, &current_law_{n}, 0u, 0u, 0}},")
        else:
            rtype = record_type(node, obj.name)
            out.append(
                f"    {{{value}u, &current_law_{n}, 0x{obj.index:04X}u, (uint32_t)sizeof({rtype}), "
                f"&x{obj.index:04X}_defaults}},"
            )
    out.append("};")
    out.append("const uint8_t current_law_count = (uint8_t)(sizeof current_law_table / sizeof current_law_table[0]);")
    out.append("")
    return "\n".join(out)
