"""The bench as a Python library: a scenario run from Python, its result a HilRun (bench.result), the object the
pytest plugin's hil_run returns.

    from bench.api import run
    r = run("scenarios/you2019_step.toml", {"scenario.periods": 200})
    r.status, r.step("iq").periods_to_settle, r["iq_A"][-1]
    r.expect_status("ok").expect_settles_within(2, signal="iq")

scenario: a TOML file's path (relative: to the current folder, else the bench's own, as `bench run` finds it), a dict
of the same layout (its relative paths, motor.folder and motor.fmu.file, to the current folder), or a
bench.scenario.Scenario; overrides: {"controller.L_hat_ratio": 0.5} and/or ["controller.L_hat_ratio=0.5"] (`--set`).

In this process (`in_process`): a run on a bus that runs in process (the direct bus, libhil's loop) with this
process's build. The bench's modules, the EDS and the C library load once per process. Without `out=` nothing is
written: the traces are in memory (HilRun.traces: the rows traces.npy would hold; HilRun.folder is None). With
`out=DIR` the run writes what `bench run --out DIR` writes (its own handler, bench/run/command.py; its output is
captured in HilRun.stdout/stderr). Either way: the verdicts and numbers of `bench run --bus direct`, bit for bit
(tests/host/test_api.py).

In a process of its own: a run on a bus (vcan0, can0: its nodes, candump and the CAN box are processes anyway), or
with `law=` (a law folder: another build, and bench.paths is fixed at this process's first import), runs as
`bench run` and is read back from its folder (`out=`, else a temporary folder, removed once read).

A scenario or override the bench refuses raises ScenarioError (a ValueError naming the field and what it takes);
another refusal before the run (an `out=` that holds files, a bus that is not there) raises RunRefused; a run that
broke down without a verdict raises RunFailed. A run whose status is not ok is a result: assert on it.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from bench.result import HilRun, Step, load_run
from bench.scenario import (
    Scenario,
    ScenarioError,
    from_dict,
    load,
    set_items,
    unselected_law,
    unselected_python_law,
)

__all__ = ["HilRun", "RunFailed", "RunRefused", "ScenarioError", "in_process", "port_check", "run"]

ScenarioLike = str | os.PathLike[str] | Mapping[str, Any] | Scenario
Overrides = Mapping[str, Any] | Sequence[str] | str | None
DICT = "the scenario dict"  # how a dict scenario is named in errors


class RunRefused(ValueError):
    """The bench refused the run before it began (nothing was written): what `bench run` said, with the fix."""


class RunFailed(RuntimeError):
    """The run broke down without a verdict (`bench run`'s exit status 1): what it said, and where what was recorded
    went."""


def in_process(bus: str = "direct", law: str | os.PathLike[str] | None = None) -> bool:
    """Whether run(..., bus=bus, law=law) runs in this process (else as a `bench run` process)."""
    from bench.cli_in_process import same_build
    from bench.run.bus.buses import choose_bus

    return law is None and choose_bus(bus).in_process and same_build()


def run(
    scenario: ScenarioLike,
    overrides: Overrides = None,
    *,
    bus: str = "direct",
    law: str | os.PathLike[str] | None = None,
    py_law: Any = None,
    out: str | os.PathLike[str] | None = None,
) -> HilRun:
    """Run `scenario` (with `overrides`) on `bus` and return its HilRun; `out`: the folder its files go to (new or
    empty), none written without it for a run in process; `law`: a current-law folder (`bench run --law`);
    `py_law`: a current law prototyped in Python (an object, or "FILE.py:Class": `bench run --py-law`)."""
    try:
        sets = set_items(overrides)
    except TypeError as exc:
        raise ScenarioError(str(exc)) from None
    folder = None if out is None else Path(out).expanduser().resolve()
    if not in_process(bus, law):
        return _in_a_process(scenario, sets, bus, law, _py_law_spec(py_law), folder)
    sc = _scenario(scenario, sets)
    path = Path(sc.source) if Path(sc.source).is_file() else None
    python_law = _py_law(py_law)
    if python_law is not None and (unselected := unselected_python_law(sc, python_law.law)) is not None:
        raise ScenarioError(unselected)
    if folder is None:
        return _in_memory(sc, path, python_law)
    return _to_folder(sc, path, folder, python_law)


def _py_law(py_law: Any) -> Any:
    """The Python law object of a run in this process (a "FILE.py:Class" loaded), checked; None: none."""
    if py_law is None:
        return None
    from bench.law_py import LawError, checked

    try:
        return checked(None, py_law) if isinstance(py_law, str) else checked(py_law, None)
    except LawError as exc:
        raise ScenarioError(str(exc)) from None


def _py_law_spec(py_law: Any) -> str | None:
    """`--py-law`'s FILE.py:Class of a run in a process of its own: as given, or where the object's class is
    defined (a class typed into a notebook has no file: its run needs this process, no law= and the direct bus)."""
    if py_law is None or isinstance(py_law, str):
        return py_law
    import inspect

    cls = type(py_law)
    if cls.__module__ == "__main__":  # its process would run the caller's script again, which runs this run ...
        raise ScenarioError(
            f"py_law: {cls.__qualname__} is defined in the script that runs: a `bench run` process (law= or a bus) "
            "loads it from a module of its own; move the class to a file and give it as 'FILE.py:Class' (or an "
            "object imported from there), or run it in this process (bus='direct', no law=)"
        )
    try:
        source = inspect.getsourcefile(cls)
    except (TypeError, OSError):
        source = None
    if source is None or "<" in cls.__qualname__:
        raise ScenarioError(
            f"py_law: {cls.__qualname__} has no file a `bench run` process could load it from; give it as "
            "'FILE.py:Class', or run it in this process (bus='direct', no law=)"
        )
    return f"{source}:{cls.__qualname__}"


def _scenario(scenario: ScenarioLike, sets: list[str]) -> Scenario:
    """The scenario as the run takes it, its overrides applied; a law it names that no build has is refused."""
    if isinstance(scenario, Scenario):
        sc = from_dict(scenario.raw, scenario.source, sets) if sets else scenario
    elif isinstance(scenario, Mapping):
        sc = from_dict(_plain(scenario), DICT, sets)
    elif isinstance(scenario, str | os.PathLike):
        sc = load(Path(scenario).expanduser(), sets)
    else:
        raise TypeError(f"run: scenario is a TOML file's path, a dict or a Scenario, not {type(scenario).__name__}")
    if (unselected := unselected_law([sc])) is not None:
        raise ScenarioError(unselected)
    return sc


def _plain(table: Mapping[str, Any]) -> dict[str, Any]:
    """A dict scenario as tomllib would give it: its tables and arrays of tables plain dicts and lists, a copy."""
    return json.loads(json.dumps(table, default=_json_value))


def _json_value(o: Any) -> Any:
    if hasattr(o, "item"):  # a numpy scalar
        return o.item()
    if isinstance(o, Mapping):
        return dict(o)
    if isinstance(o, tuple | list):
        return list(o)
    raise TypeError(f"a scenario value must be a number, a string, a boolean, a list or a table, not {o!r}")


def _in_memory(sc: Scenario, path: Path | None, py_law: Any = None) -> HilRun:
    """The run in this process, nothing written: `bench run --bus direct`'s run, its traces kept as rows."""
    from bench.canbus import LinkError
    from bench.run import RunOptions, TraceRows, run_scenario
    from bench.run.motor_block import motor_block
    from bench.run.outputs import json_default

    motor = motor_block(sc)  # the files as the scenario's load read them (as bench run's summary.json)
    rows = TraceRows()
    try:
        res = run_scenario(sc, RunOptions(bus="direct", py_law=py_law), sinks=[rows], envelopes=False)
    except LinkError as exc:
        raise RunRefused(str(exc)) from exc
    except Exception as exc:
        from bench.run.loop.configure import SettingRefused

        if isinstance(exc, SettingRefused):
            raise RunRefused(str(exc)) from exc
        raise RunFailed(f"{sc.name}: {exc}") from exc
    res.summary["motor"] = motor
    summary = json.loads(json.dumps(res.summary, default=json_default))  # as summary.json holds it
    return HilRun(
        folder=None,
        exit_code=res.exit_code,
        summary=summary,
        status=res.status,
        steps=[Step.from_summary(s) for s in summary.get("steps") or []],
        bus_log=None,
        recording=None,
        scenario=path,
        bus="direct",
        rows=rows.rows,
    )


def _to_folder(sc: Scenario, path: Path | None, folder: Path, py_law: Any = None) -> HilRun:
    """The run in this process as `bench run --out FOLDER` makes it (its parser's defaults, its handler), no viewer."""
    from bench.cli_in_process import parse_run
    from bench.run.command import execute

    args = parse_run([str(path or DICT), "--bus", "direct", "--out", str(folder), "--no-viewer"])
    assert not isinstance(args, int), "bench run's own arguments parse"
    args.in_caller = True  # a Ctrl-C while the results are written is the caller's (bench/run/command.py)
    args.py_law_obj = py_law
    said_out, said_err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(said_out), contextlib.redirect_stderr(said_err):
        code, _result, written = execute(args, sc)
    return _read_back(code, written, path, "direct", said_out.getvalue(), said_err.getvalue(), keep=True)


def _in_a_process(
    scenario: ScenarioLike,
    sets: list[str],
    bus: str,
    law: str | os.PathLike[str] | None,
    py_law: str | None,
    folder: Path | None,
) -> HilRun:
    """`bench run` in a process of its own, read back from its folder (a temporary one without `out=`)."""
    with tempfile.TemporaryDirectory(prefix="bench-api-") as tmp:
        path = _scenario_file(scenario, Path(tmp))
        out = folder if folder is not None else Path(tmp) / "run"
        cmd = [sys.executable, "-m", "bench.cli", "run", str(path), "--bus", bus, "--out", str(out), "--no-viewer"]
        cmd += [f"--set={s}" for s in sets]
        if law is not None:
            cmd += ["--law", str(Path(law).expanduser().resolve())]
        if py_law is not None:
            cmd += ["--py-law", py_law]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        shown = path if not isinstance(scenario, Mapping) else None
        return _read_back(proc.returncode, out, shown, bus, proc.stdout, proc.stderr, keep=folder is not None)


def _scenario_file(scenario: ScenarioLike, tmp: Path) -> Path:
    """The scenario as a file `bench run` reads: its own file, or the tables of a dict or of a Scenario (its
    overrides applied) written as TOML, their relative paths made absolute as this process reads them (to the
    scenario file's folder, a dict's to the current folder)."""
    if isinstance(scenario, str | os.PathLike):
        return Path(scenario).expanduser().resolve() if Path(scenario).expanduser().exists() else Path(scenario)
    from bench.scenario.toml_text import dumps

    table = _plain(scenario.raw if isinstance(scenario, Scenario) else scenario)
    source = Path(scenario.source) if isinstance(scenario, Scenario) else None
    base = source.parent if source is not None and source.is_file() else Path.cwd()
    motor = table.get("motor")
    if isinstance(motor, dict):
        if isinstance(motor.get("folder"), str):
            motor["folder"] = os.path.abspath(base / Path(motor["folder"]).expanduser())
        fmu = motor.get("fmu")
        if isinstance(fmu, dict) and isinstance(fmu.get("file"), str):
            fmu["file"] = os.path.abspath(base / Path(fmu["file"]).expanduser())
    path = tmp / "scenario.toml"
    path.write_text(dumps(table))
    return path


def _read_back(
    code: int, folder: Path | None, scenario: Path | None, bus: str, stdout: str, stderr: str, keep: bool
) -> HilRun:
    """A `bench run`'s result as a HilRun: its folder's (or, `keep` False, in memory: the folder is temporary)."""
    said = stderr.strip().splitlines()
    last = said[-1] if said else f"exit status {code}"
    if code == 2:
        raise RunRefused(last.removeprefix("bench run: "))
    if code == 130:
        raise KeyboardInterrupt(last)
    if folder is None or not (folder / "summary.json").is_file():
        raise RunFailed(last.removeprefix("bench run: "))
    run = load_run(folder, code, scenario=scenario, bus=bus, stdout=stdout, stderr=stderr)
    if keep:
        return run
    rows = run.traces if run.traces_file is not None and run.traces_file.is_file() else None
    summary = {k: v for k, v in run.summary.items() if k != "files"}
    return HilRun(None, code, summary, run.status, run.steps, None, None, scenario, bus, stdout, stderr, rows)


def port_check(
    scenario: str | os.PathLike[str],
    py_law: Any,
    overrides: Overrides = None,
    *,
    law: str | os.PathLike[str] | None = None,
    tolerance: float = 0.0,
) -> Any:
    """`bench port-check` from Python (a test's helper): the scenario with the Python prototype `py_law` (an object or
    "FILE.py:Class") and with its C port (a registered law of this build, or the law folder `law`), compared; a
    bench.port_check.PortReport (`agree`, `signals`, `text()`, `expect_agree()`). In this process without `law`,
    else as a `bench port-check` process."""
    from bench.port_check import PortReport
    from bench.port_check import port_check as check

    try:
        sets = set_items(overrides)
    except TypeError as exc:
        raise ScenarioError(str(exc)) from None
    if py_law is None:
        raise ScenarioError("port_check: py_law is the prototype: an object of its class or 'FILE.py:Class'")
    if not tolerance >= 0:
        raise ScenarioError(f"port_check: tolerance = {tolerance}: must be >= 0 (0: bit for bit)")
    if in_process("direct", law):
        sc = _scenario(scenario, sets)
        python_law = _py_law(py_law)
        if (unselected := unselected_python_law(sc, python_law.law)) is not None:
            raise ScenarioError(unselected)
        return check(sc, python_law, tolerance)
    spec = str(_py_law_spec(py_law))
    with tempfile.TemporaryDirectory(prefix="bench-port-check-") as tmp:
        report = Path(tmp) / "report.json"
        cmd = [sys.executable, "-m", "bench.cli", "port-check", str(_scenario_file(scenario, Path(tmp)))]
        cmd += ["--py-law", spec, "--tolerance", repr(tolerance)]
        cmd += ["--law", str(Path(law).expanduser().resolve())] if law is not None else []
        cmd += [*(f"--set={s}" for s in sets), "--json", str(report)]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode not in (0, 1) or not report.is_file():
            said = proc.stderr.strip().splitlines()
            last = said[-1] if said else f"exit status {proc.returncode}"
            raise RunRefused(last.removeprefix("bench port-check: "))
        return PortReport.from_json(json.loads(report.read_text()))
