"""The bench as a library, measured in one sitting (docs/BENCHMARKS.md, "The bench as a library"; issue 55's table):

- a direct run in this process (bench.api.run, no files): You 2019's step at 200 periods and the 1 s scenario
  (18,182 periods), the median after the first, beside the same runs as `bench run --bus direct` processes;
- a current law in Python: the example law's twin (examples/laws/complex_vector_pi/prototype.py) over N periods
  beside its C port, in the law's build, periods/s and the cost a period adds;
- `bench --help` and `python -c "import bench.api"` as whole processes.

    .venv/bin/python scripts/library_perf.py [--reps 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BENCH = [sys.executable, "-m", "bench.cli"]
STEP = REPO / "scenarios" / "you2019_step.toml"
SECOND = {"scenario.periods": 18_182}  # 1 s at Ts = 55 us
CVPI = REPO / "examples" / "laws" / "complex_vector_pi"
CVPI_STEP = REPO / "examples" / "scenarios" / "complex_vector_pi_step.toml"

LAW_RUN = """
import json, sys, time
sys.path.insert(0, {folder!r})
from bench.api import run
from prototype import ComplexVectorPI
n = {periods}
out = {{}}
for name, law in (("c", None), ("python", ComplexVectorPI()), ("c2", None), ("python2", ComplexVectorPI())):
    r = run({scenario!r}, {{"scenario.periods": n}}, py_law=law)
    out[name] = r.summary["timing"]["run_wall_s"]
print(json.dumps(out))
"""


def wall(cmd: list[str], env: dict[str, str] | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env=env)
    return time.perf_counter() - t0


def med_ms(xs: list[float]) -> str:
    return f"{1e3 * statistics.median(xs):.1f} ms (min {1e3 * min(xs):.1f})"


def in_process(reps: int) -> None:
    from bench.api import run

    run(STEP, {"scenario.periods": 200})  # the first: imports, the EDS, the C library
    for label, sets, n in (("200 periods", {"scenario.periods": 200}, 10 * reps), ("1 s scenario", SECOND, reps)):
        took = []
        for _ in range(n):
            t0 = time.perf_counter()
            run(STEP, sets)
            took.append(time.perf_counter() - t0)
        print(f"  bench.api.run {label}, in this process: {med_ms(took)} over {n}")


def processes(reps: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for label, periods in (("200 periods", 200), ("1 s scenario", 18_182)):
            took = []
            for k in range(reps):
                out = Path(tmp) / f"{periods}-{k}"
                cmd = [*BENCH, "run", str(STEP), "--bus", "direct", "--no-viewer", "--out", str(out)]
                took.append(wall([*cmd, "--set", f"scenario.periods={periods}"]))
            print(f"  bench run --bus direct {label}, whole process: {med_ms(took)} over {reps}")
        took = [wall([*BENCH, "--help"]) for _ in range(reps)]
        print(f"  bench --help, whole process: {med_ms(took)}")
        took = [wall([sys.executable, "-c", "import bench.api"]) for _ in range(reps)]
        print(f"  python -c 'import bench.api': {med_ms(took)}")


def python_law(periods: int) -> None:
    subprocess.run(
        [
            *BENCH,
            "port-check",
            str(CVPI_STEP),
            "--law",
            str(CVPI),
            "--py-law",
            f"{CVPI / 'prototype.py'}:ComplexVectorPI",
        ],
        check=True,
        capture_output=True,
    )  # the build
    builds = sorted((REPO / "build" / "laws").glob("complex_vector_pi-*"), key=lambda p: p.stat().st_mtime)
    env = {**os.environ, "BENCH_BUILD_DIR": str(builds[-1]), "BENCH_LAW": "complex_vector_pi"}
    code = LAW_RUN.format(folder=str(CVPI), periods=periods, scenario=str(CVPI_STEP))
    res = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, env=env)
    import json

    t = json.loads(res.stdout.strip().splitlines()[-1])
    c, py = min(t["c"], t["c2"]), min(t["python"], t["python2"])
    print(
        f"  the example law over {periods:,} periods (loop and decoding, best of 2): C {periods / c:,.0f} periods/s, "
        f"its Python twin {periods / py:,.0f} periods/s; the twin adds {1e6 * (py - c) / periods:.1f} us a period"
    )


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--reps", type=int, default=5, help="repetitions of each whole-process figure (default 5)")
    p.add_argument("--law-periods", type=int, default=50_000, help="periods of the Python law runs (default 50000)")
    args = p.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores, Python {sys.version.split()[0]}")
    in_process(args.reps)
    processes(args.reps)
    python_law(args.law_periods)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
