"""The CLI run as a user runs it (subprocess)."""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import re
import shlex
import subprocess
import sys
from typing import Any

import pytest
from bench_cli import bench_cli

from bench.canbus import probe_af_can
from bench.paths import REPO


def test_help_lists_commands() -> None:
    """`bench --help` lists every command of the table (bench/commands.py) with its help line, in the table's order,
    and the parser knows exactly the table's commands."""
    from bench.cli import build_parser
    from bench.commands import COMMANDS

    out = bench_cli("--help", env={"COLUMNS": "200"}).stdout
    listed = [c for c in COMMANDS if c.help is not None]
    places = [m.start() if (m := re.search(rf"\n    {c.name}\s", out)) else -1 for c in listed]
    assert -1 not in places and places == sorted(places), out
    for c in listed:
        assert " ".join(c.help.split()[:4]) in " ".join(out.split()), (c.name, out)
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    assert list(sub.choices) == [c.name for c in COMMANDS]  # type: ignore[attr-defined]


def test_help_imports_no_command() -> None:
    """`bench --help` is the rows' help lines: no command's module is imported, nor numpy or canopen."""
    code = (
        "import sys\nfrom bench.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in sys.modules if m in ('numpy', 'canopen') or m.startswith('bench.run')))"
    )
    res = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert "COMMAND" in res.stdout and res.stdout.splitlines()[-1] == "[]", res.stdout


def test_a_command_parsed_alone_is_the_command_of_the_whole_parser() -> None:
    """`bench CMD` builds CMD's arguments only (bench/commands.py): its parser is the one of the whole table."""
    from bench.cli import build_parser
    from bench.commands import COMMANDS

    def sub(full: list[str] | None) -> dict[str, argparse.ArgumentParser]:
        act = next(a for a in build_parser(full)._actions if isinstance(a, argparse._SubParsersAction))
        return dict(act.choices)

    whole = sub(None)
    for c in COMMANDS:
        alone = sub([c.name])
        assert alone[c.name].format_help() == whole[c.name].format_help(), c.name
        assert [a.dest for a in alone[c.name]._actions] == [a.dest for a in whole[c.name]._actions], c.name
        others = [n for n in alone if n != c.name]
        assert all(len(alone[n]._actions) == 1 for n in others)  # -h only: not built


def test_the_extras_a_command_needs_come_from_its_row(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every extra missing: a command whose row needs extras is refused naming its first (before --law builds),
    the others are not; --serve and the CiA 402 master's figure add [view] to run, replay and demo."""
    from bench import cli, extras
    from bench.commands import COMMANDS, find

    monkeypatch.setattr(extras, "lacking", lambda extra: f"{extra}_module")
    for c in COMMANDS:
        refusal = cli._lacking(c, None)
        if c.needs:
            assert refusal is not None and f"bench {c.name} needs the package's [{c.needs[0]}] extra" in refusal
        else:
            assert refusal is None, c.name
    parse = cli.build_parser().parse_args
    step = str(REPO / "scenarios" / "you2019_step.toml")
    for argv in (["run", step, "--serve"], ["run", step, "--drive-profile", "cia402"], ["replay", "x.log", "--serve"]):
        assert "[view] extra" in (cli._lacking(find(argv[0]), parse(argv)) or ""), argv
    assert cli._lacking(find("demo"), parse(["demo", "--serve"])) is not None
    for argv in (["run", step], ["replay", "x.log"], ["demo"]):
        assert cli._lacking(find(argv[0]), parse(argv)) is None, argv


def test_the_commands_that_take_law_are_the_rows_that_say_so() -> None:
    """bench/law.py's own list of the commands take_law reads --law from, and the table's rows with law=True."""
    from bench.commands import COMMANDS
    from bench.law import COMMANDS as LAW_COMMANDS

    assert set(LAW_COMMANDS) == {c.name for c in COMMANDS if c.law}


def test_doctor_reports_can_and_fallback() -> None:
    res = bench_cli("doctor", expect=0)
    assert "kernel CAN (AF_CAN)" in res.stdout
    if not probe_af_can().af_can:
        assert "errno 97" in res.stdout
        assert "VM fallback" in res.stdout
        assert re.search(r"CAN box: (down|up|booting|stopping)", res.stdout), res.stdout  # the box's state
    for dist in ("python-can", "canopen", "rerun-sdk"):
        assert dist in res.stdout


def test_vm_without_command_is_a_usage_error() -> None:
    res = bench_cli("vm", expect=64)
    assert "give the command" in res.stderr


def test_vm_returns_the_command_status_and_waits_for_no_background_process() -> None:
    """`bench vm -- CMD` exits with CMD's status (3; 9 had the VM no vcan0), with a real vcan0 inside, and returns
    though CMD leaves a process running in the guest (the VM powers off). One boot for the three: each costs ~40 s
    here (the CAN phase's `bench vm -- pytest ...` exits 0 through the same path)."""
    cmd = "ip -d link show vcan0 | grep -q vcan && cat /sys/class/net/vcan0/operstate || exit 9; sleep 100000 & exit 3"
    bench_cli("vm", "--", "sh", "-c", cmd, timeout=600, expect=3)


def test_vm_timeout_is_enforced_without_output() -> None:
    res = bench_cli("vm", "--timeout", "40", "--", "sleep", "100000", timeout=600, expect=124)
    assert "timed out" in res.stderr


def test_help_lists_no_hidden_command() -> None:
    """The internal `capture` is not listed (a help=SUPPRESS leaked as "capture ==SUPPRESS==")."""
    out = bench_cli("--help").stdout
    assert "SUPPRESS" not in out and "capture" not in out, out


def test_run_help_lists_every_exit_code_of_the_verdict_table() -> None:
    """bench run/replay --help: every status with its exit code, from summary.EXIT_CODES (8, 9 were missing)."""
    import re

    from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET

    for cmd in ("run", "replay"):
        text = " ".join(bench_cli(cmd, "--help").stdout.split())  # argparse wraps lines anywhere
        for status, code in EXIT_CODES.items():
            assert re.search(rf"\b{code} {status}\b", text), (cmd, status, code)
        assert f"{EXIT_EXPECTATION_NOT_MET} expected status not reached" in text


def test_docs_name_only_commands_that_exist() -> None:
    """Every `bench COMMAND` the README and docs show in code exists (the README named a `bench check`)."""
    import re

    from bench.cli import build_parser
    from bench.paths import REPO

    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    commands = set(sub.choices)  # type: ignore[attr-defined]
    bad = []
    for doc in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for code in re.findall(r"`([^`\n]+)`", doc.read_text()):
            for m in re.finditer(r"(?:^|[\s/])bench ([a-z][a-z-]*)", code):
                if m.group(1) not in commands:
                    bad.append(f"{doc.name}: `{code}`")
    assert not bad, bad


def test_the_readme_lists_every_exit_code() -> None:
    """README's "Exit status" paragraph, the one hand-written copy (bench run --help is generated from EXIT_CODES):
    every code of the table, and no other."""
    import re

    from bench.paths import REPO
    from bench.run.command import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INTERRUPTED
    from bench.run.verdict.summary import EXIT_CODES, EXIT_EXPECTATION_NOT_MET

    text = (REPO / "README.md").read_text()
    para = text[text.index("**Exit status**") :].split("\n\n")[0]
    listed = {int(n) for n in re.findall(r"(?:^|[\s,;:(])(\d{1,3}) (?=[a-z])", para)}
    codes = {*EXIT_CODES.values(), EXIT_EXPECTATION_NOT_MET, EXIT_FAILURE, EXIT_BAD_INPUT, EXIT_INTERRUPTED}
    assert listed == codes


def test_doctor_tells_a_pip_user_pip_and_a_clone_make_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """A missing dependency of an installed package: the bench again from where it came (which brings it), the
    installed numpy pinned, not a bare `pip install "python-can"` that may move numpy; in a clone: make setup."""
    from bench.tools import doctor

    monkeypatch.setattr(doctor, "INSTALLED", True)  # a pip-installed package: no Makefile to run
    numpy = importlib.metadata.version("numpy")
    hint = doctor._install_hint("python-can")  # the bench's origin here: this clone (bench.extras.origin)
    assert hint == shlex.join([sys.executable, "-m", "pip", "install", "-e", str(REPO), f"numpy=={numpy}"]), hint
    monkeypatch.setattr(doctor, "INSTALLED", False)
    assert doctor._install_hint("python-can").startswith("make setup")


class _Dist:
    """A stand-in for importlib.metadata's distribution of the bench, with the direct_url.json pip wrote (or none)."""

    def __init__(self, direct_url: dict[str, Any] | None, version: str = "0.9.1") -> None:
        self.version = version
        self._text = None if direct_url is None else json.dumps(direct_url)

    def read_text(self, name: str) -> str | None:
        return self._text if name == "direct_url.json" else None


SHA = "0123456789abcdef0123456789abcdef01234567"


@pytest.mark.parametrize(
    "direct_url, kind, args",
    [
        (None, "index", ["pmsm-hil-bench[view]==0.9.1"]),
        (
            {"url": "https://github.com/lab/pmsm-hil-bench.git", "vcs_info": {"vcs": "git", "commit_id": SHA}},
            "git",
            [f"pmsm-hil-bench[view] @ git+https://github.com/lab/pmsm-hil-bench.git@{SHA}"],
        ),
        (
            {"url": "ssh://git@lab/x.git", "vcs_info": {"vcs": "git", "commit_id": SHA}, "subdirectory": "bench"},
            "git",
            [f"pmsm-hil-bench[view] @ git+ssh://git@lab/x.git@{SHA}#subdirectory=bench"],
        ),
        ({"url": "file:///opt/my%20benches/pmsm", "dir_info": {}}, "folder", ["/opt/my benches/pmsm[view]"]),
        ({"url": "file:///src/pmsm", "dir_info": {"editable": True}}, "editable", ["-e", "/src/pmsm[view]"]),
        (
            {"url": "file:///w/pmsm_hil_bench-0.9.1-py3-none-linux_x86_64.whl", "archive_info": {}},
            "archive",
            ["pmsm-hil-bench[view] @ file:///w/pmsm_hil_bench-0.9.1-py3-none-linux_x86_64.whl"],
        ),
    ],
    ids=["pypi", "git", "git-subdirectory", "folder", "editable", "wheel"],
)
def test_the_extras_hint_names_the_source_and_keeps_numpy(
    monkeypatch: pytest.MonkeyPatch, direct_url: dict[str, Any] | None, kind: str, args: list[str]
) -> None:
    """bench.extras: the install line adds the extra to the bench from where pip installed it (PEP 610's
    direct_url.json: git at the installed commit, a folder, an editable folder, a wheel; none: an index at the
    installed version), with `numpy==<installed>`, as every message that names a missing extra says it."""
    from bench import extras

    monkeypatch.setattr(extras, "INSTALLED", True)
    monkeypatch.setattr(importlib.metadata, "distribution", lambda name: _Dist(direct_url))
    numpy = f"numpy=={importlib.metadata.version('numpy')}"
    assert extras.origin()[0] == kind
    assert extras.requirement("view") == [*args, numpy]
    line = extras.missing_extra("view", "bench replay", "no module 'rerun'")
    assert line == (
        f"bench replay needs the package's [view] extra (no module 'rerun'): "
        f"{shlex.join([sys.executable, '-m', 'pip', 'install', *args, numpy])}"
    )
    assert "pip install 'pmsm-hil-bench[view]'" not in line  # the bare line of before, which named no source


def test_doctor_reports_a_missing_extra_as_optional_with_a_line_that_keeps_numpy(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A pip user without [view]: the extra's line is optional (`--`, not `NO`), names what it brings and how to add
    it from where the bench came with the installed numpy pinned; doctor's exit status stays 0."""
    from bench import extras
    from bench.tools import doctor

    real = doctor._py_version
    monkeypatch.setattr(doctor, "_py_version", lambda d: None if d == "rerun-sdk" else real(d))
    monkeypatch.setattr(doctor, "INSTALLED", True)
    numpy = importlib.metadata.version("numpy")
    view = doctor.extra_check("view")
    assert (view.ok, view.optional) == (False, True)
    assert "rerun-sdk not installed" in view.detail and "optional: run.rrd" in view.detail, view.detail
    assert view.fix == extras.install_command("view")  # from this clone, the bench's origin here
    assert view.fix == shlex.join([sys.executable, "-m", "pip", "install", "-e", f"{REPO}[view]", f"numpy=={numpy}"])
    checks = [doctor.Check("gcc", True, "12"), view, doctor.extra_check("fmu")]
    monkeypatch.setattr(doctor, "collect", lambda: (checks, "host"))
    assert doctor.report() == 0
    out = capsys.readouterr().out
    assert re.search(r"\[-- \] \[view\] extra +rerun-sdk not installed", out), out
    assert f"fix: {view.fix}" in out and "problem(s)" not in out, out
    assert "Optional, not installed: [view] extra (not a problem" in out and f"your numpy {numpy} kept" in out, out
    broken = [*checks, doctor.Check("python-can", False, "not installed")]
    monkeypatch.setattr(doctor, "collect", lambda: (broken, "host"))
    assert doctor.report() == 1  # a missing dependency still is a problem
    assert "1 problem(s) above" in capsys.readouterr().out


def test_the_extras_tables_name_pyproject_s_extras() -> None:
    """bench/extras.py's tables (the modules, the distributions doctor shows, the purposes) cover exactly the extras
    of pyproject.toml but [all] and [dev], and each distribution doctor shows is one the extra installs."""
    import tomllib

    from bench import extras

    declared = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    features = {k: v for k, v in declared.items() if k not in ("all", "dev")}
    assert set(extras.EXTRAS) == set(extras.DISTS) == set(extras.PURPOSE) == set(features)
    for extra, dists in extras.DISTS.items():
        names = {re.split(r"[<>=!~;\[ ]", r, maxsplit=1)[0].lower() for r in features[extra]}
        assert set(dists) <= names, (extra, set(dists) - names)
