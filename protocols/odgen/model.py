"""A node's EDS read into what its C is made of (load): every entry with its C field, type and limits; the struct
members of the communication and manufacturer areas; the record typedefs; the index and sub-index #defines; the
field lists of the manufacturer records. The EDS is read through protocols/eds_reader.py, with its checks (each
entry's data type supported, both limits or neither)."""

from __future__ import annotations

import configparser
from dataclasses import dataclass, field
from pathlib import Path

import canopen
import eds_reader  # protocols/: gen_od.py puts its folder on sys.path
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes
from eds_reader import EdsError, float_limits, section_of

from . import EDS_DIR
from .c_types import C_TYPES, DT_NAMES, c_ident, record_type
from .fields import field_list

STRING_MIN_CAPACITY = 32


@dataclass
class Entry:
    var: ODVariable
    field: str  # C member path inside the RAM struct (e.g. "comm.x1017_producer_heartbeat_time")
    ctype: str
    capacity: int  # strings: characters without NUL
    low: float | int | None
    high: float | int | None


@dataclass
class NodeModel:
    """A node's object dictionary as the generator writes it, in index order."""

    od: canopen.ObjectDictionary
    raw: configparser.ConfigParser  # the EDS as INI (what `canopen` ignores: REAL32 limits, ValueNames, ...)
    entries: list[Entry] = field(default_factory=list)
    record_types: list[str] = field(default_factory=list)  # typedefs of the records only the node app uses
    comm_fields: list[str] = field(default_factory=list)  # members of od_<node>_comm_t (below 0x2000)
    mfr_fields: list[str] = field(default_factory=list)  # members of od_<node>_mfr_t
    defines: list[str] = field(default_factory=list)  # OD_<NODE>_<OBJECT>_IDX, OD_<NODE>_<OBJECT>_<MEMBER>_SUB
    field_lists: list[str] = field(default_factory=list)  # plain manufacturer records' typedefs and X-macros
    # a machine model's own record (plant.eds "Model <name>"): (name, record type, member, index, its field list)
    model_records: list[tuple[str, str, str, int, str]] = field(default_factory=list)


# A plant record named "Model <name>" is the machine model <name>'s own (plant_rt/models/<name>/): the plant's
# configuration carries it whole (plant_types.h, plant_model_params_t) and its node app copies and checks it.
MODEL_RECORD = "Model "


def eds_path(node: str, eds_dir: Path | None = None) -> Path:
    """A node's EDS file: EDS_DIR's, or eds_dir's (--law)."""
    return (eds_dir or EDS_DIR) / f"{node}.eds"


def load(node: str, eds_dir: Path | None = None) -> NodeModel:
    """The OD of a node: entries, record types, comm/mfr struct members, #defines and field lists."""
    eds = eds_path(node, eds_dir)
    model = NodeModel(eds_reader.import_od(eds, strict=True), eds_reader.parse(eds))
    for index in sorted(model.od.indices):
        _add_object(node, eds, model, model.od.indices[index])
    return model


def _add_object(node: str, eds: Path, model: NodeModel, obj: ODVariable | ODRecord | ODArray) -> None:
    """One object of the OD: its #defines, its entries, its member of the RAM struct (a record: its typedef, in
    the field lists when it holds plain C values, and a manufacturer record's X-macro field lists)."""
    index = obj.index
    area = model.comm_fields if index < 0x2000 else model.mfr_fields
    prefix = "comm" if index < 0x2000 else "mfr"
    oname = f"x{index:04X}_{c_ident(obj.name)}"
    macro_base = f"{node.upper()}_{c_ident(obj.name).upper()}"
    model.defines.append(f"#define OD_{macro_base}_IDX 0x{index:04X}u")
    subs = [obj] if isinstance(obj, ODVariable) else [obj.subindices[s] for s in sorted(obj.subindices)]
    members = [_add_entry(eds, model, obj, var, f"{prefix}.{oname}", macro_base) for var in subs]
    if isinstance(obj, ODVariable):
        area.append(members[0])
        return
    rtype = record_type(node, obj.name)
    text = f"/* 0x{index:04X} {obj.name} */\ntypedef struct {{\n    " + "\n    ".join(members) + f"\n}} {rtype};\n"
    # a manufacturer record of plain C values is the cores' too (a current law reads its parameters
    # from it and writes its status into it: firmware_shim/core/current_law.h)
    plain = index >= 0x2000 and not any(v.data_type == datatypes.DOMAIN for v in subs)
    (model.field_lists if plain else model.record_types).append(text)
    area.append(f"{rtype} {oname};")
    if index >= 0x2000:
        model.field_lists.append(field_list(macro_base, obj, oname, subs))
    if plain and obj.name.startswith(MODEL_RECORD):
        name = c_ident(obj.name[len(MODEL_RECORD) :]).lower()
        model.model_records.append((name, rtype, oname, index, f"OD_{macro_base}_PARAMS"))


def _add_entry(
    eds: Path, model: NodeModel, obj: ODVariable | ODRecord | ODArray, var: ODVariable, path: str, macro_base: str
) -> str:
    """One entry (a variable, or a record's member at `path`): its Entry, its _SUB #define; its C declaration."""
    if var.data_type not in DT_NAMES:
        raise EdsError(f"{eds} [{section_of(var)}] {var.name}: data type 0x{var.data_type:X} not supported")
    sec = section_of(var)
    if isinstance(obj, ODVariable):
        c_field, member_name = path, path.partition(".")[2]
    else:
        member_name = c_ident(var.name)
        c_field = f"{path}.{member_name}"
        model.defines.append(f"#define OD_{macro_base}_{member_name.upper()}_SUB 0x{var.subindex:02X}u")
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
    if var.data_type == datatypes.REAL32:
        low, high = float_limits(model.raw, var)
    else:
        low, high = var.min, var.max
    if (low is None) != (high is None):
        raise EdsError(f"{eds} [{sec}] {var.name}: give both LowLimit and HighLimit or neither")
    model.entries.append(Entry(var, c_field, ctype, capacity, low, high))
    return decl
