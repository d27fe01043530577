"""The peer on the same 1 s scenario, timed in the same run as the bench: gym-electric-motor 3.0
(shared/peers/bench_gem.py: You 2019 motor, Ts = 55 us, standstill, iq step 0 -> 1 A at 1 ms,
18,182 periods), whole process, in its own Python 3.12 venv (.peers-venv, made by scripts/peers.sh
when missing). When the venv cannot be made (no Python 3.12, PyPI unreachable) the result says
so ("unavailable") and the rest of the perf run goes on."""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.paths import REPO
from bench.tools.perf.common import measure, stats

PEERS_VENV = REPO / ".peers-venv"
PEERS_SH = REPO / "scripts" / "peers.sh"


def peers_dir() -> Path:
    """shared/peers beside the repository (BENCH_PEERS_DIR overrides)."""
    env = os.environ.get("BENCH_PEERS_DIR")
    return Path(env) if env else REPO.parent / "shared" / "peers"


def ensure_venv(say: Callable[[str], None]) -> tuple[Path | None, str | None]:
    """(the venv's python, None) or (None, why it is unavailable)."""
    py = PEERS_VENV / "bin" / "python"
    probe = [str(py), "-c", "import gym_electric_motor"]
    if py.exists() and subprocess.run(probe, capture_output=True, timeout=120).returncode == 0:
        return py, None
    say(
        f"peers: {PEERS_VENV.name} is missing or incomplete: installing it with {PEERS_SH.relative_to(REPO)} "
        "(Python 3.12, gym-electric-motor, motulator; a few minutes)"
    )
    r = subprocess.run(
        ["bash", str(PEERS_SH)],
        capture_output=True,
        text=True,
        timeout=1800,
        env={**os.environ, "PEERS_VENV": str(PEERS_VENV)},
    )
    if r.returncode != 0 or not py.exists():
        tail = " ".join((r.stderr or r.stdout).strip().splitlines()[-3:])
        return None, f"scripts/peers.sh failed (status {r.returncode}): {tail}"
    return py, None


def gem(reps: int = 3, say: Callable[[str], None] | None = None) -> dict[str, Any]:
    say = say or (lambda msg: None)
    script = peers_dir() / "bench_gem.py"
    if not script.exists():
        return {"unavailable": f"{script} not found (set BENCH_PEERS_DIR)"}
    py, why = ensure_venv(say)
    if py is None:
        return {"unavailable": why}
    argv = [str(py), str(script), "--speed", "standstill", "--solver", "dopri5"]
    runs = []
    for _ in range(max(1, reps)):
        m = measure(argv, timeout=600, cwd=script.parent).check("bench_gem.py")
        out = json.loads(m.stdout.strip().splitlines()[-1])
        runs.append((m, out))
    walls = [m.wall_s for m, _ in runs]
    sim = [o["periods_per_s"] for _, o in runs]
    last = runs[-1][1]
    periods = int(last["n_periods"])
    return {
        "simulator": last.get("simulator"),
        "solver": last.get("solver"),
        "speed": last.get("speed"),
        "periods": periods,
        "repetitions": len(runs),
        "wall_s": stats(walls),
        "peak_rss_kB": max(m.peak_rss_kB for m, _ in runs),
        "sim_wall_s": stats([o["sim_wall_s"] for _, o in runs]),
        "setup_s": stats([o["setup_s"] for _, o in runs]),
        "sim_periods_per_s": stats(sim)["median"],
        "periods_per_s_whole_process": periods / stats(walls)["median"],
        "iq_final_A": last.get("iq_final"),
        "command": f".peers-venv/bin/python {script} --speed standstill --solver dopri5",
    }
