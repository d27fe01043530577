"""The EMCY codes the nodes send, by name: read from the EDS files that declare them (the [EmergencyCodes] of
plant.eds and drive.eds, the CANopen stack's own in protocols/eds/common.ini) through the EDS reader that
protocols/gen_od.py generates their C #defines with, so that a new code is named without a copy here."""

from __future__ import annotations

from functools import cache


@cache
def emcy_names() -> dict[int, str]:
    """EMCY code -> its name in the EDS, lower case, the name of its C #define without the prefix (co_emcy.h's
    CO_EMCY_HEARTBEAT, from common.ini's heartbeat=0x8130 -> 'heartbeat')."""
    from bench.eds import emcy_table  # here: bench.eds imports canopen

    return {c.code: c.name for codes in emcy_table().values() for c in codes}


def emcy_codes(*names: str) -> list[int]:
    """The codes of these names (lower case, without prefix), in their order; a name no EDS declares is a KeyError
    (a renamed [EmergencyCodes] key must not quietly turn a status off)."""
    by_name = {n: c for c, n in emcy_names().items()}
    missing = [n for n in names if n not in by_name]
    if missing:
        raise KeyError(
            f"EMCY {', '.join(missing)}: no such name in the EDS files' [EmergencyCodes] ({', '.join(by_name)})"
        )
    return [by_name[n] for n in names]
