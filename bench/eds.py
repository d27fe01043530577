"""The EDS files, read with `canopen` (the single source of truth of the CANopen contract).

What `canopen` does not read (REAL32 LowLimit/HighLimit, ValueNames, BitNames, the EMCY codes of
[EmergencyCodes], the shared protocols/eds/common.ini) is read by protocols/eds_reader.py, the one EDS reader of
the bench and of protocols/gen_od.py (which generates the C from the same files through it).
"""

from __future__ import annotations

import configparser
import functools
import hashlib
import importlib.util
import os
import pickle
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar

import canopen
from canopen.objectdictionary import ODVariable, datatypes

from bench.paths import EDS_DIR, REPO, STATE

T = TypeVar("T")


def _import_reader() -> ModuleType:
    """protocols/eds_reader.py (protocols/ is no package: gen_od.py runs as a script and imports it from its own
    folder, as the module eds_reader; the same name here, so both hold one module)."""
    if "eds_reader" in sys.modules:
        return sys.modules["eds_reader"]
    spec = importlib.util.spec_from_file_location("eds_reader", REPO / "protocols" / "eds_reader.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["eds_reader"] = module
    spec.loader.exec_module(module)
    return module


reader = _import_reader()


def eds_path(node: str) -> Path:
    return EDS_DIR / f"{node}.eds"


def common_path() -> Path:
    """protocols/eds/common.ini (or the law build's copy): what both nodes share (the stack's EMCY codes, the
    fault injector's sizes)."""
    return EDS_DIR / reader.COMMON


def section_of(var: ODVariable) -> str:
    return reader.section_of(var)  # type: ignore[no-any-return]


@cache
def raw_eds(path: str) -> configparser.ConfigParser:
    """An EDS file as INI text (the keys canopen does not read: ValueNames, BitNames, CurrentLaws ...), read once."""
    return _cached_files("raw", (Path(path),), lambda: reader.parse(path))


def default_node_id(node: str) -> int:
    """A node's default node-ID: its EDS's [DeviceComissioning] NodeID (plant 0x10, drive 0x20; the C nodes'
    OD_<NODE>_DEFAULT_NODE_ID is generated from the same key)."""
    return reader.default_node_id(raw_eds(str(eds_path(node))))  # type: ignore[no-any-return]


def add_node_id_arguments(p: Any) -> None:
    """--plant-id / --drive-id (hex or decimal) of an argparse parser, defaulting to the EDS's NodeIDs."""
    for node in ("plant", "drive"):
        nid = default_node_id(node)
        p.add_argument(
            f"--{node}-id",
            type=lambda s: int(s, 0),
            default=nid,
            help=f"{node} node-ID (default 0x{nid:02X}, {node}.eds)",
        )


def float_limits(path: Path, var: ODVariable) -> tuple[float | None, float | None]:
    """LowLimit/HighLimit of a REAL32 entry (`canopen` parses only the integer ones)."""
    return reader.float_limits(raw_eds(str(path)), var)  # type: ignore[no-any-return]


def value_names(path: Path, var: ODVariable) -> tuple[str, ...]:
    """Names of an enumerated entry's values 0, 1, ... (key ValueNames of its EDS section, also read by
    protocols/gen_od.py for the C enumerations); () for a plain number."""
    return reader.value_names(raw_eds(str(path)), var)  # type: ignore[no-any-return]


def enum(node: str, obj: str, name: str) -> dict[str, int]:
    """Value of each name of an enumerated entry, e.g. enum("drive", "Controller", "controller")."""
    return {n: i for i, n in enumerate(value_names(eds_path(node), load(node)[obj][name]))}


def bits(node: str, obj: str, name: str) -> dict[str, int]:
    """Mask of each named bit of a bit-field entry (key BitNames of its EDS section, bit 0 first; gen_od.py writes
    the same masks as the C's <NODE>_<ENTRY>_<BIT>), e.g. bits("plant", "Measurement", "status") ==
    {"trip": 0x01, "holding": 0x02, "missed": 0x04, "held": 0x08}; {} for an entry without BitNames."""
    path = eds_path(node)
    names = reader.bit_names(raw_eds(str(path)), load(node)[obj][name], str(path))
    return {n: 1 << bit for bit, n in enumerate(names) if n}


@functools.cache
def _code_key() -> bytes:
    """The code that builds what the cache keeps (this module and the EDS reader): two installs of different
    bench versions share the working folder's cache, never each other's pickles."""
    return hashlib.sha256(Path(__file__).read_bytes() + (REPO / "protocols" / "eds_reader.py").read_bytes()).digest()


def _cached(what: str, node: str, build: Callable[[], T]) -> T:
    """`build()` memoized on disk, keyed by the node's EDS file's content (`_cached_files`)."""
    return _cached_files(what, (eds_path(node),), build)


def _cached_files(what: str, paths: tuple[Path, ...], build: Callable[[], T]) -> T:
    """`build()` memoized on disk, keyed by the files' content, this code and the canopen version: parsing
    an EDS costs ~0.1 s of every command's start (a few ms an INI parse); unpickling it a few ms."""
    try:  # each file's own digest: text moved from one file to the next is another key
        content = b"".join(hashlib.sha256(path.read_bytes()).digest() for path in paths)
    except OSError:  # a missing file: build() says which, in its own words
        return build()
    versions = f"{canopen.__version__}|{sys.version_info[0]}.{sys.version_info[1]}|{what}"
    key = hashlib.sha256(content + _code_key() + versions.encode()).hexdigest()[:20]
    cache = STATE / "eds-cache" / f"{paths[0].stem}-{key}.pickle"
    try:
        return pickle.loads(cache.read_bytes())  # type: ignore[no-any-return]
    except Exception:  # noqa: BLE001 - absent, torn or from other code: built again, and written over
        pass
    value = build()
    try:
        cache.parent.mkdir(parents=True, exist_ok=True)
        tmp = cache.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(pickle.dumps(value))
        tmp.replace(cache)
    except OSError:  # a read-only checkout still works, only slower
        pass
    return value


@cache
def load(node: str, node_id: int | None = None) -> canopen.ObjectDictionary:
    return _cached(f"od|{node_id}", node, lambda: reader.import_od(eds_path(node), node_id=node_id))


@cache
def emcy_table() -> dict[str, tuple[Any, ...]]:
    """Every EMCY code the nodes send, by where the EDS declares it: "common" (common.ini: the CANopen stack's
    own), "plant", "drive" (each node's [EmergencyCodes]); each an eds_reader.EmcyCode (name, code, description).
    A code or a name declared twice is refused (EdsError)."""
    nodes = ("plant", "drive")
    files = (common_path(), *(eds_path(n) for n in nodes))
    return _cached_files("emcy", files, lambda: reader.emcy_table(EDS_DIR, nodes))


def fault_injector_size(key: str) -> int:
    """A fixed size of the fault injector from [FaultInjector] of common.ini (MaxRules: its rule table,
    FI_MAX_RULES in the C, generated from the same key)."""
    path = common_path()
    return reader.fault_injector(raw_eds(str(path)), str(path))[key]  # type: ignore[no-any-return]


@dataclass(frozen=True)
class Param:
    """One writable parameter of a node, with its range from the EDS."""

    node: str
    obj: str
    name: str
    index: int
    subindex: int
    data_type: int
    low: float | None
    high: float | None
    description: str
    names: tuple[str, ...] = ()  # of the values 0, 1, ... of an enumerated entry (EDS ValueNames)

    @property
    def is_float(self) -> bool:
        return self.data_type == datatypes.REAL32


@cache
def params(node: str, objects: tuple[str, ...]) -> dict[str, Param]:
    """Writable sub-entries of the named objects, by sub-entry name."""
    return _cached(f"params|{'|'.join(objects)}", node, lambda: _params(node, objects))


def _params(node: str, objects: tuple[str, ...]) -> dict[str, Param]:
    od = load(node)
    out: dict[str, Param] = {}
    for oname in objects:
        obj = od[oname]
        subs = [obj] if isinstance(obj, ODVariable) else [obj.subindices[s] for s in sorted(obj.subindices)]
        for var in subs:
            if not var.writable or var.subindex == 0 and not isinstance(obj, ODVariable):
                continue
            if var.name in out:  # e.g. a user law's parameter named like one of the drive's
                raise ValueError(
                    f"{eds_path(node)}: {oname}.{var.name} and {out[var.name].obj}.{var.name} are both parameters "
                    f"of one scenario section: rename one (a scenario key names one entry)"
                )
            if var.data_type == datatypes.REAL32:
                lo, hi = float_limits(eds_path(node), var)
            else:
                lo, hi = var.min, var.max
            out[var.name] = Param(
                node,
                oname,
                var.name,
                var.index,
                var.subindex,
                var.data_type,
                lo,
                hi,
                var.description or "",
                value_names(eds_path(node), var),
            )
    return out


# A plant record named "Model <name>" is the machine model <name>'s own (protocols/odgen/model.py, plant_rt/models/)
MODEL_RECORD = "Model "


def model_records() -> tuple[str, ...]:
    """The machine models' own records of plant.eds ("Model <name>"), in index order: their parameters are a
    scenario's [motor] keys beside Motor model's."""
    from canopen.objectdictionary import ODRecord

    od = load("plant")
    return tuple(
        od[i].name for i in sorted(od.indices) if isinstance(od[i], ODRecord) and od[i].name.startswith(MODEL_RECORD)
    )
