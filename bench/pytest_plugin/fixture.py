"""The callable `hil_run` gives a test: one scenario run per call, its result as a HilRun, each run named in the
failing test's report and its key figures in the JUnit properties."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest

from bench.pytest_plugin.checks import LawRefusal, bus_problem, law_build
from bench.pytest_plugin.result import HilRun, junit_properties, report_text
from bench.pytest_plugin.runner import (
    Failure,
    Overrides,
    RunFolders,
    bench_command,
    check_scenario,
    command,
    execute,
    execute_here,
    finish,
    in_process,
    motor_properties,
    names_controller,
    override_list,
    provenance,
    refuse,
    sanitize,
    scenario_file,
    table_overrides,
)
from bench.pytest_plugin.state import RUN_TEXTS, RUN_VIEWS, LaterView, LawBuild, Settings


class HilRunner:
    """hil_run(scenario, overrides=None, *, bus=None, law=None, motor=None, name=None, faults=None, events=None,
    timeout=None, extra_args=()) -> HilRun

    scenario: a TOML file's path (relative: to the current folder, else to the test file's folder) or a dict
    of the same layout (written as TOML next to its run folder). overrides: {"controller.L_hat_ratio": 0.5}
    and/or ["controller.L_hat_ratio=0.5", ...] (`bench run --set`). bus: this call's bus instead of the test's
    hil marker's or --hil-bus. law: a current-law folder for this call instead of the marker's or --hil-law
    (relative as a scenario path): built once per session (bench/law.py; a folder that changes during the
    session is refused), and selected (controller.controller = its name) unless the scenario or the overrides
    name a controller at the start, in which case the scenario must select it somewhere (`bench run --law`).
    motor: the plant's motor instead of the marker's or the scenario's: a motor folder (motor.toml and its flux
    map, relative as a scenario path: `bench run --motor DIR`), or an FMU mapping, the [motor.fmu] table as a
    dict ({"file": "x.fmu", "inputs": {...}, "outputs": {...}}; its file relative as a scenario path); the run's
    summary.json names it with a digest of its files ("motor"), and the JUnit properties hil_motor and
    hil_motor_digest. name: the run folder's name (default: the scenario file's stem, or the dict's
    scenario.name). faults, events: [[faults]] / [[events]] tables (dicts) run after the scenario's own
    (docs/FAULTS.md). timeout: seconds before the run is stopped (SIGTERM) and the test fails (the run then goes to a
    process of its own: a run in the test's process cannot be stopped). extra_args: more `bench run` options
    (["--drive", "mcu"], ["--log-format", "asc"], ...).

    A direct run without a law= and a timeout= runs in this process (bench/cli_in_process.py; --hil-isolate: never),
    the others as `bench run` processes. The run goes to <--hil-out>/<test node id>/<name>[-N]/ (-N: the name's N-th
    run in the test). A scenario that does not exist or does not check against the EDS, a bus that is not there, a
    law that does not build, a run that writes no summary.json: the test fails naming the problem. A run that ends
    with a status other than ok is a result, not a failure: assert on it (run.expect_status("ok"))."""

    def __init__(self, request: pytest.FixtureRequest, settings: Settings) -> None:
        self._settings = settings
        self._node = request.node
        from bench.root import REPO

        # last, the bench's own (scenarios/you2019_step.toml, examples/...), as bench run finds them
        self._search = [Path.cwd(), request.path.parent, request.config.rootpath, REPO]
        self._config = request.config
        self._runs = RunFolders(settings.out / sanitize(request.node.nodeid))
        marker = request.node.get_closest_marker("hil")
        self._marked: dict[str, Any] = dict(marker.kwargs) if marker is not None else {}
        self.history: list[HilRun] = []

    @property
    def bus(self) -> str:
        return str(self._marked.get("bus") or self._settings.bus)

    @property
    def folder(self) -> Path:
        """This test's folder of run folders."""
        return self._runs.folder

    def __call__(
        self,
        scenario: str | os.PathLike[str] | Mapping[str, Any],
        overrides: Overrides = None,
        *,
        bus: str | None = None,
        law: str | os.PathLike[str] | None = None,
        motor: str | os.PathLike[str] | Mapping[str, Any] | None = None,
        name: str | None = None,
        faults: Sequence[Mapping[str, Any]] | None = None,
        events: Sequence[Mapping[str, Any]] | None = None,
        timeout: float | None = None,
        extra_args: Sequence[str] = (),
    ) -> HilRun:
        __tracebackhide__ = True
        bus = bus or self.bus
        self._check_bus(bus)
        built, chosen = self._law(law)
        sets = override_list(overrides)
        path, run_name = scenario_file(scenario, self._search, self._runs, name)
        if chosen and built is not None and not names_controller(path, sets):
            sets.insert(0, f"controller.controller={built.name}")  # the law= of this call, selected at the start
        sets += table_overrides(path, {"faults": faults, "events": events})
        motor_args, motor_sets = self._motor(motor if motor is not None else self._marked.get("motor"))
        shown = "the scenario dict" if isinstance(scenario, Mapping) else None  # else the file names itself
        env = {} if not chosen or built is None else {"BENCH_BUILD_DIR": str(built.out), "BENCH_LAW": built.names}
        checked = check_scenario(path, [*sets, *motor_sets], shown, built.out if chosen and built is not None else None)
        folder = self._runs.folder / run_name
        run_sets = sets if motor_args else [*sets, *motor_sets]  # a folder as --motor DIR: its override
        cmd = command(path, folder, bus, run_sets, [*motor_args, *extra_args])
        later: list[Any] = []
        run = finish(cmd, folder, path, bus, self._execute(cmd, timeout, env, bus, extra_args, later), timeout)
        texts = self._node.stash.setdefault(RUN_TEXTS, [])
        n = len(texts) + 1
        prefix = "hil_" if n == 1 else f"hil_run{n}_"
        given = provenance(path, bus, built)
        if isinstance(run, Failure):
            texts.append(run.section)
            props = [("status", "no summary"), ("exit_code", run.exit_code), ("run_folder", run.folder), *given]
            props += motor_properties(_motor_block(checked))
            self._node.user_properties.extend((prefix + k, str(v)) for k, v in props)
            refuse(run.message)
        reproduce = self._reproduce(cmd, built, chosen)
        if later:  # drawn if the test fails (bench/pytest_plugin/__init__.py, pytest_runtest_makereport)
            views = self._node.stash.setdefault(RUN_VIEWS, [])
            views.append(LaterView(later[0], run, len(texts), reproduce))
        texts.append(report_text(run) + "\n" + reproduce)
        self._node.user_properties.extend(junit_properties(run, prefix))
        given += motor_properties(run.summary.get("motor"))
        self._node.user_properties.extend((prefix + k, str(v)) for k, v in given)
        self.history.append(run)
        return run

    def _law(self, law: str | os.PathLike[str] | None) -> tuple[LawBuild | None, bool]:
        """(the law build of this call, whether the call or the marker chose it rather than --hil-law)."""
        __tracebackhide__ = True
        given = law if law is not None else self._marked.get("law")
        if given is None:
            if self._settings.law is None:
                return None, False
            return self._build(self._settings.law, "--hil-law"), False
        return self._build(self._find(given, Path.is_dir), "hil_run: law="), True

    def _build(self, folder: Path, option: str) -> LawBuild:
        __tracebackhide__ = True
        try:
            return law_build(self._settings, folder, option)
        except LawRefusal as exc:
            refuse(str(exc))

    def _motor(self, motor: Any) -> tuple[list[str], list[str]]:
        """(`bench run` arguments, scenario overrides) of a motor= (the call's or the marker's): a folder is
        `--motor DIR` (the override motor.folder = DIR, which the scenario check reads), an FMU mapping the
        override motor.fmu = {...}, its file made absolute."""
        __tracebackhide__ = True
        if motor is None:
            return [], []
        if isinstance(motor, Mapping):
            table = dict(motor)
            if isinstance(table.get("file"), str | os.PathLike):
                table["file"] = str(self._find(table["file"], Path.is_file))
            return [], override_list({"motor.fmu": table})
        if not isinstance(motor, str | os.PathLike):
            refuse(f"hil_run: motor= takes a motor folder's path or an FMU mapping (a dict), not {motor!r}")
        folder = self._find(motor, Path.is_dir)
        if not folder.is_dir():
            where = " or ".join(str(d / motor) for d in self._search) if not Path(motor).is_absolute() else folder
            refuse(f"hil_run: motor= {str(motor)!r}: no such folder ({where}); a motor folder holds motor.toml")
        return ["--motor", str(folder)], override_list({"motor.folder": str(folder)})

    def _find(self, given: str | os.PathLike[str], kind: Any) -> Path:
        """A path as a scenario's: absolute as given, else the first of the search folders that has it."""
        p = Path(given).expanduser()
        tried = [p] if p.is_absolute() else [d / p for d in self._search]
        return Path(os.path.abspath(next((t for t in tried if kind(t)), tried[0])))

    def _execute(
        self,
        cmd: list[str],
        timeout: float | None,
        env: dict[str, str],
        bus: str,
        extra: Sequence[str],
        later: list[Any],
    ) -> tuple[int, str, str, bool]:
        """The run; one through the CAN box boots it first if none is up (box.ensure: said on the terminal), and
        is counted with the slot it took for the session's line on the box."""
        __tracebackhide__ = True
        import bench.pytest_plugin.box as box  # not `from bench.pytest_plugin`: no arrow to the face

        reason = box.needs(bus, extra)
        if reason is None and in_process(cmd, timeout, env, self._settings.isolate):
            return execute_here(cmd, later if self._settings.view == "failed" else None)
        if reason is None:
            return execute(cmd, timeout, env)
        from bench.run.bus.box.control import BoxError

        try:
            box.ensure(self._config, self._node.nodeid, reason)
        except BoxError as exc:
            refuse(f"hil_run: {exc}")
        watch = box.SlotWatch()
        try:
            return execute(cmd, timeout, env, started=watch.start)
        finally:
            box.record_run(self._config, watch.stop())

    def _reproduce(self, cmd: list[str], built: LawBuild | None, chosen: bool) -> str:
        """The run as a command line a plain shell runs (the bench by its absolute path): `bench run` with the
        test's overrides, faults and events, and its law: --law for a law of the call or the marker (selected in
        the overrides), the build itself for --hil-law's (whose runs need not select it: `bench run --law` would
        refuse them). Each paste writes a new folder beside the test's (a run refuses an existing one):
        `mktemp -d` makes it, empty, which `bench run --out` takes, unique even for two pastes in one second."""
        import shlex

        law = [f"--law={built.folder}"] if built is not None and chosen else []
        args = list(cmd[3:])
        fresh = ""
        if "--out" in args:
            at = args.index("--out")
            template = shlex.quote(f"{args[at + 1]}-again-XXXXXX")
            del args[at : at + 2]
            fresh = f' --out "$(mktemp -d {template})"'
        line = shlex.join([*bench_command(), *args, *law]) + fresh
        if built is not None and not chosen:
            line = f"BENCH_BUILD_DIR={shlex.quote(str(built.out))} {line}"
        shown = f"\nlaw:         {built.folder} ({built.name}, content {built.digest})" if built else ""
        return f"reproduce:   {line}{shown}"

    def _check_bus(self, bus: str) -> None:
        """A bus other than the session's (checked at its start) is checked at its first use."""
        __tracebackhide__ = True
        problems = self._settings.bus_problems
        if bus not in problems:
            problems[bus] = bus_problem(bus, "bus")
        if problems[bus] is not None:
            refuse(f"hil_run: {problems[bus]}")


def _motor_block(sc: Any) -> dict[str, Any] | None:
    """The motor block of a scenario this process read (a run that wrote no summary.json), or None."""
    if sc is None:
        return None
    from bench.run.motor_block import motor_block

    return motor_block(sc)
