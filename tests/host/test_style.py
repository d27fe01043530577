"""Code style (issue 13): the Python passes ruff's lint and formatter, the hand-written C clang-format.

ruff's rules and line length are pyproject.toml's [tool.ruff]; the C style is the root .clang-format,
over the C of firmware_shim, plant_rt, protocols and bench/direct (protocols/generated is written by
protocols/gen_od.py from the EDS files and not formatted). ruff is a pinned dependency of the venv,
clang-format comes with the set-up (`scripts/setup.sh`: clang-format); a missing tool fails the test
with the command that installs it. `make format` applies both formatters.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bench.paths import REPO

C_DIRS = ("firmware_shim", "plant_rt", "protocols", "bench/direct")
GENERATED = REPO / "protocols" / "generated"
CLANG_FORMAT_MAJOR = 14  # Debian 12's; another version lays some constructs out differently
MAX_REPORT = 6000  # characters of tool output in a failure message


def c_sources() -> list[Path]:
    """The hand-written C: every .c/.h under C_DIRS but protocols/generated."""
    return sorted(p for d in C_DIRS for p in (REPO / d).rglob("*.[ch]") if GENERATED not in p.parents)


def _ruff() -> str:
    ruff = Path(sys.executable).parent / "ruff"
    if not ruff.is_file():
        pytest.fail(
            f"{ruff} not found: pip install -e . in the venv (ruff is pinned in pyproject.toml), or `make setup`"
        )
    return str(ruff)


def _clang_format() -> str:
    path = shutil.which("clang-format")
    if path is None:
        pytest.fail("clang-format not found: apt-get install clang-format (or run `make setup`)")
    out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=60, check=True).stdout
    m = re.search(r"clang-format version (\d+)\.", out)
    if m is None or int(m.group(1)) != CLANG_FORMAT_MAJOR:
        pytest.fail(
            f"clang-format {CLANG_FORMAT_MAJOR} expected (Debian 12: apt-get install clang-format), found: {out}"
        )
    return path


def _run(cmd: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)


def _check(res: subprocess.CompletedProcess[str], what: str, quiet: bool = False) -> None:
    """Fail with `what` and the tool's output (shortened) unless it exited 0 (and, if quiet, said nothing)."""
    text = (res.stdout + res.stderr).strip()
    if res.returncode != 0 or (quiet and text):
        if len(text) > MAX_REPORT:
            text = text[:MAX_REPORT] + f"\n... ({len(text) - MAX_REPORT} more characters)"
        pytest.fail(f"{what}:\n{text}", pytrace=False)


def test_c_sources_found() -> None:
    found = {d for d in C_DIRS if any(p.is_relative_to(REPO / d) for p in c_sources())}
    assert found == set(C_DIRS), f"no C found under {set(C_DIRS) - found}"
    assert not any(p.is_relative_to(GENERATED) for p in c_sources())


def test_ruff_lint() -> None:
    res = _run([_ruff(), "check", "--no-cache", "--output-format", "concise", "."])
    _check(res, "ruff check (rules: pyproject.toml [tool.ruff.lint])")


def test_ruff_format() -> None:
    res = _run([_ruff(), "format", "--no-cache", "--diff", "."])
    _check(res, "Python not formatted as ruff format does (run `make format`)")


def test_clang_format() -> None:
    files = [str(p.relative_to(REPO)) for p in c_sources()]
    res = _run([_clang_format(), "--dry-run", "--Werror", "--style=file", *files])
    bad = sorted(set(re.findall(r"^(\S+?):\d+:\d+: (?:error|warning):", res.stderr, re.M)))
    _check(res, f"C not formatted as .clang-format says (run `make format`): {', '.join(bad)}", quiet=True)


def test_generated_code_is_not_formatted() -> None:
    """protocols/generated stays as gen_od.py writes it: its .clang-format turns formatting off."""
    files = sorted(str(p.relative_to(REPO)) for p in GENERATED.glob("*.[ch]"))
    assert files
    res = _run([_clang_format(), "--dry-run", "--Werror", "--style=file", *files])
    _check(res, "clang-format would change protocols/generated", quiet=True)
    assert "DisableFormat: true" in (GENERATED / ".clang-format").read_text()
