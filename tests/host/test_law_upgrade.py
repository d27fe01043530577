"""A law written against the previous law interface (issue 52): the bench's message says what changed, in which
version and what to write instead, pointing to docs/YOUR_CONTROLLER.md's upgrade note, never the compiler's error
alone. The removed names are one table (bench/law_upgrade.py); each is checked to be gone from what a law sees and
to be recognised in gcc's and clang's words; the version is one (pyproject.toml) and CHANGELOG.md names the
removals."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import bench
from bench.law_upgrade import NOTES, REMOVED, Removed, explain, removed_in
from bench.paths import REPO

EXAMPLE_LAW = REPO / "examples" / "laws" / "complex_vector_pi"
GUIDE = REPO / "docs" / "YOUR_CONTROLLER.md"
CHANGELOG = REPO / "CHANGELOG.md"
LAW_SEES = ("firmware_shim/core", "protocols/generated", "protocols/canopen")  # what `#include "current_law.h"` needs


def _law_of_0_1(tmp_path: Path) -> Path:
    """The docs' example law as 0.1 had it (git show 88a0484: `.signals = 0,` after `.status`)."""
    law = tmp_path / "user" / "old_law"
    shutil.copytree(EXAMPLE_LAW, law)
    c = law / "complex_vector_pi.c"
    text = c.read_text()
    assert text.count("    .status = cvpi_status,\n") == 1
    c.write_text(text.replace("    .status = cvpi_status,\n", "    .status = cvpi_status,\n    .signals = 0,\n"))
    return law


def test_a_law_written_for_0_1_is_told_what_changed_and_what_to_write(tmp_path: Path) -> None:
    law = _law_of_0_1(tmp_path)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BENCH_", "MAKEFLAGS"))}
    res = subprocess.run(
        ["make", "-C", str(REPO), "--no-print-directory", f"LAW={law}", f"PYTHON={sys.executable}"],
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
    )
    said = res.stdout + res.stderr
    assert res.returncode != 0, said
    message = said[said.index(f"bench: LAW={law}: ") :]
    assert re.search(r"current_law_t\.signals: removed in 0\.2\.0: a law's quantities are the status entries", message)
    assert "Trace= key" in message and "delete the signals function, the .signals member" in message, message
    assert 'docs/YOUR_CONTROLLER.md, "Upgrading from 0.1"' in message, message
    before, _, compiler = message.partition("the compiler's first error:\n")
    assert compiler.startswith(f"{law}/complex_vector_pi.c:"), message  # the compiler's own words follow
    assert re.search(r"has no member named .signals.", compiler), message
    assert "drive_config_t" not in before, message  # only what this law uses


def _probe(row: Removed) -> str:
    """C that uses the removed name as a law of its version did."""
    if row.owner == "current_law_t":
        return f"const current_law_t probe = {{ .{row.name} = 0 }};\n"
    if row.owner == "drive_config_t":
        return f"float probe(const drive_config_t *c) {{ return (float)c->{row.name}; }}\n"
    return f"int probe = (int){row.name};\n"


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_every_removed_name_is_gone_and_recognised(cc: str, tmp_path: Path) -> None:
    """Each row's name no longer compiles in a law (`#include "current_law.h"`), and the compiler's words for it
    name exactly that row."""
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} is not installed")
    for n, row in enumerate(REMOVED):
        src = tmp_path / f"probe{n}.c"
        src.write_text('#include "current_law.h"\n' + _probe(row))
        inc = [f"-I{REPO / d}" for d in LAW_SEES]
        res = subprocess.run([cc, "-std=c11", "-fsyntax-only", *inc, str(src)], capture_output=True, text=True)
        assert res.returncode != 0, f"{row.what} still compiles in a law"
        assert removed_in(res.stderr.splitlines()) == [row], (row, res.stderr)


def test_other_compilers_words_and_what_is_not_ours() -> None:
    assert removed_in(["x.c:3:5: error: unknown field 'signals' specified in initializer"]) == [REMOVED[0]]
    mine = "x.c:3:5: error: 'my_state_t' {aka 'struct <anonymous>'} has no member named 'signals'"
    assert removed_in([mine]) == []  # a member of the user's own struct: not the interface's
    assert explain(["x.c:1:1: error: expected ';' before '}' token"]) is None


def test_one_version_and_the_changes_are_written_down() -> None:
    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert bench.__version__ == version
    log = CHANGELOG.read_text()
    released = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", log, re.MULTILINE)
    assert released and released[0] == version, f"CHANGELOG.md's newest release is not {version}: {released}"
    assert re.search(r"^## \[Unreleased\]", log, re.MULTILINE), "CHANGELOG.md: no Unreleased section at the top"
    guide = GUIDE.read_text()
    for row in REMOVED:
        assert tuple(map(int, row.version.split("."))) <= tuple(map(int, version.split("."))), row
        assert row.version in NOTES and re.search(rf"^## \d+\. {re.escape(NOTES[row.version])}$", guide, re.M), row
        start = log.index(f"## [{row.version}]")
        end = log.find("\n## [", start + 1)
        section = log[start : end if end > 0 else None]
        named = (row.owner, row.name) if row.owner.endswith("_t") else (row.owner,)  # a member; a header's ids
        assert all(n in section for n in named), f"CHANGELOG.md [{row.version}] does not name {row.what}"
