"""EDS names and values as C: identifiers (c_ident, record_type), the C type and the CO_DT_* name of each EDS data
type, and C literals of values (c_float, default_of, default_literal). No file is written here."""

from __future__ import annotations

import re
import struct

from canopen.objectdictionary import ODVariable, datatypes

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
SIGNED = (datatypes.INTEGER8, datatypes.INTEGER16, datatypes.INTEGER32)


def c_ident(name: str) -> str:
    """EDS ParameterName -> C identifier (standard names lower-cased, manufacturer names kept)."""
    s = re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_")
    if " " in name:
        s = s.lower()
    if not s or s[0].isdigit():
        s = "_" + s
    return s


def record_type(node: str, name: str) -> str:
    """The C struct type of a node's record (EDS name `name`): od_<node>_<name>_t."""
    return f"od_{node}_{c_ident(name).lower()}_t"


def c_float(v: float) -> str:
    """A float literal of the REAL32 nearest to v (the shortest text that reads back as it)."""
    f32 = struct.unpack("<f", struct.pack("<f", v))[0]
    text = repr(f32)
    if "e" not in text and "." not in text and "inf" not in text:
        text += ".0"
    return text + "f"


def default_of(var: ODVariable) -> str:
    """The EDS default of a number entry as a C literal (decimal; `u` on the unsigned ones)."""
    if var.data_type == datatypes.REAL32:
        return c_float(float(var.default or 0.0))
    value = int(var.default or 0)
    return str(value) if var.data_type in SIGNED else f"{value}u"


def default_literal(var: ODVariable) -> str | None:
    """The initialiser of an entry in a node's defaults (od_<node>.c): a string, a float, an integer (unsigned in
    hex; a node-ID relative default as its offset, co_od_reset adds the node-ID); None for a DOMAIN."""
    raw = getattr(var, "default_raw", None)
    if var.data_type == datatypes.DOMAIN:
        return None
    if var.data_type == datatypes.VISIBLE_STRING:
        s = var.default or ""
        return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if var.data_type == datatypes.REAL32:
        v = float(var.default or 0.0)
        return c_float(v)
    if var.relative:
        # Store the offset; co_od_reset adds the node-ID.
        value = int(re.sub(r"\+?\$NODEID\+?", "", raw.replace(" ", "").upper()), 0)
    else:
        value = int(var.default or 0)
    if var.data_type in SIGNED:
        return str(value)
    return f"0x{value:X}u"
