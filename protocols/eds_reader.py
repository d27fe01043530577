"""The one reader of the EDS files: protocols/gen_od.py (build time, the C) and bench/eds.py (run time) both read
them through this module.

`canopen` reads the objects (:func:`import_od`). What it ignores is read here from the same files as INI text
(:func:`parse`): the LowLimit/HighLimit of a REAL32 entry, the ValueNames of an enumerated entry, the BitNames
of a bit-field entry, a node's manufacturer EMCY codes (its [EmergencyCodes] section) and the shared file
protocols/eds/common.ini (what both nodes share and neither node's EDS holds: the CANopen stack's own EMCY codes,
the fault injector's table size).

A bit-field entry (an UNSIGNED8/16/32 whose bits are flags, e.g. plant.eds 0x2100:05 Measurement.status) names its
bits in its section as an enumerated entry names its values: ``BitNames=trip,holding,missed,held`` names bit 0, 1,
2, 3 (ValueNames=a,b names the values 0, 1); an empty name leaves a bit unnamed (``BitNames=a,,c``). Each name is a
lower-case C identifier. gen_od.py writes ``#define <NODE>_<ENTRY>_<NAME> 0x<mask>u`` (PLANT_STATUS_HELD 0x08u) into
od_<node>_fields.h; the bench reads the masks with bench.eds.bits.

An [EmergencyCodes] section (not a CiA 306 section: EDS readers skip it) holds one line per code,
``<name>=<code> [description]``: a lower-case C identifier, four hex digits, a few words. gen_od.py writes it as
``#define <PREFIX>_EMCY_<NAME> 0x<code>u`` (PLANT_/DRIVE_ in od_<node>_fields.h, CO_ in eds_common.h); the
bench names the code <name> (bench/emcy.py).

Standard library and `canopen` only, nothing of the bench: gen_od.py runs it wherever firmware is built.
"""

from __future__ import annotations

import configparser
import logging
import re
from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes

COMMON = "common.ini"  # beside the EDS files: what both nodes share (see the module's docstring)
EMCY_SECTION = "EmergencyCodes"
FAULT_SECTION = "FaultInjector"  # in common.ini: the injector's fixed sizes (protocols/faults/fault_injector.h)
C_NAME = re.compile(r"[a-z][a-z0-9_]*\Z")  # a lower-case C identifier: an EMCY code's name, a bit's name
EMCY_VALUE = re.compile(r"0x([0-9A-Fa-f]{4})(?:\s+(.*))?\Z")
FAULT_KEY = re.compile(r"[A-Z][A-Za-z0-9]*\Z")


class EdsError(ValueError):
    """An EDS file (or common.ini) the generator and the bench refuse: the message names the file and the section."""


class EmcyCode(NamedTuple):
    name: str  # lower case, without prefix: 'meas_lost'
    code: int
    description: str


def parse(path: Path | str) -> configparser.ConfigParser:
    """The file as INI text, keys with their case (what `canopen` does not read). A section or a key given twice
    is refused, as `canopen` refuses it in an EDS file."""
    return parse_text(Path(path).read_text(), str(path))


def parse_text(text: str, what: str) -> configparser.ConfigParser:
    """`parse` of a text (`what` names it in a refusal: a law's fragment before it is merged)."""
    raw = configparser.ConfigParser(strict=True, interpolation=None)
    raw.optionxform = str  # type: ignore[assignment,method-assign]
    try:
        raw.read_string(text, source=what)
    except configparser.Error as exc:
        raise EdsError(f"{what}: {str(exc).splitlines()[0]}") from None
    return raw


def section_of(var: ODVariable) -> str:
    """The EDS section of an entry: '2200sub1' for a sub-entry, '1017' for a variable."""
    if isinstance(var.parent, (ODRecord, ODArray)):
        return f"{var.index:04X}sub{var.subindex:X}"
    return f"{var.index:04X}"


def float_limits(raw: configparser.ConfigParser, var: ODVariable) -> tuple[float | None, float | None]:
    """LowLimit/HighLimit of a REAL32 entry, which `canopen` does not parse."""
    sec = section_of(var)

    def get(key: str) -> float | None:
        return float(raw.get(sec, key)) if raw.has_option(sec, key) else None

    return get("LowLimit"), get("HighLimit")


def value_names(raw: configparser.ConfigParser, var: ODVariable) -> tuple[str, ...]:
    """The names of an enumerated entry's values 0, 1, ... (key ValueNames of its section: the C enumerations,
    the scenario files' names); () for a plain number."""
    sec = section_of(var)
    if not raw.has_option(sec, "ValueNames"):
        return ()
    return tuple(n.strip() for n in raw.get(sec, "ValueNames").split(","))


BIT_WIDTH = {datatypes.UNSIGNED8: 8, datatypes.UNSIGNED16: 16, datatypes.UNSIGNED32: 32}


def bit_names(raw: configparser.ConfigParser, var: ODVariable, where: str = "") -> tuple[str, ...]:
    """The names of a bit-field entry's bits 0, 1, ... (key BitNames of its section: the C #defines of the masks,
    the bench's names), "" for a bit left unnamed; () for an entry without the key. Refused (`where` names the file):
    a name that is no lower-case C identifier or is given twice, more names than the entry has bits, an entry that is
    not UNSIGNED8/16/32 or that has ValueNames too."""
    sec = section_of(var)
    if not raw.has_option(sec, "BitNames"):
        return ()
    names = tuple(n.strip() for n in raw.get(sec, "BitNames").split(","))
    named = [n for n in names if n]
    what = f"{where} [{sec}] {var.name}: BitNames={raw.get(sec, 'BitNames')}"
    if var.data_type not in BIT_WIDTH or raw.has_option(sec, "ValueNames"):
        raise EdsError(f"{what}: only an UNSIGNED8/16/32 entry without ValueNames has named bits")
    if not named or not all(C_NAME.match(n) for n in named) or len(set(named)) != len(named):
        raise EdsError(f"{what}: want distinct lower-case C identifiers, bit 0 first (an empty name: a bit unnamed)")
    if len(names) > BIT_WIDTH[var.data_type]:
        raise EdsError(f"{what}: {len(names)} bits, the entry has {BIT_WIDTH[var.data_type]}")
    return names


def default_node_id(raw: configparser.ConfigParser) -> int:
    """[DeviceComissioning] NodeID (the C nodes' OD_<NODE>_DEFAULT_NODE_ID comes from the same key)."""
    return int(raw.get("DeviceComissioning", "NodeID"), 0)


class Collect(logging.Handler):
    """The warnings `canopen` logs while it reads a file (a strict reader takes each for a refusal)."""

    def __init__(self) -> None:
        super().__init__(level=logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def import_od(path: Path | str, node_id: int | None = None, *, strict: bool = False) -> canopen.ObjectDictionary:
    """The object dictionary read by `canopen`; strict: a warning of `canopen` is an EdsError (the generator's)."""
    if not strict:
        return canopen.import_od(str(path), node_id=node_id)
    handler = Collect()
    logging.getLogger("canopen").addHandler(handler)
    try:
        od = canopen.import_od(str(path), node_id=node_id)
    finally:
        logging.getLogger("canopen").removeHandler(handler)
    if handler.messages:
        raise EdsError(f"{path}: canopen warned: {handler.messages}")
    return od


def emcy_codes(raw: configparser.ConfigParser, where: str) -> tuple[EmcyCode, ...]:
    """The [EmergencyCodes] of a file (`where` names it in a refusal), in the file's order; () without the
    section. A code given twice (a name given twice: :func:`parse`), a name that is no lower-case C identifier or a
    code that is not four hex digits is refused."""
    if not raw.has_section(EMCY_SECTION):
        return ()
    out: list[EmcyCode] = []
    for name, value in raw.items(EMCY_SECTION):
        m = EMCY_VALUE.match(value.strip())
        if not C_NAME.match(name) or m is None:
            raise EdsError(
                f"{where} [{EMCY_SECTION}] {name}={value}: want <name>=0x<four hex digits> [description], "
                "the name a lower-case C identifier"
            )
        code = EmcyCode(name, int(m.group(1), 16), (m.group(2) or "").strip())
        if "*/" in code.description:
            raise EdsError(f"{where} [{EMCY_SECTION}] {name}: '*/' in the description (it becomes a C comment)")
        if any(c.code == code.code for c in out):
            raise EdsError(f"{where} [{EMCY_SECTION}] {name}: code 0x{code.code:04X} named twice")
        out.append(code)
    return tuple(out)


def emcy_table(eds_dir: Path, nodes: Iterable[str]) -> dict[str, tuple[EmcyCode, ...]]:
    """Every EMCY code the nodes send, by where it is declared: "common" (common.ini: the CANopen stack's own,
    sent by every node), then each node (the [EmergencyCodes] of its EDS). A code or a name declared in two
    places is refused: the bench names a code by its name alone, and a name by its code."""
    files = {"common": eds_dir / COMMON, **{node: eds_dir / f"{node}.eds" for node in nodes}}
    out: dict[str, tuple[EmcyCode, ...]] = {}
    seen: dict[str | int, str] = {}
    for source, path in files.items():
        if not path.is_file():
            raise EdsError(f"{path}: missing")
        out[source] = emcy_codes(parse(path), str(path))
        for c in out[source]:
            for key in (c.name, c.code):
                if key in seen and seen[key] != source:
                    what = f"code 0x{key:04X}" if isinstance(key, int) else f"name {key}"
                    raise EdsError(f"{path} [{EMCY_SECTION}] {c.name}: {what} is declared in {files[seen[key]]} too")
                seen[key] = source
    return out


def fault_injector(raw: configparser.ConfigParser, where: str) -> dict[str, int]:
    """common.ini's [FaultInjector]: the injector's fixed sizes by key (MaxRules: its rule table, FI_MAX_RULES),
    each a positive integer."""
    out: dict[str, int] = {}
    for key, value in raw.items(FAULT_SECTION) if raw.has_section(FAULT_SECTION) else ():
        try:
            number = int(value, 0)
        except ValueError:
            number = 0
        if not FAULT_KEY.match(key) or number <= 0:
            raise EdsError(f"{where} [{FAULT_SECTION}] {key}={value}: want a CamelCase key = a positive integer")
        out[key] = number
    return out


def fault_macro(key: str) -> str:
    """The C macro of a [FaultInjector] key: MaxRules -> FI_MAX_RULES."""
    return "FI_" + re.sub(r"(?<!^)(?=[A-Z])", "_", key).upper()
