"""The callable `hil_run` gives a test: one scenario run per call, its result as a HilRun, each run named in the
failing test's report and its key figures in the JUnit properties."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest

from bench.pytest_plugin.checks import bus_problem
from bench.pytest_plugin.result import HilRun, junit_properties, report_text
from bench.pytest_plugin.runner import (
    Failure,
    Overrides,
    RunFolders,
    check_scenario,
    command,
    execute,
    finish,
    override_list,
    refuse,
    sanitize,
    scenario_file,
    table_overrides,
)
from bench.pytest_plugin.state import RUN_TEXTS, Settings


class HilRunner:
    """hil_run(scenario, overrides=None, *, bus=None, name=None, faults=None, events=None, timeout=None,
    extra_args=()) -> HilRun

    scenario: a TOML file's path (relative: to the current folder, else to the test file's folder) or a dict
    of the same layout (written as TOML next to its run folder). overrides: {"controller.L_hat_ratio": 0.5}
    and/or ["controller.L_hat_ratio=0.5", ...] (`bench run --set`). bus: this call's bus instead of --hil-bus.
    name: the run folder's name (default: the scenario file's stem, or the dict's scenario.name). faults,
    events: [[faults]] / [[events]] tables (dicts) run after the scenario's own (docs/FAULTS.md). timeout:
    seconds before the run is stopped (SIGTERM) and the test fails. extra_args: more `bench run` options
    (["--drive", "mcu"], ["--log-format", "asc"], ...).

    The run goes to <--hil-out>/<test node id>/<name>[-N]/ (-N: the name's N-th run in the test). A scenario
    that does not exist or does not check against the EDS, a bus that is not there, a run that writes no
    summary.json: the test fails naming the problem. A run that ends with a status other than ok is a result,
    not a failure: assert on it (run.expect_status("ok"))."""

    def __init__(self, request: pytest.FixtureRequest, settings: Settings) -> None:
        self._settings = settings
        self._node = request.node
        from bench.root import REPO

        # last, the bench's own (scenarios/you2019_step.toml, examples/...), as bench run finds them
        self._search = [Path.cwd(), request.path.parent, request.config.rootpath, REPO]
        self._runs = RunFolders(settings.out / sanitize(request.node.nodeid))
        self.history: list[HilRun] = []

    @property
    def bus(self) -> str:
        return self._settings.bus

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
        name: str | None = None,
        faults: Sequence[Mapping[str, Any]] | None = None,
        events: Sequence[Mapping[str, Any]] | None = None,
        timeout: float | None = None,
        extra_args: Sequence[str] = (),
    ) -> HilRun:
        __tracebackhide__ = True
        bus = bus or self._settings.bus
        self._check_bus(bus)
        sets = override_list(overrides)
        path, run_name = scenario_file(scenario, self._search, self._runs, name)
        sets += table_overrides(path, {"faults": faults, "events": events})
        shown = "the scenario dict" if isinstance(scenario, Mapping) else None  # else the file names itself
        check_scenario(path, sets, shown)
        folder = self._runs.folder / run_name
        cmd = command(path, folder, bus, sets, list(extra_args))
        run = finish(cmd, folder, path, bus, execute(cmd, timeout), timeout)
        texts = self._node.stash.setdefault(RUN_TEXTS, [])
        n = len(texts) + 1
        prefix = "hil_" if n == 1 else f"hil_run{n}_"
        if isinstance(run, Failure):
            texts.append(run.section)
            props = [("status", "no summary"), ("exit_code", run.exit_code), ("run_folder", run.folder)]
            self._node.user_properties.extend((prefix + k, str(v)) for k, v in props)
            refuse(run.message)
        texts.append(report_text(run) + "\n" + self._reproduce(cmd))
        self._node.user_properties.extend(junit_properties(run, prefix))
        if self._settings.law is not None:
            self._node.user_properties.append((prefix + "law", str(self._settings.law)))
        self.history.append(run)
        return run

    def _reproduce(self, cmd: list[str]) -> str:
        """The run as a command line: `bench run` with the test's overrides, faults and events (and its law)."""
        import shlex

        law = [] if self._settings.law is None else [f"--law={self._settings.law}"]
        args = list(cmd[3:])
        if "--out" in args:  # the test's own run folder exists (a run refuses it): a new one beside it
            at = args.index("--out") + 1
            args[at] = args[at] + "-again"
        line = shlex.join(["bench", *args, *law])
        return f"reproduce:   {line}" + (f"\nlaw:         {self._settings.law}" if law else "")

    def _check_bus(self, bus: str) -> None:
        """A bus other than the session's (checked at its start) is checked at its first use."""
        __tracebackhide__ = True
        problems = self._settings.bus_problems
        if bus not in problems:
            problems[bus] = bus_problem(bus, "bus")
        if problems[bus] is not None:
            refuse(f"hil_run: {problems[bus]}")
