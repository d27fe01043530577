"""CANopen frame handling in-process (build/bin/co_perf): ns per frame of the stack's paths."""

from __future__ import annotations

import re
from typing import Any

from bench.paths import binary
from bench.tools.perf.common import run

CO_PERF_FRAMES = 1_000_000


def canopen_cost(frames: int = CO_PERF_FRAMES) -> dict[str, Any]:
    out = run([str(binary("co_perf")), str(frames)])
    res: dict[str, Any] = {"frames_each": frames}
    for m in re.finditer(r"^co_perf: (\w+)_ns ([\d.]+)", out, re.M):
        res[f"{m[1]}_ns"] = float(m[2])
    if len(res) < 2:
        raise RuntimeError(f"unexpected co_perf output: {out!r}")
    return res
