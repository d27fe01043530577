"""A scenario given as a dict, written as TOML for `bench run` (tomllib reads TOML but cannot write it, and the
bench takes no TOML writer as a dependency): the shapes a scenario has, tables of scalars, arrays and inline
tables, and arrays of tables ([[events]], [[faults]])."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from typing import Any

BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def key(k: object) -> str:
    if not isinstance(k, str):
        raise TypeError(f"a TOML key must be a string, not {k!r}")
    return k if BARE_KEY.fullmatch(k) else _string(k)


def _string(s: str) -> str:
    # JSON's escapes are TOML's (\" \\ \n \t \uXXXX ...); DEL must be escaped in TOML, not in JSON
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")


def value(v: Any) -> str:
    """A TOML value: booleans, integers, floats (inf, nan), strings, arrays, inline tables."""
    if hasattr(v, "item") and not isinstance(v, str | bytes):  # a numpy scalar
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{key(k)} = {value(x)}" for k, x in v.items()) + " }" if v else "{}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} ({type(v).__name__}) in a scenario's TOML")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list | tuple) and len(v) > 0 and all(isinstance(x, Mapping) for x in v)


def dumps(data: Mapping[str, Any]) -> str:
    """The TOML text of a scenario dict: top-level scalars, then a [table] per dict and an [[array]] entry per
    dict of a list of dicts; anything deeper as inline tables."""
    lines = [f"{key(k)} = {value(v)}" for k, v in data.items() if not (isinstance(v, Mapping) or _is_table_array(v))]
    for k, v in data.items():
        if isinstance(v, Mapping):
            lines += ["", f"[{key(k)}]", *(f"{key(kk)} = {value(vv)}" for kk, vv in v.items())]
        elif _is_table_array(v):
            for item in v:
                lines += ["", f"[[{key(k)}]]", *(f"{key(kk)} = {value(vv)}" for kk, vv in item.items())]
    return "\n".join(lines).lstrip("\n") + "\n"
