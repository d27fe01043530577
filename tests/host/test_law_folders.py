"""A user law's build folder (bench/law.py, issue 28): one per law folder (two folders of one law name, e.g. two
CI jobs on one machine, never build over each other), the builds of folders that are gone removed, and a
working folder that cannot be written refused in one line, not a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.law import LawBuildError, _prune, build, build_folder
from bench.paths import REPO

LAW = REPO / "examples" / "laws" / "complex_vector_pi"


def test_two_folders_of_one_law_name_build_apart(tmp_path: Path) -> None:
    a, b = build_folder(tmp_path / "a", "my_law", tmp_path), build_folder(tmp_path / "b", "my_law", tmp_path)
    assert a != b and a.parent == b.parent == tmp_path / "laws" and a.name.startswith("my_law-")
    assert build_folder(tmp_path / "a", "my_law", tmp_path) == a


def test_the_builds_of_folders_that_are_gone_are_removed(tmp_path: Path) -> None:
    laws = tmp_path / "laws"
    kept_src, gone_src = tmp_path / "kept", tmp_path / "gone"
    kept_src.mkdir()
    for name, src in (("my_law-aaaa0000", kept_src), ("my_law-bbbb0000", gone_src), ("other-cccc0000", gone_src)):
        (laws / name).mkdir(parents=True)
        (laws / name / "law.from").write_text(f"{src}\n")
    current = laws / "my_law-dddd0000"
    current.mkdir()
    _prune(current, "my_law")
    assert sorted(p.name for p in laws.iterdir()) == ["my_law-aaaa0000", "my_law-dddd0000", "other-cccc0000"]


def test_a_working_folder_that_cannot_be_written_is_refused_in_one_line(tmp_path: Path) -> None:
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    with pytest.raises(LawBuildError, match=r"^cannot build in .*BENCH_CACHE_DIR"):
        build(LAW, state=blocked)
