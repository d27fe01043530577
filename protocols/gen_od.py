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
import configparser
import re
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # the EDS reader beside this file, however it is run (script, runpy, importlib)
try:
    import eds_reader
    from eds_reader import EdsError, EmcyCode, float_limits, section_of, value_names
finally:
    sys.path.remove(str(HERE))

EDS_DIR = HERE / "eds"
OUT_DIR = HERE / "generated"
NODES = ("plant", "drive")
STRING_MIN_CAPACITY = 32

C_TYPES = {
    datatypes.BOOLEAN: "uint8_t",
    datatypes.INTEGER8: "int8_t",
    datatypes.INTEGER16: "int16_t",
    datatypes.INTEGER32: "int32_t",
    datatypes.UNSIGNED8: "uint8_t",
    datatypes.UNSIGNED16: "uint16_t",
    datatypes.UNSIGNED32: "uint32_t",
    datatypes.REAL32: "float",
}
DT_NAMES = {
    datatypes.BOOLEAN: "CO_DT_BOOLEAN",
    datatypes.INTEGER8: "CO_DT_INTEGER8",
    datatypes.INTEGER16: "CO_DT_INTEGER16",
    datatypes.INTEGER32: "CO_DT_INTEGER32",
    datatypes.UNSIGNED8: "CO_DT_UNSIGNED8",
    datatypes.UNSIGNED16: "CO_DT_UNSIGNED16",
    datatypes.UNSIGNED32: "CO_DT_UNSIGNED32",
    datatypes.REAL32: "CO_DT_REAL32",
    datatypes.VISIBLE_STRING: "CO_DT_VISIBLE_STRING",
    datatypes.DOMAIN: "CO_DT_DOMAIN",
}


def c_ident(name: str) -> str:
    """EDS ParameterName -> C identifier (standard names lower-cased, manufacturer names kept)."""
    s = re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_")
    if " " in name:
        s = s.lower()
    if not s or s[0].isdigit():
        s = "_" + s
    return s


@dataclass
class Entry:
    var: ODVariable
    field: str  # C member path inside the RAM struct (e.g. "comm.x1017_producer_heartbeat_time")
    ctype: str
    capacity: int  # strings: characters without NUL
    low: float | int | None
    high: float | int | None


def load(
    node: str,
    eds_dir: Path | None = None,
) -> tuple[canopen.ObjectDictionary, list[Entry], list[str], list[str], list[str], list[str], list[str]]:
    """The OD of a node: entries, record types, comm/mfr struct members, #defines, field lists and enums."""
    eds = (eds_dir or EDS_DIR) / f"{node}.eds"
    od = eds_reader.import_od(eds, strict=True)
    raw = eds_reader.parse(eds)
    entries: list[Entry] = []
    comm_fields: list[str] = []
    mfr_fields: list[str] = []
    defines: list[str] = []
    field_lists: list[str] = []
    record_types: list[str] = []
    for index in sorted(od.indices):
        obj = od.indices[index]
        area = comm_fields if index < 0x2000 else mfr_fields
        prefix = "comm" if index < 0x2000 else "mfr"
        oname = f"x{index:04X}_{c_ident(obj.name)}"
        macro_base = f"{node.upper()}_{c_ident(obj.name).upper()}"
        defines.append(f"#define OD_{macro_base}_IDX 0x{index:04X}u")
        subs = [obj] if isinstance(obj, ODVariable) else [obj.subindices[s] for s in sorted(obj.subindices)]
        members: list[str] = []
        for var in subs:
            if var.data_type not in DT_NAMES:
                raise EdsError(f"{eds} [{section_of(var)}] {var.name}: data type 0x{var.data_type:X} not supported")
            sec = section_of(var)
            if isinstance(obj, ODVariable):
                field = f"{prefix}.{oname}"
                member_name = oname
            else:
                member_name = c_ident(var.name)
                field = f"{prefix}.{oname}.{member_name}"
                defines.append(f"#define OD_{macro_base}_{member_name.upper()}_SUB 0x{var.subindex:02X}u")
            capacity = 0
            if var.data_type == datatypes.VISIBLE_STRING:
                default = var.default or ""
                capacity = len(default) if var.access_type == "const" else max(STRING_MIN_CAPACITY, len(default))
                decl = f"char {member_name}[{capacity + 1}];"
                ctype = "char"
            elif var.data_type == datatypes.DOMAIN:
                decl = f"co_domain_t {member_name};"
                ctype = "co_domain_t"
            else:
                ctype = C_TYPES[var.data_type]
                decl = f"{ctype} {member_name};"
            members.append(decl)
            if var.data_type == datatypes.REAL32:
                low, high = float_limits(raw, var)
            else:
                low, high = var.min, var.max
            if (low is None) != (high is None):
                raise EdsError(f"{eds} [{sec}] {var.name}: give both LowLimit and HighLimit or neither")
            entries.append(Entry(var, field, ctype, capacity, low, high))
        if isinstance(obj, ODVariable):
            area.append(members[0])
        else:
            rtype = f"od_{node}_{c_ident(obj.name).lower()}_t"
            text = (
                f"/* 0x{index:04X} {obj.name} */\ntypedef struct {{\n    " + "\n    ".join(members) + f"\n}} {rtype};\n"
            )
            # a manufacturer record of plain C values is the cores' too (a current law reads its parameters
            # from it and writes its status into it: firmware_shim/core/current_law.h)
            plain = index >= 0x2000 and not any(v.data_type == datatypes.DOMAIN for v in subs)
            (field_lists if plain else record_types).append(text)
            area.append(f"{rtype} {oname};")
            if index >= 0x2000:
                field_lists.append(_field_list(macro_base, obj, oname, subs))
    extras = _enums(node, od, raw) + _bits(node, od, raw, f"{node}.eds")  # enumerations, named bits
    return od, entries, record_types, comm_fields, mfr_fields, [], defines + field_lists + extras


def _field_list(macro_base: str, obj: ODRecord | ODArray, oname: str, subs: list[ODVariable]) -> str:
    """X-macros of a manufacturer record's values, X(index, subindex, record member, field): its
    parameters (writable: _PARAMS) and its status values (read-only: _STATUS). A node app expands them
    into the tables that copy the record to and from its core's structs, whose fields carry the same
    names (the compiler refuses a name the core does not have): protocols/canopen/co_field_map.h."""
    out = []
    for suffix, writable in (("PARAMS", True), ("STATUS", False)):
        rows = [
            f"    X(0x{v.index:04X}u, 0x{v.subindex:02X}u, {oname}, {c_ident(v.name)}, {_default_of(v)})"
            for v in subs
            if v.subindex != 0
            and v.data_type not in (datatypes.DOMAIN, datatypes.VISIBLE_STRING)
            and v.writable == writable
        ]
        if rows:
            out.append(
                f"/* 0x{obj.index:04X} {obj.name}, {'parameters' if writable else 'status'}: "
                f"X(index, subindex, record, field, EDS default) */\n#define OD_{macro_base}_{suffix}(X) \\\n"
                + " \\\n".join(rows)
                + "\n"
            )
    defaults = [
        f"#define OD_{macro_base}_{c_ident(v.name).upper()}_DEFAULT {_default_of(v)}"
        for v in subs
        if v.subindex != 0 and v.data_type not in (datatypes.DOMAIN, datatypes.VISIBLE_STRING)
    ]
    return "\n" + "\n".join(out) + "\n" + "\n".join(defaults) + "\n"


def _default_of(var: ODVariable) -> str:
    if var.data_type == datatypes.REAL32:
        return _c_float(float(var.default or 0.0))
    value = int(var.default or 0)
    return (
        str(value) if var.data_type in (datatypes.INTEGER8, datatypes.INTEGER16, datatypes.INTEGER32) else f"{value}u"
    )


def _enums(node: str, od: canopen.ObjectDictionary, raw: configparser.ConfigParser) -> list[str]:
    out = []
    for obj in od.values():
        for var in [obj] if isinstance(obj, ODVariable) else obj.values():
            names = value_names(raw, var)
            if names:
                base = f"OD_{node.upper()}_{c_ident(var.name).upper()}"
                rows = ",\n".join(f"    {base}_{n.upper()} = {i}" for i, n in enumerate(names))
                out.append(f"/* 0x{var.index:04X}:{var.subindex:02X} {obj.name}.{var.name} */\nenum {{\n{rows}\n}};\n")
    return out


def _bits(node: str, od: canopen.ObjectDictionary, raw: configparser.ConfigParser, source: str) -> list[str]:
    """`#define <NODE>_<ENTRY>_<NAME> 0x<mask>u` of each named bit of a bit-field entry (key BitNames of its section:
    protocols/eds_reader.py), e.g. PLANT_STATUS_HELD 0x08u of plant.eds 0x2100:05 Measurement.status."""
    out = []
    for obj in od.values():
        for var in [obj] if isinstance(obj, ODVariable) else obj.values():
            names = eds_reader.bit_names(raw, var, source)
            if names:
                base = f"{node.upper()}_{c_ident(var.name).upper()}"
                digits = eds_reader.BIT_WIDTH[var.data_type] // 4
                rows = [f"#define {base}_{n.upper()} 0x{1 << bit:0{digits}X}u" for bit, n in enumerate(names) if n]
                head = f"/* 0x{var.index:04X}:{var.subindex:02X} {obj.name}.{var.name} bits (BitNames of {source}) */"
                out.append("\n".join([head, *rows, ""]))
    return out


def _default_literal(e: Entry) -> str | None:
    var = e.var
    raw = getattr(var, "default_raw", None)
    if var.data_type == datatypes.DOMAIN:
        return None
    if var.data_type == datatypes.VISIBLE_STRING:
        s = var.default or ""
        return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if var.data_type == datatypes.REAL32:
        v = float(var.default or 0.0)
        return _c_float(v)
    if var.relative:
        # Store the offset; co_od_reset adds the node-ID.
        value = int(re.sub(r"\+?\$NODEID\+?", "", raw.replace(" ", "").upper()), 0)
    else:
        value = int(var.default or 0)
    if var.data_type in (datatypes.INTEGER8, datatypes.INTEGER16, datatypes.INTEGER32):
        return str(value)
    return f"0x{value:X}u"


def _c_float(v: float) -> str:
    f32 = struct.unpack("<f", struct.pack("<f", v))[0]
    text = repr(f32)
    if "e" not in text and "." not in text and "inf" not in text:
        text += ".0"
    return text + "f"


LAW_ENUM = ("Controller", "controller")  # the entry whose ValueNames name the current laws
OPEN_LOOP = "open_loop"  # value 0 of that entry: the drive app's own open loop, not a law


def law_table(node: str, od: canopen.ObjectDictionary, raw: configparser.ConfigParser) -> str | None:
    """The registry of the current laws (firmware_shim/core/current_law.h): one row per value of
    Controller.controller but open_loop, bound to the descriptor `current_law_<value name>` its C file
    defines and to the record whose EDS section names it in its CurrentLaws key (its parameters and
    status), with that record's EDS defaults. Plain C: the cores link it."""
    if LAW_ENUM[0] not in od.names:
        return None
    names = value_names(raw, od[LAW_ENUM[0]][LAW_ENUM[1]])
    records: dict[str, ODRecord] = {}
    for obj in od.values():
        sec = f"{obj.index:04X}"
        if isinstance(obj, ODRecord) and raw.has_option(sec, "CurrentLaws"):
            for law in (n.strip() for n in raw.get(sec, "CurrentLaws").split(",")):
                if law not in names:
                    raise EdsError(f"[{sec}] {obj.name}: CurrentLaws names {law!r}, not a value of {LAW_ENUM}")
                records[law] = obj
    out = [
        f"/* current_law_table.c - Generated by protocols/gen_od.py from protocols/eds/{node}.eds - do not edit.",
        " * The current laws the drive can select (Controller.controller), each with its EDS record. */",
        '#include "current_law.h"',
        "",
    ]
    done: set[int] = set()
    for obj in records.values():
        if obj.index in done:
            continue
        done.add(obj.index)
        rtype = f"od_{node}_{c_ident(obj.name).lower()}_t"
        rows = [f"    .{c_ident(v.name)} = {_default_of(v)}," for v in obj.values() if v.data_type in C_TYPES]
        out.append(f"static const {rtype} x{obj.index:04X}_defaults = {{\n" + "\n".join(rows) + "\n};")
        out.append(
            f'_Static_assert(sizeof({rtype}) <= CURRENT_LAW_RECORD_BYTES, "record 0x{obj.index:04X} {obj.name} '
            f'exceeds CURRENT_LAW_RECORD_BYTES (current_law.h)");'
        )
    out.append("")
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
            rtype = f"od_{node}_{c_ident(obj.name).lower()}_t"
            out.append(
                f"    {{{value}u, &current_law_{n}, 0x{obj.index:04X}u, (uint32_t)sizeof({rtype}), "
                f"&x{obj.index:04X}_defaults}},"
            )
    out.append("};")
    out.append("const uint8_t current_law_count = (uint8_t)(sizeof current_law_table / sizeof current_law_table[0]);")
    out.append("")
    return "\n".join(out)


def _entry_row(up: str, e: Entry) -> str:
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
        lim = f"{{.f = {_c_float(float(e.low))}}}, {{.f = {_c_float(float(e.high))}}}"  # type: ignore[arg-type]
    else:
        lim = f"{{.i = {int(e.low)}}}, {{.i = {int(e.high)}}}"  # type: ignore[arg-type]
    ptr = f"OD_{up}.{e.field}" if var.data_type == datatypes.VISIBLE_STRING else f"&OD_{up}.{e.field}"
    return (
        f"    {{0x{var.index:04X}u, 0x{var.subindex:02X}u, {DT_NAMES[var.data_type]}, "
        f"{' | '.join(flags) or '0'}, {size}, {ptr}, {lim}}}, /* {var.name} */"
    )


def render(node: str, eds_dir: Path | None = None) -> dict[str, str]:
    """The generated files of a node, by file name (from EDS_DIR's EDS files, or eds_dir's: --law)."""
    od, entries, record_types, comm_fields, mfr_fields, defines, fields = load(node, eds_dir)
    eds = (eds_dir or EDS_DIR) / f"{node}.eds"
    up = node.upper()
    src_note = f"Generated by protocols/gen_od.py from protocols/eds/{node}.eds - do not edit."
    f: list[str] = [
        f"/* od_{node}_fields.h - {src_note}",
        " * Plain C, no CANopen: the cores include it for the names, defaults and enumerations",
        " * of the EDS (one source), the node app for its copy tables (co_field_map.h), the bits",
        f" * of its bit-field entries (BitNames) and the node's own EMCY codes ({up}_EMCY_*). */",
        f"#ifndef OD_{up}_FIELDS_H",
        f"#define OD_{up}_FIELDS_H",
        "",
        "#include <stdint.h>",
        "",
        *fields,
        *_emcy_defines(up, eds_reader.emcy_codes(eds_reader.parse(eds), str(eds)), f"{node}.eds"),
        f"#endif /* OD_{up}_FIELDS_H */",
        "",
    ]
    h: list[str] = [
        f"/* od_{node}.h - {src_note} */",
        f"#ifndef OD_{up}_H",
        f"#define OD_{up}_H",
        "",
        "#include <stdint.h>",
        '#include "co_od.h"',
        f'#include "od_{node}_fields.h"',
        "",
        f"#define OD_{up}_DEFAULT_NODE_ID {od.node_id or 0}u",
        "",
    ]
    h += record_types
    h.append("typedef struct {")
    h += [f"    {f}" for f in comm_fields]
    h.append(f"}} od_{node}_comm_t;\n")
    h.append("typedef struct {")
    h += [f"    {f}" for f in mfr_fields]
    h.append(f"}} od_{node}_mfr_t;\n")
    h.append("/* The communication part comes first: a communication reset restores it alone. */")
    h.append(f"typedef struct {{\n    od_{node}_comm_t comm;\n    od_{node}_mfr_t mfr;\n}} od_{node}_ram_t;\n")
    h.append(f"extern od_{node}_ram_t OD_{up};")
    h.append(f"extern const co_od_t od_{node};\n")
    h += defines
    h += ["", f"#endif /* OD_{up}_H */", ""]

    c: list[str] = [f"/* od_{node}.c - {src_note} */", f'#include "od_{node}.h"', "", f"od_{node}_ram_t OD_{up};", ""]
    c.append(f"static const od_{node}_ram_t defaults = {{")
    for e in entries:
        lit = _default_literal(e)
        if lit is not None:
            c.append(f"    .{e.field} = {lit},")
    c.append("};\n")
    c.append("static const co_od_entry_t entries[] = {")
    c += [_entry_row(up, e) for e in entries]
    c.append("};\n")
    c.append(
        f"const co_od_t od_{node} = {{entries, (uint16_t)(sizeof entries / sizeof entries[0]), &OD_{up}, "
        f"&defaults, sizeof(od_{node}_comm_t), sizeof(od_{node}_ram_t)}};"
    )
    c.append("")
    files = {f"od_{node}.h": "\n".join(h), f"od_{node}.c": "\n".join(c), f"od_{node}_fields.h": "\n".join(f)}
    table = law_table(node, od, eds_reader.parse(eds))
    if table is not None:
        files["current_law_table.c"] = table
    return files


def _emcy_defines(prefix: str, codes: tuple[EmcyCode, ...], source: str) -> list[str]:
    """`#define <PREFIX>_EMCY_<NAME> 0x<code>u` of each EMCY code of a file, its description as a comment."""
    rows = [
        f"#define {prefix}_EMCY_{c.name.upper()} 0x{c.code:04X}u" + (f" /* {c.description} */" if c.description else "")
        for c in codes
    ]
    return [f"/* EMCY error codes ([{eds_reader.EMCY_SECTION}] of {source}) */", *rows, ""] if rows else []


def render_common(eds_dir: Path | None = None) -> str:
    """eds_common.h from common.ini: the CANopen stack's own EMCY codes (CO_EMCY_*, co_emcy.h includes it) and the
    fault injector's fixed sizes (FI_*, fault_injector.h). Plain C, no include."""
    path = (eds_dir or EDS_DIR) / eds_reader.COMMON
    if not path.is_file():
        raise EdsError(f"{path}: missing (what both nodes share: the stack's EMCY codes, the fault injector's sizes)")
    raw = eds_reader.parse(path)
    sizes = eds_reader.fault_injector(raw, str(path))
    return "\n".join(
        [
            f"/* eds_common.h - Generated by protocols/gen_od.py from protocols/eds/{eds_reader.COMMON} - do not edit.",
            " * Plain C: what both nodes share, the CANopen stack's own EMCY codes (co_emcy.h) and the fault",
            " * injector's fixed sizes (fault_injector.h). */",
            "#ifndef EDS_COMMON_H",
            "#define EDS_COMMON_H",
            "",
            *_emcy_defines("CO", eds_reader.emcy_codes(raw, str(path)), eds_reader.COMMON),
            f"/* The fault injector's fixed sizes ([{eds_reader.FAULT_SECTION}] of {eds_reader.COMMON}) */",
            *(f"#define {eds_reader.fault_macro(key)} {value}u" for key, value in sizes.items()),
            "",
            "#endif /* EDS_COMMON_H */",
            "",
        ]
    )


def _law_eds(law: Path, out_eds: Path) -> None:
    """The merged EDS files of a user's law (gen_law.py) in out_eds: drive.eds with the law, plant.eds, common.ini."""
    sys.path.insert(0, str(HERE))
    try:
        import gen_law
    finally:
        sys.path.remove(str(HERE))
    _, _, text = gen_law.merge(EDS_DIR / "drive.eds", law, C_TYPES.keys())
    out_eds.mkdir(parents=True, exist_ok=True)
    (out_eds / "drive.eds").write_text(text)
    for name in ("plant.eds", eds_reader.COMMON):
        (out_eds / name).write_text((EDS_DIR / name).read_text())


def _generate(args: argparse.Namespace) -> dict[Path, str] | int:
    """Every generated file by path, or gen_od's exit status (2) after a one-line refusal."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        eds_dir, files = None, {}
        try:
            if args.law is not None:
                eds_dir = Path(tmp) / "eds"
                _law_eds(args.law, eds_dir)
                files = {args.out / "eds" / p.name: p.read_text() for p in sorted(eds_dir.iterdir())}
            out = OUT_DIR if args.out is None else args.out / "generated"
            eds_reader.emcy_table(eds_dir or EDS_DIR, NODES)  # no code or name declared twice
            for node in NODES:
                files |= {out / name: text for name, text in render(node, eds_dir).items()}
            files[out / "eds_common.h"] = render_common(eds_dir)
        except ValueError as exc:  # EdsError, gen_law.LawError
            print(f"gen_od: {exc}", file=sys.stderr)
            return 2
    return files


def main(argv: list[str] | None = None) -> int:
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
    args = ap.parse_args(argv)
    if args.law is not None and args.out is None:
        print("gen_od: --law needs --out OUTDIR (protocols/generated is the plain drive's)", file=sys.stderr)
        return 2
    files = _generate(args)
    if isinstance(files, int):
        return files
    stale = []
    for path, text in files.items():
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(str(path))
        elif not path.exists() or path.read_text() != text:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            shown = path.resolve().relative_to(HERE.parent) if path.resolve().is_relative_to(HERE.parent) else path
            print(f"gen_od: wrote {shown}")
    if stale:
        print("gen_od: stale generated files (run `python protocols/gen_od.py`): " + ", ".join(stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
