"""The pytest plugin (bench/pytest_plugin/): the hil_run fixture over the direct bus, its spec-like assertions and
their messages, the failing test's report section and JUnit properties, and bad input (a missing scenario, a
bus that is not there, a law that does not build) refused by name before any run, with no traceback of the
plugin. Each session is a pytest in a subprocess that loads the plugin with -p (pyproject.toml's pytest11 entry
point, what an installed package uses, is checked on its own)."""

from __future__ import annotations

import json
import math
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
from law_util import zero_law_as

from bench.pytest_plugin.result import HilRun, load_run
from bench.pytest_plugin.runner import override_list, sanitize, table_overrides, tail
from bench.scenario.toml_text import dumps

pytest_plugins = ["pytester"]

REPO = Path(__file__).resolve().parents[2]
STEP = REPO / "scenarios" / "you2019_step.toml"
ZERO_LAW_SCENARIO = REPO / "tests" / "laws" / "zero_law.toml"
PLUGIN_FRAMES = "bench/pytest_plugin"  # a frame of the plugin in a report: a traceback inside it


def _env() -> dict[str, str]:
    """The sessions load the plugin with -p, and no plugin by entry point: whether pytest finds the package's
    entry point depends on where it looks (an installed package; a clone's egg-info in the current folder), and
    a plugin registered twice is an error. pyproject.toml's entry point is checked on its own."""
    return {**os.environ, "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"}


PLUGIN = ("-p", "bench.pytest_plugin", "-p", "no:cacheprovider")


@pytest.fixture
def hil_pytester(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> pytest.Pytester:
    """pytester for a session in a subprocess that loads the plugin by -p (_env), with an ini of its own."""
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")
    pytester.makeini("[pytest]\n")  # the rootdir: the run folders go to its hil-runs/
    return pytester


def _run(pytester: pytest.Pytester, *args: str) -> pytest.RunResult:
    return pytester.runpytest_subprocess(*PLUGIN, *args)


def _output(result: pytest.RunResult) -> str:
    return "\n".join(result.outlines + result.errlines)


# ------------------------------------------------------------------ a session over the direct bus

SESSION = f"""
STEP = {str(STEP)!r}


def test_matched_deadbeat_meets_its_spec(hil_run, hil_bus):
    run = hil_run(STEP, {{"scenario.periods": 60}})
    run.expect_status("ok").expect_status().expect_settles_within(2, signal="iq")
    run.expect_overshoot_below(1.0).expect_steady_state_error_below(0.01).expect_no_emcy()
    assert hil_bus == "direct" and run.bus == "direct" and run.exit_code == 0
    assert run["iq_A"].shape == (60,) and "iq_ref_A" in run.columns and run["period"][-1] == 59
    assert abs(run["iq_A"][-1] - 1.0) < 0.01
    step = run.step("iq")
    assert (step.at_period, step.from_A, step.to_A, step.periods_to_settle) == (20, 0.0, 1.0, 2)
    assert run.summary["bus_stats"]["lost_frames"] == 0
    assert run.bus_log.is_file() and run.recording is None  # --hil-view=failed: drawn when a test fails


def test_mismatched_inductance_overshoots(hil_run):
    hil_run(STEP, {{"scenario.periods": 60}}).expect_overshoot_below(1.0)
    run = hil_run(STEP, ["scenario.periods=60", "controller.L_hat_ratio=1.6"])
    run.expect_status("ok")
    run.expect_overshoot_below(10)


def test_a_scenario_as_a_dict(hil_run):
    scenario = {{
        "scenario": {{"name": "dict step", "periods": 40}},
        "motor": {{"preset": "you2019", "mech_mode": "locked"}},
        "drive": {{"preset": "ideal"}},
        "controller": {{"controller": "deadbeat_you2019", "Vmax_V": 139.0}},
        "events": [{{"at_period": 10, "references": {{"iq_ref_A": 1.0}}}}],
    }}
    run = hil_run(scenario)
    run.expect_status("ok").expect_settles_within(2)
    assert run.folder.name == "dict_step" and (run.folder.parent / "dict_step.toml").is_file()
    assert run.step().at_period == 10 and len(run["iq_A"]) == 40


def test_a_missing_scenario(hil_run):
    hil_run("no_such_scenario.toml")


def test_a_key_the_eds_does_not_know(hil_run):
    hil_run(STEP, {{"controller.no_such_key": 1}})
"""


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> tuple[pytest.RunResult, Path]:
    """One pytest session of SESSION, run once for the tests that read it (each of its runs is a bench run)."""
    root = tmp_path_factory.mktemp("plugin_session").resolve()
    (root / "test_spec.py").write_text(SESSION)
    (root / "pytest.ini").write_text("[pytest]\n")
    cmd = [sys.executable, "-m", "pytest", *PLUGIN, "--junitxml=junit.xml", "test_spec.py"]
    proc = subprocess.run(cmd, cwd=root, env=_env(), capture_output=True, text=True, timeout=900)
    return pytest.RunResult(proc.returncode, proc.stdout.splitlines(), proc.stderr.splitlines(), 0.0), root


def test_the_session_passes_and_fails_where_it_should(session: tuple[pytest.RunResult, Path]) -> None:
    result, root = session
    assert result.parseoutcomes() == {"passed": 2, "failed": 3}, _output(result)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    cases = ET.parse(root / "junit.xml").getroot().iter("testcase")
    failed = {c.get("name") for c in cases if c.find("failure") is not None}
    assert failed == {
        "test_mismatched_inductance_overshoots",
        "test_a_missing_scenario",
        "test_a_key_the_eds_does_not_know",
    }, _output(result)
    passed = root / "hil-runs" / "test_spec.py_test_matched_deadbeat_meets_its_spec" / "you2019_step"
    assert passed.is_dir()
    # --hil-view=failed (the default): a passing test's direct run draws no recording and no plots ...
    assert {p.name for p in passed.iterdir()} == {"bus.log", "summary.json", "traces.npy"}
    assert json.loads((passed / "summary.json").read_text())["files"]["recording"] is None
    # ... a failing test's runs have them, drawn when it failed, and its summary.json names them
    failed = root / "hil-runs" / "test_spec.py_test_mismatched_inductance_overshoots"
    for run in sorted(p.parent for p in failed.glob("*/summary.json")):
        files = json.loads((run / "summary.json").read_text())["files"]
        assert files["recording"] == "run.rrd" and (run / "run.rrd").stat().st_size > 0, files
        assert (
            sorted(files["plots"])
            == sorted(p.name for p in run.glob("*.svg"))
            == ["overview.svg", "step_00_iq_p20.svg"]
        )


def test_a_broken_bound_names_the_measured_figure_the_bound_and_the_run(
    session: tuple[pytest.RunResult, Path],
) -> None:
    result, root = session
    out = _output(result)
    folder = root / "hil-runs" / "test_spec.py_test_mismatched_inductance_overshoots"
    second = folder / "you2019_step-2"  # the test's second run of the scenario
    summary = json.loads((second / "summary.json").read_text())
    measured = summary["steps"][0]["overshoot_pct"]
    assert measured > 10
    assert f"iq step at period 20 (0.00 → 1.00 A) overshoots by {measured:.3g} %" in out, out
    assert "bound: below 10 %." in out and f"Run: {second}" in out, out
    # the report section names both runs, their bus logs and recordings, and how to view one
    assert "HIL runs (2)" in out, out
    for run in (folder / "you2019_step", second):
        assert f"run folder:  {run}" in out and f"bus log:     {run / 'bus.log'}" in out, out
        assert f"{run / 'run.rrd'}" in out, out
    assert f"rerun {second / 'run.rrd'}" in out, out
    assert f"summary:     {second / 'summary.json'}" in out and f"traces:      {second / 'traces.npy'}" in out, out
    assert "plots:       overview.svg, step_00_iq_p20.svg" in out, out
    assert PLUGIN_FRAMES not in out and "Traceback" not in out, out
    # the reproduce line runs as pasted into a plain shell (no venv activated, the bench by its absolute path),
    # each paste into a new folder beside the test's, and gives the same figure
    line = next(x for x in out.splitlines() if x.startswith("reproduce:") and str(second) in x)
    line = line.removeprefix("reproduce:").strip()
    assert Path(shlex.split(line)[0]).is_absolute(), line
    plain = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/")}
    for _ in range(2):
        res = subprocess.run(["bash", "-c", line], cwd=root, env=plain, capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, f"{line}\n{res.stdout}{res.stderr}"
    again = sorted(second.parent.glob(f"{second.name}-again-*"))
    assert len(again) == 2, again
    for folder in again:
        redone = json.loads((folder / "summary.json").read_text())
        assert redone["steps"][0]["overshoot_pct"] == measured


def test_the_key_figures_are_junit_properties(session: tuple[pytest.RunResult, Path]) -> None:
    _, root = session
    cases = {c.get("name"): c for c in ET.parse(root / "junit.xml").getroot().iter("testcase")}
    props = {name: [(p.get("name"), p.get("value")) for p in case.iter("property")] for name, case in cases.items()}
    failed = dict(props["test_mismatched_inductance_overshoots"])
    assert failed["hil_status"] == "ok" and failed["hil_exit_code"] == "0", failed
    assert failed["hil_iq_p20_settle_periods"] == "2", failed  # the matched run
    assert float(failed["hil_run2_iq_p20_overshoot_pct"]) > 10, failed  # the mismatched one
    assert Path(failed["hil_run2_run_folder"]).name == "you2019_step-2", failed
    assert math.isfinite(float(failed["hil_run2_iq_p20_ss_error_A"])), failed
    passed = dict(props["test_matched_deadbeat_meets_its_spec"])
    assert passed["hil_status"] == "ok" and Path(passed["hil_run_folder"], "summary.json").is_file(), passed
    assert not props["test_a_missing_scenario"], "no run, no figures"


def test_bad_scenarios_fail_by_name_before_any_run(session: tuple[pytest.RunResult, Path]) -> None:
    result, root = session
    out = _output(result)
    assert "hil_run: scenario file 'no_such_scenario.toml' not found" in out, out
    assert f"--set controller.no_such_key=1 (on {STEP}): unknown key 'controller.no_such_key'; allowed in" in out, out
    assert "During handling" not in out and PLUGIN_FRAMES not in out and "Traceback" not in out, out
    runs = root / "hil-runs"
    assert not list((runs / "test_spec.py_test_a_key_the_eds_does_not_know").glob("*/summary.json"))


# ------------------------------------------------------------------ session-start refusals


@pytest.mark.parametrize("bus", ["nosuchbus0", "can3"])
def test_a_bus_that_is_not_there_is_an_error_before_any_test(hil_pytester: pytest.Pytester, bus: str) -> None:
    """can3: a CAN adapter this host does not have (without kernel CAN, not the VM's emulated controller either)."""
    hil_pytester.makepyfile("def test_never_runs(hil_run):\n    raise SystemExit('ran')\n")
    result = _run(hil_pytester, "--hil-bus", bus)
    out = _output(result)
    assert result.ret == pytest.ExitCode.USAGE_ERROR, out
    assert f"ERROR: --hil-bus {bus}: " in out and "test_never_runs" not in out, out
    assert "Traceback" not in out and PLUGIN_FRAMES not in out, out


def test_hil_view_all_a_stopped_runs_drawing_and_a_bad_value(hil_pytester: pytest.Pytester) -> None:
    hil_pytester.makepyfile(
        "def test_passes(hil_run):\n    hil_run('scenarios/you2019_step.toml').expect_status('ok')\n"
    )
    result = _run(hil_pytester, "--hil-view=all")
    assert result.ret == 0, _output(result)
    run = next((hil_pytester.path / "hil-runs").glob("*/you2019_step"))
    assert (run / "run.rrd").stat().st_size > 0 and (run / "overview.svg").is_file(), sorted(run.iterdir())
    # the default: a failing test's run that stopped early (a node killed) gets its recording and plots too
    hil_pytester.makepyfile(
        "def test_fails(hil_run):\n"
        "    run = hil_run('scenarios/you2019_step.toml', {'scenario.expect': 'node_lost'},\n"
        "                  faults=[{'kind': 'kill', 'node': 'plant', 'at_period': 150}])\n"
        "    assert run.status == 'ok'\n"
    )
    result = _run(hil_pytester)
    assert result.ret == pytest.ExitCode.TESTS_FAILED, _output(result)
    run = next((hil_pytester.path / "hil-runs").glob("*test_fails/you2019_step"))
    assert json.loads((run / "summary.json").read_text())["status"] == "node_lost"
    assert (run / "run.rrd").stat().st_size > 0 and (run / "overview.svg").is_file(), sorted(run.iterdir())
    assert f"recording:   {run / 'run.rrd'}" in _output(result), _output(result)
    hil_pytester.makeini("[pytest]\nhil_view = sometimes\n")
    result = _run(hil_pytester)
    assert result.ret == pytest.ExitCode.USAGE_ERROR, _output(result)
    assert "hil_view = 'sometimes': one of failed, all" in _output(result), _output(result)


def _law(tmp_path: Path, name: str) -> Path:
    """tests/laws/zero_law as a law of another name (its own build folder: tests may run side by side)."""
    return zero_law_as(tmp_path / name, name)


def test_a_law_that_does_not_build_is_an_error_naming_the_file(hil_pytester: pytest.Pytester, tmp_path: Path) -> None:
    law = _law(tmp_path, "hil_plugin_broken_law")
    src = law / "zero_law.c"
    src.write_text(src.read_text().replace("->steps++;", "->steps++ not_c;"))
    hil_pytester.makepyfile("def test_never_runs(hil_run):\n    raise SystemExit('ran')\n")
    result = _run(hil_pytester, f"--hil-law={law}")
    out = _output(result)
    assert result.ret == pytest.ExitCode.USAGE_ERROR, out
    assert f"ERROR: --hil-law {law}: the law in {law} does not compile" in out, out
    assert f"{src}:" in out and "error:" in out and "test_never_runs" not in out, out
    assert "Traceback" not in out and PLUGIN_FRAMES not in out, out


def test_the_runs_use_the_law_of_hil_law(hil_pytester: pytest.Pytester, tmp_path: Path) -> None:
    """--hil-law builds the law and every run uses that build (the zero law commands 0 V: iq stays 0), and the
    scenario is checked against the law's own EDS (its controller name, its record's keys)."""
    law = _law(tmp_path, "hil_plugin_law")
    hil_pytester.makepyfile(
        f"""
        def test_zero_law(hil_run):
            run = hil_run({str(ZERO_LAW_SCENARIO)!r}, {{"controller.controller": "hil_plugin_law"}})
            run.expect_status("ok")
            assert abs(run["iq_A"]).max() < 1e-6 and run.step("iq").periods_to_settle is None

        def test_a_key_of_the_law_checked(hil_run):
            hil_run({str(ZERO_LAW_SCENARIO)!r}, {{"controller.controller": "hil_plugin_law", "controller.gain": -1}})
        """
    )
    result = _run(hil_pytester, f"--hil-law={law}")
    out = _output(result)
    assert result.parseoutcomes() == {"passed": 1, "failed": 1}, out
    assert "controller.gain = -1" in out and "Traceback" not in out, out


TWO_LAWS = """
import pytest

LAW_A = {law_a!r}
CVPI = {cvpi!r}
STEP = {step!r}
ZERO = {{"scenario": {{"name": "zero", "periods": 40}}, "motor": {{"preset": "you2019", "mech_mode": "locked"}},
        "controller": {{"gain": 0.25}}, "events": [{{"at_period": 10, "references": {{"iq_ref_A": 1.0}}}}]}}


def test_a_law_by_call(hil_run):
    run = hil_run(ZERO, law=LAW_A)  # the dict names no controller: law= selects it
    assert abs(run["iq_A"]).max() < 1e-6  # the zero law: 0 V, whatever the reference


@pytest.mark.hil(law=CVPI)
def test_another_law_by_marker(hil_run):
    run = hil_run(CVPI + "/../../scenarios/complex_vector_pi_step.toml", {{"scenario.periods": 420}})
    assert abs(run["iq_A"][-1] - 1.0) < 0.05  # a law that tracks the reference
    run.expect_settles_within(1)  # it settles in 9 periods: fails, and the report names the law


def test_a_built_in_law_under_hil_law(hil_run):
    hil_run(STEP, {{"scenario.periods": 60}}).expect_status("ok").expect_settles_within(2)


@pytest.mark.hil(bus="nosuchbus0")
def test_a_bus_this_host_lacks(hil_run):
    raise SystemExit("ran")


def test_a_law_folder_changed_during_the_session(hil_run):
    src = LAW_A + "/zero_law.c"
    open(src, "a").write("/* changed */\\n")
    hil_run(ZERO, law=LAW_A)
"""


def test_two_laws_in_one_session_a_marker_skip_and_the_junit_provenance(
    hil_pytester: pytest.Pytester, tmp_path: Path
) -> None:
    """Issue 39: per-call and per-marker laws next to --hil-law, each built once; a hil marker's missing bus a
    skip (a failure under --hil-require); a law folder changed mid-session refused; JUnit's properties carry the
    bus, version, scenario and law digest, and its system-out the failing test's HIL run section."""
    law_a = _law(tmp_path, "plugin_law_a")
    cvpi = tmp_path / "examples" / "laws" / "complex_vector_pi"
    shutil.copytree(REPO / "examples" / "laws", cvpi.parent)
    shutil.copytree(REPO / "examples" / "scenarios", tmp_path / "examples" / "scenarios")
    text = TWO_LAWS.format(law_a=str(law_a), cvpi=str(cvpi), step=str(STEP))
    hil_pytester.makepyfile(test_laws=text)
    result = _run(hil_pytester, f"--hil-law={law_a}", "--junitxml=junit.xml", "-o", "junit_logging=system-out", "-rs")
    out = _output(result)
    assert result.parseoutcomes() == {"passed": 2, "failed": 2, "skipped": 1}, out
    skipped = next(ln for ln in out.splitlines() if ln.startswith("SKIPPED [1]"))
    assert "hil(bus=...) nosuchbus0: " in skipped, out  # the reason: the bus, and why this host has none
    assert f"hil_run: law= {law_a}: the folder changed during this pytest session" in out, out
    assert out.count("bench: building law plugin_law_a") == 1, out  # --hil-law and law= share one build
    cases = {c.get("name"): c for c in ET.parse(hil_pytester.path / "junit.xml").getroot().iter("testcase")}
    props = {n: dict((p.get("name"), p.get("value")) for p in c.iter("property")) for n, c in cases.items()}
    from bench import __version__
    from bench.law import digest

    a = props["test_a_law_by_call"]
    assert a["hil_law"] == "plugin_law_a" and a["hil_bus"] == "direct" and a["hil_bench_version"] == __version__, a
    assert len(a["hil_law_digest"]) == 16 and a["hil_law_folder"] == str(law_a), a
    assert props["test_another_law_by_marker"]["hil_law_digest"] == digest(cvpi), props
    assert props["test_a_built_in_law_under_hil_law"]["hil_law"] == "plugin_law_a", props  # the session's build
    system_out = cases["test_another_law_by_marker"].findtext("system-out") or ""
    assert "reproduce:" in system_out and f"--law={cvpi}" in system_out and "summary.json" in system_out, system_out
    required = _run(hil_pytester, "-k", "lacks", "--hil-require")
    assert required.parseoutcomes() == {"errors": 1, "deselected": 4}, _output(required)  # failed at its setup
    assert "--hil-require: hil(bus=...) nosuchbus0: " in _output(required), _output(required)


# ------------------------------------------------------------------ a cancelled session (the box's: test_hil_cancel.py)

CANCELLED = f"""
def test_a_long_run(hil_run):
    hil_run({str(STEP)!r}, {{"scenario.periods": 5_000_000}})


def test_a_long_wait():  # without xdist never reached: the session stops after the first; with it, cancelled too
    import time

    time.sleep(600)
"""


@pytest.mark.parametrize(
    "xdist", [[], ["-n", "2", "--hil-isolate"]], ids=["one-process-run-in-process", "xdist-run-in-a-process"]
)
def test_a_sigterm_cancels_the_running_test_and_ends_the_session(tmp_path: Path, xdist: list[str]) -> None:
    """SIGTERM to pytest while a direct run runs (in the test's process, or with --hil-isolate in a `bench run` of
    its own): the run is stopped, the test skipped naming the signal, the session interrupted after it (under
    xdist: no worker reported crashed, none replaced), no traceback, no run folder left half-written."""
    (tmp_path / "test_cancel.py").write_text(CANCELLED)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    argv = [sys.executable, "-m", "pytest", *PLUGIN, "-rs", *xdist, "-p", "xdist" if xdist else "no:xdist"]
    proc = subprocess.Popen(
        [*argv, "test_cancel.py"], cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    runs = tmp_path / "hil-runs"
    try:
        deadline = time.monotonic() + 300
        while not list(runs.glob("*/*.partial")) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(1)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    said = out + err
    assert proc.returncode == pytest.ExitCode.INTERRUPTED, said
    assert "SKIPPED [1] test_cancel.py:2: cancelled by SIGTERM: the test was stopped" in out, said
    assert "Interrupted: cancelled by SIGTERM" in out, said
    assert _result_line(out) == (f"{2 if xdist else 1} skipped"), said
    assert "Traceback" not in said and "crashed" not in said and "replacing" not in said, said
    assert not _pids(f"bench.cli run .*{tmp_path}")  # hil_run stopped its run
    assert not list(runs.glob("*/*.partial")) and list(runs.glob("*/*.failed")), list(runs.rglob("*"))
    assert "hil: CAN box" not in said  # a session that used no box says nothing of it


def _result_line(out: str) -> str:
    """pytest's last line's counts: '1 skipped' of '===== 1 skipped in 4.88s ====='."""
    return out.strip().splitlines()[-1].strip("= ").split(" in ")[0]


def _pids(pattern: str) -> list[str]:
    return subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True).stdout.split()


# ------------------------------------------------------------------ the pieces, without a run


def test_the_box_line_and_which_runs_go_to_the_box() -> None:
    from bench.pytest_plugin.box import BoxLog, needs, summary_line
    from bench.pytest_plugin.runner import bench_command

    assert summary_line(BoxLog()) is None  # no box used: no line
    log = BoxLog(boots=[{"test": "t", "reason": "r", "s": 97.25, "worker": "gw1"}], runs=3, slots={2, 1})
    log.end = "stopped at the session's end (this session booted it)"
    assert summary_line(log) == (
        "hil: CAN box: booted once by this session (97.2 s, gw1); 3 runs in it, slots 1, 2; stopped at the "
        "session's end (this session booted it)"
    )
    before = BoxLog(up_before="someone", runs=1, slots={4}, end="left up: ...")
    assert summary_line(before) == "hil: CAN box: up before this session; 1 run in it, slot 4; left up: ..."
    # the box of before ended mid-session and a run of this session booted another (its token): said so
    again = BoxLog(up_before="someone", runs=2, slots={1}, end="stopped ...", ours_at_end=True)
    assert summary_line(again) == (
        "hil: CAN box: booted by a run of this session (the one up before it ended); 2 runs in it, slot 1; stopped ..."
    )
    assert needs("direct") is None and needs("can0") is None
    assert needs("vcan0", ["--drive", "mcu"]) is None and needs("vcan0", ["--drive=mcu"]) is None  # a VM of its own
    assert needs("vcan0", ["--box"]) == "asked for (--box or BENCH_BOX=1)"
    bench = bench_command()
    assert Path(bench[0]).is_absolute() and Path(bench[0]).is_file(), bench


def _fake_run(tmp_path: Path, steps: list[dict[str, Any]], **summary: Any) -> HilRun:
    body = {"status": "ok", "status_expected": True, "expect": ["ok"], "emcy": [], "steps": steps, **summary}
    body["files"] = {"log": "bus.log", "recording": "run.rrd", "traces": "traces.npy", "plots": []}
    (tmp_path / "summary.json").write_text(json.dumps(body))
    return load_run(tmp_path, 0 if body["status_expected"] else 7)


def _step(
    signal: str = "iq", at: int = 20, settle: int | None = 2, over: float = 0.0, err: float = 0.0
) -> dict[str, Any]:
    return {
        "signal": signal,
        "at_period": at,
        "from_A": 0.0,
        "to_A": 1.0,
        "periods_to_settle": settle,
        "overshoot_pct": over,
        "overshoot_A": over / 100,
        "steady_state_error_A": err,
        "window_periods": 40,
    }


def _message(fn: Any, *args: Any, **kwargs: Any) -> str:
    with pytest.raises(AssertionError) as info:
        fn(*args, **kwargs)
    return str(info.value)


def test_the_helpers_say_what_was_measured_against_which_bound(tmp_path: Path) -> None:
    run = _fake_run(tmp_path, [_step(settle=7, over=12.5, err=-0.03), _step("id", 50, settle=None)])
    m = _message(run.expect_settles_within, 3, "iq")
    assert m == f"iq step at period 20 (0.00 → 1.00 A) settles in 7 periods; bound: within 3 periods.\nRun: {tmp_path}"
    m = _message(run.expect_settles_within, 10)
    assert "id step at period 50 (0.00 → 1.00 A) never settles" in m and "iq step" not in m, m
    m = _message(run.expect_overshoot_below, 5)
    assert "iq step at period 20 (0.00 → 1.00 A) overshoots by 12.5 % (0.125 A); bound: below 5 %." in m, m
    m = _message(run.expect_steady_state_error_below, 0.01, "iq")
    assert "has a steady-state error of -0.03 A; bound: below 0.01 A in magnitude." in m, m
    run.expect_settles_within(7, "iq").expect_overshoot_below(12.6).expect_steady_state_error_below(0.031, "iq")
    m = _message(run.expect_status, "diverged", "tripped")
    assert m == f"the run's status is ok (exit status 0); expected: diverged or tripped.\nRun: {tmp_path}"


def test_no_helper_passes_on_nothing(tmp_path: Path) -> None:
    run = _fake_run(tmp_path, [])
    for check in (run.expect_settles_within, run.expect_overshoot_below, run.expect_steady_state_error_below):
        assert "no reference step to check" in _message(check, 1)
    run = _fake_run(tmp_path, [_step()])
    assert "no id step to check settling on; the run's steps: iq step at period 20" in _message(
        run.expect_settles_within, 5, "id"
    )
    with pytest.raises(LookupError, match="the run has 0 id steps"):
        run.step("id")


def test_status_emcy_and_the_scenarios_own_expectation(tmp_path: Path) -> None:
    emcy = [{"node": "drive", "code": "0x2310", "period": 31}]
    run = _fake_run(tmp_path, [_step()], status="tripped", status_expected=False, emcy=emcy)
    m = _message(run.expect_status)
    assert m.startswith("the run's status is tripped (exit status 7); expected: ok (the scenario's expect)."), m
    assert "the run saw 1 EMCY message(s): drive 0x2310 at period 31; expected: none." in _message(run.expect_no_emcy)
    expected = _fake_run(tmp_path, [_step()], status="diverged", expect=["diverged", "tripped"])
    expected.expect_status().expect_status("diverged")


def test_a_dict_scenario_is_written_as_toml_that_reads_back() -> None:
    scenario = {
        "scenario": {"name": 'a "quoted" name ü', "periods": 40, "expect": ["diverged", "tripped"]},
        "controller": {"L_hat_ratio": 0.5, "enable": True, "Vmax_V": 1e-5, "limit": math.inf},
        "trace": {"pdo3": ["Online tuning.det_A2", "Online tuning.K1_hat_V_A"]},
        "events": [{"at_period": 10, "references": {"iq_ref_A": 1.0}}, {"at_period": 20, "controller": {}}],
        "faults": [{"kind": "drop", "frame": "drive.TPDO1", "at_period": 21}],
    }
    assert tomllib.loads(dumps(scenario)) == scenario
    assert override_list({"controller.L_hat_ratio": 0.5, "controller.controller": "pi"}) == [
        "controller.L_hat_ratio=0.5",
        'controller.controller="pi"',
    ]
    assert override_list(["a.b=1"]) == ["a.b=1"] and override_list("a.b=1") == ["a.b=1"]


def test_faults_and_events_of_a_call_run_after_the_scenarios_own(tmp_path: Path) -> None:
    from bench.scenario import load

    path = tmp_path / "s.toml"
    path.write_text(STEP.read_text() + '\n[[faults]]\nkind = "drop"\nframe = "drive.TPDO1"\nat_period = 30\n')
    drop = {"kind": "drop", "frame": "drive.TPDO1", "at_period": 21}
    sets = table_overrides(path, {"faults": [drop], "events": [{"at_period": 40, "references": {"iq_ref_A": 0.5}}]})
    assert table_overrides(path, {"faults": None, "events": []}) == []
    sc = load(path, [*sets, "drive.command_timeout_us=20000"])  # the plant goes on without a dropped command
    assert [f.at_period for f in sc.faults] == [30, 21] and sc.event_periods() == [20, 40]


def test_names_and_output_tails() -> None:
    assert sanitize("tests/test_x.py::test_a[L=0.5, R=1]") == "tests_test_x.py_test_a_L_0.5_R_1"
    long = sanitize("x" * 300)
    assert len(long) == 100 and long != sanitize("x" * 301)
    assert tail("a\n  run: 1/9\r  run: 9/9 done\r\nb\n\n", 2) == "  run: 9/9 done\nb"


def test_installing_the_package_enables_the_plugin() -> None:
    entry = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["entry-points"]["pytest11"]
    assert entry == {"pmsm_hil": "bench.pytest_plugin"}


def test_the_plugin_is_cheap_to_import() -> None:
    """Every pytest session of an installed package loads it: no numpy, no bench module beyond its own face."""
    code = "import sys, bench.pytest_plugin; print(sorted(m for m in sys.modules if m.startswith(('bench', 'numpy'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    assert out.stdout.split() == ["['bench',", "'bench.pytest_plugin',", "'bench.pytest_plugin.state']"], out.stdout


# ------------------------------------------------------------------ a crash of the C library in the test's process

CRASHING = f"""
def test_a_crash(hil_run):
    hil_run({str(ZERO_LAW_SCENARIO)!r}, {{"controller.controller": "hil_crash_law"}})


def test_after_it(hil_run):
    assert hil_run({str(STEP)!r}, {{"scenario.periods": 40}}).status == "ok"
"""


def test_a_crash_in_the_test_process_is_reported_and_the_session_goes_on(
    hil_pytester: pytest.Pytester, tmp_path: Path
) -> None:
    """A law that faults (SIGSEGV once the reference steps) in a direct run in the test's process (--hil-law: the
    session's build): under xdist the worker's crash is that test's failure, named, and the next test runs; with
    --hil-isolate the run's own process crashes and the test fails with its exit status; the session goes on."""
    law = _law(tmp_path, "hil_crash_law")
    src = law / "zero_law.c"
    crash = "if (in->iq_ref_A > 0.5f) *(volatile uint32_t *)(uintptr_t)cfg->Ts_s = 1u; /* a wild write */\n    "
    src.write_text(src.read_text().replace("    (void)in;\n", "    " + crash, 1))
    hil_pytester.makepyfile(test_crash=CRASHING)
    xdist = _run(hil_pytester, f"--hil-law={law}", "-n", "2", "-p", "xdist")
    out = _output(xdist)
    assert xdist.parseoutcomes().get("failed") == 1 and xdist.parseoutcomes().get("passed") == 1, out
    assert "test_crash.py::test_a_crash" in out and "crashed while running" in out, out
    isolated = _run(hil_pytester, f"--hil-law={law}", "--hil-isolate", "-p", "no:xdist")
    out = _output(isolated)
    assert isolated.parseoutcomes() == {"failed": 1, "passed": 1}, out
    assert "exit status -11 (killed by signal 11)" in out, out
