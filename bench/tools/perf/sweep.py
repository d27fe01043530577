"""`bench sweep` on 1 process vs all cores: the same 8-point grid, wall time and speed-up."""

from __future__ import annotations

import os
import time
from typing import Any

from ...paths import REPO


def sweep_scaling() -> dict[str, Any]:
    """`bench sweep` on 1 process vs all cores: the same 8-point grid, wall time and speed-up."""
    from ...sweep import run_grid

    scenario = REPO / "scenarios" / "you2019_step.toml"
    grid = [("controller.L_hat_ratio", ["0.5", "0.8", "1.0", "1.2"]), ("controller.R_hat_ratio", ["0.5", "1.5"])]
    cores = os.cpu_count() or 1
    walls = {}
    for jobs in sorted({1, cores}):
        t0 = time.monotonic()
        run_grid(scenario, grid, [], jobs, progress=False)
        walls[jobs] = time.monotonic() - t0
    return {"points": 8, "cores": cores, "wall_s": walls, "speedup": walls[1] / walls[cores]}
