"""The EMCY codes the nodes send, by name: read from the C headers that define them (co_emcy.h, plant_app.h,
drive_app.h), so that a new code is named without a copy here."""

from __future__ import annotations

import re
from functools import cache

from bench.paths import REPO

HEADERS = ("protocols/canopen/co_emcy.h", "plant_rt/node/plant_app.h", "firmware_shim/shim/drive_app.h")


@cache
def emcy_names() -> dict[int, str]:
    """EMCY code -> its #define's name, lower case, without the prefix (co_emcy.h's CO_EMCY_HEARTBEAT ->
    'heartbeat')."""
    out: dict[int, str] = {}
    pat = re.compile(r"#define\s+(?:CO|PLANT|DRIVE)_EMCY_(\w+)\s+0x([0-9A-Fa-f]+)u")
    for h in HEADERS:
        path = REPO / h
        if path.exists():
            for name, code in pat.findall(path.read_text()):
                if name not in ("H", "MAX_ACTIVE"):
                    out.setdefault(int(code, 16), name.lower())
    return out


def emcy_codes(*names: str) -> list[int]:
    """The codes of these #define names (lower case, without prefix)."""
    return [c for c, n in emcy_names().items() if n in names]
