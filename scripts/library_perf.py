"""The bench as a library, measured in one sitting (docs/BENCHMARKS.md, "The bench as a library"; issue 55's table):

- a direct run in this process (bench.api.run, no files): You 2019's step at 200 periods and the 1 s scenario
  (18,182 periods), the median after the first, beside the same runs as `bench run --bus direct` processes;
- a current law in Python: the example law's twin (examples/laws/complex_vector_pi/prototype.py) over N periods
  beside its C port, in the law's build, periods/s and the cost a period adds;
- `bench --help` and `python -c "import bench.api"` as whole processes;
- a direct `hil_run` test in a pytest session (the call phase pytest times), drawing every run's recording and
  plots (`--hil-view=all`) and only a failing test's (the default).

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


LEAN = ["--no-rrd", "--no-plots"]


def processes(reps: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for label, periods, extra in (
            ("200 periods", 200, []),
            ("1 s scenario", 18_182, []),
            ("1 s scenario --no-rrd --no-plots", 18_182, LEAN),
        ):
            took = []
            for k in range(reps):
                out = Path(tmp) / f"{periods}-{len(extra)}-{k}"
                cmd = [*BENCH, "run", str(STEP), "--bus", "direct", "--no-viewer", "--out", str(out), *extra]
                try:
                    took.append(wall([*cmd, "--set", f"scenario.periods={periods}"]))
                except subprocess.CalledProcessError:
                    break  # a bench without these options (the code before)
            shown = f"{med_ms(took)} over {reps}" if took else "n/a (no such options)"
            print(f"  bench run --bus direct {label}, whole process: {shown}")
        took = [wall([*BENCH, "--help"]) for _ in range(reps)]
        print(f"  bench --help, whole process: {med_ms(took)}")
        took = [wall([sys.executable, "-c", "import bench.api"]) for _ in range(reps)]
        print(f"  python -c 'import bench.api': {med_ms(took)}")


PLUGIN_TESTS = """
import time
import pytest

@pytest.mark.parametrize("k", range({n}))
def test_step(hil_run, k):
    t0 = time.perf_counter()
    run = hil_run("scenarios/you2019_step.toml", {{"controller.L_hat_ratio": 1.0 + 0.01 * k}})
    took = time.perf_counter() - t0
    run.expect_status("ok")
    if k:  # after the session's first
        with open("took.txt", "a") as f:
            f.write(f"{{took}}\\n")
"""


def plugin_tests(n: int = 21) -> None:
    """A direct hil_run test of You 2019's step (200 periods): the hil_run call timed in the test, the median of
    `n` - 1 after the session's first, with the recording and plots of every run (--hil-view=all) and only a
    failing test's (the default), and the whole pytest session."""
    for view in ("all", "failed"):
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "test_steps.py").write_text(PLUGIN_TESTS.format(n=n))
            (Path(tmp) / "pytest.ini").write_text("[pytest]\n")
            cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
            t0 = time.perf_counter()
            res = subprocess.run([*cmd, f"--hil-view={view}"], cwd=tmp, capture_output=True, text=True)
            if res.returncode == 4:  # a bench without --hil-view (the code before): every run drew its view
                if view == "failed":
                    print("  a direct plugin test, --hil-view=failed: n/a (no such option)")
                    continue
                t0 = time.perf_counter()
                res = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True)
            session = time.perf_counter() - t0
            took = Path(tmp, "took.txt")
            calls = [float(x) for x in took.read_text().split()] if took.exists() else []
            shown = f"{med_ms(calls)} over {len(calls)}" if calls else f"n/a ({res.stdout[-300:]!r})"
            print(f"  a direct plugin test (200 periods), --hil-view={view}: {shown}; {n} tests: {session:.2f} s")


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
    plugin_tests()
    python_law(args.law_periods)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
