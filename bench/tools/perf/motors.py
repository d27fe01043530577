"""`bench perf`'s motor_models section: the plant's cost per period with each machine model a user can bring
(docs/YOUR_MOTOR.md) beside the built-in linear plant's, each as the whole `bench run` a user runs (direct mode,
lockstep, every output): the linear plant, the example motor folder's flux map, the example FMU (built here by
`bench motor fmu-build`, as a user builds theirs). Rounds interleave the three, so a drift of the machine hits
them alike; the section reports each run's loop (periods/s of the run, decoding included: summary.json timing)
and whole-command wall time, and the median of the rounds. Also the helpers the realtime section's motor sides
use (example_fmu_args)."""

from __future__ import annotations

import shutil
import statistics
import tempfile
from pathlib import Path
from typing import Any

from bench.paths import REPO
from bench.tools.perf.pipeline import whole_run

SCENARIO = REPO / "scenarios" / "you2019_step.toml"
EXAMPLE_MOTOR = REPO / "examples" / "motors" / "saturating_you2019"
EXAMPLE_FMU = REPO / "examples" / "fmu" / "linear_pmsm"
PERIODS = 200_000
ROUNDS = 3


def example_fmu_args(work: Path) -> list[str]:
    """`--set motor.fmu=...` of the example FMU (built into work/), the mapping its modelDescription.xml names."""
    from bench.motor.fmu_build import build_source_fmu

    fmu = build_source_fmu(EXAMPLE_FMU, work / "linear_pmsm.fmu")
    table = (
        f'{{file = "{fmu}", inputs = {{v_alpha_V = "v_alpha", v_beta_V = "v_beta"}}, outputs = {{i_a_A = "i_a", '
        'i_b_A = "i_b", theta_m_rad = "theta_m", omega_m_rad_s = "omega_m"}}'
    )
    return ["--set", f"motor.fmu={table}"]


def _one(work: Path, name: str, extra: list[str], periods: int) -> dict[str, Any]:
    out = work / name
    r = whole_run(periods, out, tuple(extra))
    shutil.rmtree(out, ignore_errors=True)
    loop = r["loop_run_wall_s"]
    return {
        "status": r["status"],
        "wall_s": r["wall_s"],
        "loop_periods_per_s": periods / loop if loop else None,
        "loop_us_per_period": 1e6 * loop / periods if loop else None,
    }


def motor_models(periods: int = PERIODS, rounds: int = ROUNDS) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="bench-perf-motors-") as td:
        work = Path(td)
        variants = {
            "linear (built-in)": [],
            "flux map (examples/motors/saturating_you2019)": ["--motor", str(EXAMPLE_MOTOR)],
            "FMU (examples/fmu/linear_pmsm, FMI 2.0)": example_fmu_args(work),
        }
        runs: dict[str, list[dict[str, Any]]] = {k: [] for k in variants}
        for _ in range(rounds):
            for name, extra in variants.items():
                runs[name].append(_one(work, name.split(" ")[0], extra, periods))
    res: dict[str, Any] = {"periods": periods, "rounds": rounds, "scenario": str(SCENARIO.relative_to(REPO))}
    res["models"] = {
        name: {
            "runs": r,
            "median_loop_us_per_period": statistics.median(x["loop_us_per_period"] for x in r),
            "median_wall_s": statistics.median(x["wall_s"] for x in r),
        }
        for name, r in runs.items()
    }
    return res
