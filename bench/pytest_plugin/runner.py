"""What `hil_run(...)` does: find (or write) the scenario, check it in this process as `bench run` will, run
`python -m bench.cli run ...` into the test's run folder and load the result. Every refusal is a
pytest.fail(pytrace=False) naming the problem: a test that asked for a bad run fails on it, with no traceback
of the plugin."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import pytest

from bench.pytest_plugin.result import HilRun, RunFolderError, load_run
from bench.pytest_plugin.state import LawBuild
from bench.scenario.toml_text import dumps, value

TAIL_LINES = 20
MARKER = ".hil-runs"  # a test's folder the plugin made (and may empty on the test's next session)
UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")
Overrides = Mapping[str, Any] | Sequence[str] | str | None


def refuse(message: str) -> NoReturn:
    """Fail the test with `message` alone: no traceback, no exception it was raised in handling."""
    __tracebackhide__ = True
    raise pytest.fail.Exception(message, pytrace=False) from None


def sanitize(text: str, limit: int = 100) -> str:
    """A file name from a node id or a scenario name: [A-Za-z0-9_.-] only (the VM's shared folders take no
    blank, ',' or '='), at most `limit` characters (a hash of the whole keeps long ids apart)."""
    import hashlib

    name = UNSAFE.sub("_", text).strip("_.") or "run"
    if len(name) > limit:
        name = f"{name[: limit - 9]}-{hashlib.sha1(text.encode()).hexdigest()[:8]}"
    return name


def override_list(overrides: Overrides) -> list[str]:
    """`--set` items from {"controller.L_hat_ratio": 0.5} (values written as TOML) or ["k=v", ...]."""
    from bench.scenario import set_items

    try:
        return set_items(overrides)
    except TypeError as exc:
        refuse(f"hil_run: {exc}")


def table_overrides(path: Path, added: Mapping[str, Sequence[Mapping[str, Any]] | None]) -> list[str]:
    """`--set faults=[...]` (or events): the scenario's own [[faults]] and, after them, those of the call."""
    import tomllib

    wanted = {k: list(v) for k, v in added.items() if v}
    if not wanted:
        return []
    try:
        raw = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError):
        raw = {}  # check_scenario names the problem
    out = []
    for k, items in wanted.items():
        if not all(isinstance(it, Mapping) for it in items):
            refuse(f"hil_run: {k}= takes a list of tables (dicts), e.g. [{{'kind': 'drop', ...}}], not {items!r}")
        own = raw.get(k) if isinstance(raw.get(k), list) else []
        out.append(f"{k}={value([*own, *items])}")
    return out


@dataclass
class RunFolders:
    """The run folders of one test: <out>/<node id>/<scenario name>[-N]/."""

    folder: Path
    used: dict[str, int] = field(default_factory=dict)

    def next(self, name: str) -> Path:
        if not self.used:
            _fresh(self.folder)
        n = self.used[name] = self.used.get(name, 0) + 1
        return self.folder / (name if n == 1 else f"{name}-{n}")


def _fresh(folder: Path) -> None:
    """The test's folder, emptied of a former session's runs (only a folder this plugin made: its marker)."""
    if folder.exists() and (folder / MARKER).is_file():
        shutil.rmtree(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / MARKER).write_text("run folders of one test, written by bench.pytest_plugin (hil_run)\n")
    except OSError as exc:
        refuse(f"hil_run: cannot make the run folder {folder}: {exc.strerror}")


def scenario_file(scenario: Any, search: Sequence[Path], runs: RunFolders, name: str | None) -> tuple[Path, str]:
    """(the TOML file to run, the run's name): a path as given (relative: to the current folder, else to the
    test file's), or a dict written as TOML into the test's folder."""
    if isinstance(scenario, Mapping):
        head = scenario.get("scenario")
        stem = sanitize(name or (head.get("name") if isinstance(head, Mapping) else None) or "scenario")
        try:
            text = dumps(scenario)
        except TypeError as exc:
            refuse(f"hil_run: the scenario dict: {exc}")
        folder = runs.next(stem)
        path = folder.parent / f"{folder.name}.toml"
        path.write_text(text)
        return path, folder.name
    if not isinstance(scenario, str | os.PathLike):
        refuse(f"hil_run: a scenario is a TOML file's path or a dict, not {scenario!r}")
    given = Path(scenario).expanduser()
    tried = [given] if given.is_absolute() else list(dict.fromkeys(d / given for d in search))
    found = next((p for p in tried if p.is_file()), None)
    if found is None:
        where = " or ".join(str(p) for p in tried)
        refuse(f"hil_run: scenario file {str(scenario)!r} not found ({where} is not a file)")
    return found.resolve(), runs.next(sanitize(name or found.stem)).name


def check_scenario(path: Path, overrides: list[str], shown: str | None, build: Path | None = None) -> Any:
    """The scenario as `bench run` will read it (bench.scenario: every key, type and range against the EDS),
    in this process so a bad one fails the test before any run; the Scenario read. Skipped (None) when this
    process already read another build's EDS than the runs will (bench.paths imported before --hil-law set
    BENCH_BUILD_DIR): `bench run` then refuses a bad scenario itself (exit 2, its message in the failure)."""
    from bench.cli_in_process import same_build

    if not same_build(build):
        return None  # a law's build (hil_run's law=): `bench run` checks the scenario against that build's EDS
    from bench.scenario import ScenarioError, load, unselected_law

    try:
        sc = load(path, overrides)
    except ScenarioError as exc:
        refuse(f"hil_run: {exc}" if shown is None else f"hil_run: {shown}: {exc}")
    refusal = unselected_law([sc])
    if refusal is not None:
        refuse(f"hil_run: {shown or path}: {refusal}")
    return sc


def command(path: Path, folder: Path, bus: str, overrides: list[str], extra: Sequence[str]) -> list[str]:
    """`bench run` as this interpreter's module (the bench of this environment, whatever PATH holds)."""
    head = [sys.executable, "-m", "bench.cli", "run", str(path), "--bus", bus, "--no-viewer", "--out", str(folder)]
    return [*head, *(a for o in overrides for a in ("--set", o)), *extra]


def _stop(proc: subprocess.Popen[str]) -> tuple[str, str]:
    """SIGTERM (bench run stops its nodes, the VM, and exits 143: bench/stop.py), then SIGKILL after a minute."""
    proc.send_signal(signal.SIGTERM)
    try:
        return proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate()


def execute(
    cmd: list[str],
    timeout: float | None,
    env: Mapping[str, str] | None = None,
    started: Callable[[int], None] | None = None,
) -> tuple[int, str, str, bool]:
    """(exit status, stdout, stderr, whether it ran out of `timeout` seconds); the run ends with the test: a
    Ctrl-C or a cancelled session (bench/pytest_plugin/cancel.py) stops it, a second signal held off meanwhile.
    env: variables set for this run on top of this process's (a law's BENCH_BUILD_DIR); started: given the run's
    PID once it is started."""
    from bench.stop import deferred

    full = None if not env else {**os.environ, **env}
    proc = subprocess.Popen(
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        errors="replace",
        env=full,
        # its own process group: a terminal's Ctrl-C, `timeout` or a CI job's stop signal the session's group, and
        # a second signal to a run that is already stopping (the group's, then _stop's) would cut its cleanup short
        # (its box slot left unclean); the run gets the one SIGTERM of _stop
        process_group=0,
    )
    try:
        if started is not None:
            started(proc.pid)
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        out, err = _stop(proc)
        return proc.returncode, out, err, True
    except BaseException:  # Ctrl-C in pytest, a cancelled session, pytest-timeout: no bench run left behind
        with deferred():
            _stop(proc)
        raise
    return proc.returncode, out, err, False


def execute_here(cmd: list[str], later: list[Any] | None = None) -> tuple[int, str, str, bool]:
    """The run of `cmd` (a `command()`) in this process (bench/cli_in_process.py): as `execute` returns it. With a
    `later` list, its recording and plots are not drawn: what draws them is appended (bench/view/deferred.py)."""
    from bench.cli_in_process import run_here

    ran = run_here(cmd[4:], view_later=later is not None)
    if later is not None and ran.view is not None:
        later.append(ran.view)
    return ran.exit_code, ran.stdout, ran.stderr, False


def in_process(cmd: list[str], timeout: float | None, env: Mapping[str, str] | None, isolate: bool) -> bool:
    """Whether hil_run runs `cmd` in this process: a direct run of this process's build (no law= of the call),
    without a timeout (a run here cannot be stopped) and without --hil-isolate."""
    if isolate or timeout is not None or env:
        return False
    from bench.cli_in_process import runs_here

    return runs_here(cmd[4:])


def tail(text: str, lines: int = TAIL_LINES) -> str:
    """The last lines of an output (a progress line rewritten with \\r counts once, as last shown)."""
    kept = [next((p.rstrip() for p in reversed(ln.split("\r")) if p.strip()), "") for ln in text.split("\n")]
    return "\n".join([ln for ln in kept if ln][-lines:])


def exit_meaning(code: int) -> str:
    """README's "exit status" table (bench/run/verdict/summary.py, bench/stop.py)."""
    from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET
    from bench.stop import EXIT_SIGINT, EXIT_SIGPIPE, EXIT_SIGTERM

    named = {v: k for k, v in EXIT_CODES.items() if v}
    named |= {0: "ok", 1: "failure", 2: "bad input", EXIT_EXPECTATION_NOT_MET: "expected status not reached"}
    named |= {EXIT_SIGINT: "interrupted", EXIT_SIGTERM: "terminated", EXIT_SIGPIPE: "broken pipe"}
    if code < 0:
        return f"killed by signal {-code}"
    return named.get(code, "unknown")


def recorded(folder: Path) -> Path:
    """Where a run's files are: its folder, or NAME.failed[-N] where `bench run` put what a failed run recorded."""
    if folder.exists():
        return folder
    failed = sorted(folder.parent.glob(f"{folder.name}.failed*"), key=lambda p: p.stat().st_mtime)
    return failed[-1] if failed else folder


@dataclass
class Failure:
    """A run that wrote no summary: the test's failure message and what its report section shows."""

    message: str
    section: str
    exit_code: int
    folder: Path


def finish(
    cmd: list[str], folder: Path, path: Path, bus: str, result: tuple[int, str, str, bool], timeout: float | None
) -> HilRun | Failure:
    """The run's result, or why there is none (with the end of the run's output)."""
    code, out, err, timed_out = result
    try:
        return load_run(folder, code, scenario=path, bus=bus, stdout=tail(out), stderr=tail(err))
    except RunFolderError as exc:
        why = "" if not (folder / "summary.json").exists() else f" ({exc})"
    import shlex

    ended = f"did not end within {timeout:g} s and was stopped" if timed_out else "ended"
    where = recorded(folder)
    head = [
        f"bench run {path} on bus {bus} {ended} with exit status {code} ({exit_meaning(code)}) and wrote no "
        f"summary.json{why}",
        f"  run folder: {where}" + ("" if where.exists() else " (not written)"),
    ]
    if (where / "bus.log").is_file():
        head.append(f"  bus log:    {where / 'bus.log'}")
    shown = tail(err) or tail(out)
    lines = [*head, f"  command:    {shlex.join(cmd)}", "  last output:"]
    lines += [f"    {ln}" for ln in shown.splitlines() or ["(none)"]]
    return Failure("hil_run: " + "\n".join(lines), "\n".join(head), code, where)


def names_controller(path: Path, overrides: Sequence[str]) -> bool:
    """The scenario file or the overrides set controller.controller at the start."""
    import tomllib

    if any(o.partition("=")[0].strip() == "controller.controller" for o in overrides):
        return True
    try:
        raw = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError):
        return False  # `bench run` says what is wrong with the file
    table = raw.get("controller")
    return isinstance(table, Mapping) and "controller" in table


def provenance(path: Path, bus: str, law: LawBuild | None) -> list[tuple[str, str]]:
    """What a run was made of, as JUnit properties: the bus, the bench's version, the scenario file's SHA-256 (16
    hex) and the law's name and content digest (bench.law.digest) when a user's law was built."""
    import hashlib

    from bench import __version__

    props = [("bus", bus), ("bench_version", __version__)]
    props.append(("scenario_sha256", hashlib.sha256(path.read_bytes()).hexdigest()[:16]))
    if law is not None:
        props += [("law", law.name), ("law_digest", law.digest), ("law_folder", str(law.folder))]
    return props


def motor_properties(block: Any) -> list[tuple[str, str]]:
    """summary.json's "motor" block (bench.run.motor_block) as JUnit properties: motor (the folder, the
    FMU, or builtin:<preset>) and motor_digest (16 hex of its files)."""
    if not isinstance(block, Mapping):
        return []
    if "builtin" in block:
        return [("motor", f"builtin:{block['builtin']}")]
    where = block.get("folder") or block.get("fmu")
    return [("motor", str(where)), ("motor_digest", str(block.get("digest")))] if where else []


def bench_command() -> list[str]:
    """The bench of this environment as a plain shell runs it: the venv's `bench` script by its absolute path (no
    activated venv, no PATH needed), else this interpreter with `-m bench.cli` (what hil_run runs)."""
    python = Path(os.path.abspath(sys.executable))  # not resolved: a venv's python is a link out of the venv
    script = python.parent / "bench"
    try:  # pip's script of this package (it imports bench.cli), not another program of that name
        ours = os.access(script, os.X_OK) and b"bench.cli" in script.read_bytes()[:1000]
    except OSError:
        ours = False
    return [str(script)] if ours else [str(python), "-m", "bench.cli"]
