"""The EDS files, read with `canopen` (the single source of truth of the CANopen contract).

`canopen` parses integer LowLimit/HighLimit but not REAL32 ones; :func:`float_limits`
reads those from the same EDS section (protocols/gen_od.py, which stands on its own, has its own
copy of this reader; tests/host/test_eds.py checks that both agree).
"""

from __future__ import annotations

import configparser
import hashlib
import os
import pickle
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes

from bench.paths import BUILD, EDS_DIR

T = TypeVar("T")


def eds_path(node: str) -> Path:
    return EDS_DIR / f"{node}.eds"


def section_of(var: ODVariable) -> str:
    if isinstance(var.parent, (ODRecord, ODArray)):
        return f"{var.index:04X}sub{var.subindex:X}"
    return f"{var.index:04X}"


@cache
def _raw(path: str) -> configparser.ConfigParser:
    raw = configparser.ConfigParser(strict=False)
    raw.optionxform = str  # type: ignore[assignment,method-assign]
    raw.read(path)
    return raw


def default_node_id(node: str) -> int:
    """A node's default node-ID: its EDS's [DeviceComissioning] NodeID (plant 0x10, drive 0x20; the C nodes'
    OD_<NODE>_DEFAULT_NODE_ID is generated from the same key)."""
    return int(_raw(str(eds_path(node))).get("DeviceComissioning", "NodeID"), 0)


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
    raw = _raw(str(path))
    sec = section_of(var)

    def get(key: str) -> float | None:
        return float(raw.get(sec, key)) if raw.has_option(sec, key) else None

    return get("LowLimit"), get("HighLimit")


def value_names(path: Path, var: ODVariable) -> tuple[str, ...]:
    """Names of an enumerated entry's values 0, 1, ... (key ValueNames of its EDS section, also read by
    protocols/gen_od.py for the C enumerations); () for a plain number."""
    raw = _raw(str(path))
    sec = section_of(var)
    if not raw.has_option(sec, "ValueNames"):
        return ()
    return tuple(n.strip() for n in raw.get(sec, "ValueNames").split(","))


def enum(node: str, obj: str, name: str) -> dict[str, int]:
    """Value of each name of an enumerated entry, e.g. enum("drive", "Controller", "controller")."""
    return {n: i for i, n in enumerate(value_names(eds_path(node), load(node)[obj][name]))}


def _cached(what: str, node: str, build: Callable[[], T]) -> T:
    """`build()` memoized on disk, keyed by the EDS file's content and the canopen version: parsing
    an EDS costs ~0.1 s of every command's start; unpickling it a few ms."""
    path = eds_path(node)
    key = hashlib.sha256(path.read_bytes() + f"{canopen.__version__}|{what}".encode()).hexdigest()[:20]
    cache = BUILD / "eds-cache" / f"{node}-{key}.pickle"
    try:
        return pickle.loads(cache.read_bytes())  # type: ignore[no-any-return]
    except (OSError, pickle.PickleError, EOFError, AttributeError):
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
    return _cached(f"od|{node_id}", node, lambda: canopen.import_od(str(eds_path(node)), node_id=node_id))


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
