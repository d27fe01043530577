"""A scenario's [trace]: drive.eds entries, by their "Object.sub-entry" names, mapped into the drive's TPDO3/TPDO4."""

from __future__ import annotations

from typing import Any

from canopen.objectdictionary import ODVariable, datatypes

from bench.eds import load as load_od


class TraceError(ValueError):
    """A [trace] table the drive cannot map (the scenario loader names it as a ScenarioError)."""


def trace_table(where: str, table: Any) -> dict[int, tuple[str, ...]]:
    """[trace] pdo3/pdo4: drive.eds entries (by "Object.sub-entry" name) mapped into TPDO3/TPDO4."""
    if not isinstance(table, dict):
        raise TraceError(f"{where}: [trace] must be a table with pdo3 / pdo4 lists")
    od = load_od("drive")
    out: dict[int, tuple[str, ...]] = {}
    for key, names in table.items():
        if key not in ("pdo3", "pdo4"):
            raise TraceError(f"{where}: unknown key trace.{key}; allowed: pdo3, pdo4")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names) or not names:
            raise TraceError(f'{where}: trace.{key} must be a non-empty list of "Object.entry" names')
        size = 0
        for name in names:
            obj, _, sub = name.partition(".")
            try:
                var = od[obj][sub] if sub else od[obj]
            except KeyError:
                raise TraceError(f"{where}: trace.{key}: {name!r} is not an entry of drive.eds") from None
            if not isinstance(var, ODVariable) or not var.pdo_mappable or not var.readable:
                raise TraceError(f"{where}: trace.{key}: {name!r} cannot be mapped into a TPDO")
            size += len(var.encode_raw(0)) if var.data_type != datatypes.REAL32 else 4
        if size > 8:
            raise TraceError(f"{where}: trace.{key} needs {size} bytes; a PDO carries at most 8")
        out[int(key[3:])] = tuple(names)
    return out
