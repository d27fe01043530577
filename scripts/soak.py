"""The soak: the vcan tests that compare against direct or assert on EMCYs, in a loop, with both cores kept busy,
counting false verdicts (issue 52; docs/CI.md "The soak").

    make soak                                   # the defaults: 4 busy loops, 3 plugin sessions of 40 + 40 tests
    .venv/bin/python scripts/soak.py --rounds 5 --busy 2 --tests 30
    .venv/bin/python scripts/soak.py --suite 3  # also the project's CAN phase, 3 times in a row

Two kinds of round, each under the same load (busy loops `sh -c 'while :; do :; done'` started here and killed
by their PIDs at the end, also on Ctrl-C or SIGTERM):

- plugin: a user's project (written into the soak's folder) through the pytest plugin in one `pytest -n 2`
  session, the path where two runs share the CAN box at once: per index a test over vcan0 with the example law
  (`@pytest.mark.hil(bus="vcan0", law=...)`, `expect_status("ok").expect_no_emcy()`) and its direct twin, the
  same test in direct mode. A false verdict: the vcan test's outcome differs from its twin's (a vcan failure
  whose twin passed, or the reverse).
- suite (--suite N): the project's CAN phase (tests/can, not kernel_can) N times in a row; a false verdict is
  any failing test (each compares against direct or against its own bound).

Prints one line per round and a table at the end; writes soak.json (every failure with its first message line,
grouped by cause) into the soak's folder, build/soak/<time>/. Exit 0 when no false verdict, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # run as a script: the bench's own modules (the CAN box's state, the busy loops)
from bench.tools.busy import busy_loops  # noqa: E402 (after the path it is found on)

PY = REPO / ".venv" / "bin" / "python"
BENCH = REPO / ".venv" / "bin" / "bench"

PROJECT_TEST = '''"""Written by scripts/soak.py: per index, a run of the example law over vcan0 and its direct twin."""
from pathlib import Path

import pytest

SCENARIO = Path({scenario!r})
LAW = Path({law!r})


@pytest.mark.parametrize("i", range({n}))
@pytest.mark.hil(bus="vcan0", law=LAW)
def test_vcan(hil_run, i):
    hil_run(SCENARIO).expect_status("ok").expect_no_emcy()


@pytest.mark.parametrize("i", range({n}))
@pytest.mark.hil(bus="direct", law=LAW)
def test_direct(hil_run, i):
    hil_run(SCENARIO).expect_status("ok").expect_no_emcy()
'''


def outcomes(junit: Path) -> dict[str, tuple[bool, str]]:
    """test name -> (passed, the first line of its failure message) from a JUnit XML file."""
    out: dict[str, tuple[bool, str]] = {}
    if not junit.exists():
        return out
    for case in ET.parse(junit).getroot().iter("testcase"):
        name = f"{case.get('classname', '')}::{case.get('name', '')}"
        bad = next(iter([*case.iter("failure"), *case.iter("error")]), None)
        skipped = next(iter(case.iter("skipped")), None)
        if skipped is not None:
            out[name] = (False, f"skipped: {skipped.get('message', '')}")
        elif bad is not None:
            out[name] = (False, (bad.get("message") or bad.text or "").strip().splitlines()[0][:300])
        else:
            out[name] = (True, "")
    return out


def plugin_round(folder: Path, n: int, k: int) -> dict[str, Any]:
    """One `pytest -n 2` session of the soak project: its runs and false verdicts."""
    junit = folder / f"plugin-{k}.xml"
    cmd = [str(PY), "-m", "pytest", "-n", "2", "-p", "no:cacheprovider", "-q", f"--junitxml={junit}"]
    cmd += ["--hil-require", f"--hil-out={folder / f'runs-{k}'}", str(folder / "project")]
    t0 = time.monotonic()
    out = _session(cmd, folder / "project")
    (folder / f"plugin-{k}.out").write_text(out)
    got = outcomes(junit)
    false: list[dict[str, Any]] = []
    for i in range(n):
        v = next((o for name, o in got.items() if name.endswith(f"test_vcan[{i}]")), (False, "no result"))
        d = next((o for name, o in got.items() if name.endswith(f"test_direct[{i}]")), (False, "no result"))
        if v[0] != d[0] or "no result" in (v[1], d[1]):  # a session that ran nothing is no pass
            false.append({"index": i, "vcan": v, "direct": d, "cause": (v[1] or d[1])})
    return {"kind": "plugin", "vcan_runs": n, "runs": 2 * n, "false": false, "wall_s": time.monotonic() - t0}


def suite_round(folder: Path, k: int, extra: list[str]) -> dict[str, Any]:
    """The project's CAN phase (tests/can, not kernel_can) once: any failing test is a false verdict."""
    junit = folder / f"suite-{k}.xml"
    cmd = [str(PY), "-m", "pytest", str(REPO / "tests" / "can"), "-m", "not kernel_can", "-p", "no:cacheprovider"]
    cmd += ["-q", f"--junitxml={junit}", *extra]
    t0 = time.monotonic()
    out = _session(cmd, REPO)
    (folder / f"suite-{k}.out").write_text(out)
    got = outcomes(junit)
    false = [{"test": name, "cause": o[1]} for name, o in got.items() if not o[0]]
    if not got:
        false.append({"test": "(the session)", "cause": "no result (see its .out)"})
    return {"kind": "suite", "tests": len(got), "runs": len(got), "false": false, "wall_s": time.monotonic() - t0}


def _session(cmd: list[str], cwd: Path) -> str:
    """A pytest session, its output; on SIGTERM or Ctrl-C here it is sent SIGTERM (the plugin then cancels its runs
    and stops what it started) and given 120 s before it is killed."""
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        out, _ = proc.communicate()
        return out
    except BaseException:
        proc.terminate()
        try:
            proc.wait(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
        raise


def write_project(folder: Path, n: int) -> None:
    project = folder / "project"
    project.mkdir(parents=True)
    scenario = REPO / "examples" / "ci_project" / "scenarios" / "law_step.toml"
    law = REPO / "examples" / "laws" / "complex_vector_pi"
    (project / "test_soak.py").write_text(PROJECT_TEST.format(scenario=str(scenario), law=str(law), n=n))
    (project / "pytest.ini").write_text("[pytest]\n")  # the project's own rootdir (not the repository's)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog="docs/CI.md: The soak")
    ap.add_argument("--rounds", type=int, default=3, help="plugin sessions (default 3)")
    ap.add_argument("--tests", type=int, default=40, help="vcan tests per session, each with its direct twin (40)")
    ap.add_argument("--busy", type=int, default=2 * (os.cpu_count() or 1), help="busy loops (default 2 per CPU)")
    ap.add_argument("--suite", type=int, default=0, help="then the project's CAN phase this many times (0)")
    ap.add_argument("--out", type=Path, default=None, help="the soak's folder (default build/soak/<time>)")
    a = ap.parse_args(argv)
    for name, v, lo in (
        ("--rounds", a.rounds, 0),
        ("--tests", a.tests, 1),
        ("--busy", a.busy, 0),
        ("--suite", a.suite, 0),
    ):
        if v < lo:
            ap.error(f"{name} {v}: must be at least {lo}")
    if not PY.exists():
        ap.error(f"{PY} is missing: run `make setup` first")
    folder = a.out or REPO / "build" / "soak" / time.strftime("%Y%m%d-%H%M%S")
    if folder.exists():
        ap.error(f"--out {folder} exists: the soak writes a new folder")
    write_project(folder, a.tests)
    print(
        f"soak: {a.rounds} plugin session(s) of {a.tests} vcan tests and their direct twins, then {a.suite} CAN "
        f"phase(s), under {a.busy} busy loop(s); in {folder}",
        flush=True,
    )
    from bench.run.bus.box import life

    booted = not life.is_ready()  # a box that was up (another session's) is left up at the end
    subprocess.run([str(BENCH), "box", "up"], check=False)  # booted once, before the load: not counted in a round
    rounds: list[dict[str, Any]] = []
    try:
        with busy_loops(a.busy, sigterm_exits=True) as pids:
            print(f"soak: busy loops {pids}", flush=True)
            for k in range(a.rounds):
                rounds.append(plugin_round(folder, a.tests, k))
                _say(rounds[-1], k)
            for k in range(a.suite):
                rounds.append(suite_round(folder, k, []))
                _say(rounds[-1], k)
    finally:
        if booted:
            subprocess.run([str(BENCH), "box", "down"], check=False, capture_output=True)
        report = _report(rounds, a.busy)
        (folder / "soak.json").write_text(json.dumps(report, indent=1))
        print(_table(report), flush=True)
    return 0 if report["false_verdicts"] == 0 else 1


def _say(r: dict[str, Any], k: int) -> None:
    print(
        f"soak: {r['kind']} round {k + 1}: {r['runs']} tests, {len(r['false'])} false verdict(s), {r['wall_s']:.0f} s",
        flush=True,
    )


def _report(rounds: list[dict[str, Any]], busy: int) -> dict[str, Any]:
    causes = Counter(f["cause"] for r in rounds for f in r["false"])
    return {
        "busy_loops": busy,
        "cpus": os.cpu_count(),
        "rounds": rounds,
        "vcan_runs_plugin": sum(r.get("vcan_runs", 0) for r in rounds),
        "tests": sum(r["runs"] for r in rounds),
        "false_verdicts": sum(len(r["false"]) for r in rounds),
        "by_cause": dict(causes.most_common()),
    }


def _table(rep: dict[str, Any]) -> str:
    lines = [
        f"soak: {rep['tests']} tests ({rep['vcan_runs_plugin']} plugin vcan runs with a direct twin), "
        f"{rep['busy_loops']} busy loops on {rep['cpus']} CPUs: {rep['false_verdicts']} false verdict(s)"
    ]
    lines += [f"  {n} x {cause}" for cause, n in rep["by_cause"].items()]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
