"""A user law's build folder (bench/law.py, issue 28): one per law folder (two folders of one law name, e.g. two
CI jobs on one machine, never build over each other), the builds of folders that are gone removed, and a
working folder that cannot be written refused in one line, not a traceback."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from bench_cli import bench_cli
from law_util import zero_law_as

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


def _zero_law(tmp_path: Path, name: str) -> Path:
    """tests/laws/zero_law as a law of another name, outside the repository."""
    return zero_law_as(tmp_path / "user" / name, name)


def _state(root: Path) -> dict[str, tuple[int, int]]:
    """Every file under a folder: (size, mtime in ns), by its path there."""
    return {str(f.relative_to(root)): (f.stat().st_size, f.stat().st_mtime_ns) for f in root.rglob("*") if f.is_file()}


def test_make_law_and_bench_law_build_once_into_one_folder(tmp_path: Path) -> None:
    """The guide's two commands (`make LAW=DIR`, then `bench run --law DIR`): the second compiles nothing."""
    law = _zero_law(tmp_path, "once_law")
    made = subprocess.run(["make", "-C", str(REPO), f"LAW={law}"], capture_output=True, text=True, timeout=900)
    out = build_folder(law, "once_law")
    assert made.returncode == 0 and f"built in {out}" in made.stdout, made.stdout[-2000:] + made.stderr[-2000:]
    assert "  cc " in made.stderr and (out / "bin" / "drive_node").is_file()
    ran = bench_cli(
        "run", REPO / "tests" / "laws" / "zero_law.toml", "--law", law, "--set", "controller.controller=once_law",
        "--bus", "direct", "--no-viewer", "--out", tmp_path / "r", timeout=900, expect=0,
    )  # fmt: skip
    assert "  cc " not in ran.stderr and f"its build {out} is current" in ran.stderr, ran.stderr[-2000:]


def test_a_failing_build_leaves_the_good_one_and_a_first_one_leaves_nothing(tmp_path: Path) -> None:
    state = tmp_path / "state"
    law = _zero_law(tmp_path, "kept_law")
    out = build(law, state=state)
    good = _state(out)
    assert "bin/drive_node" in good and "libhil.so" in good
    src = law / "zero_law.c"
    src.write_text(src.read_text().replace("->steps++;", "->steps++ not_c;"))
    with pytest.raises(LawBuildError, match="does not compile"):
        build(law, state=state)
    assert _state(out) == good  # the last good build as it was: every file, its size and time
    other = _zero_law(tmp_path / "2", "first_law")
    broken = next(other.glob("*.c"))
    broken.write_text(broken.read_text().replace("->steps++;", "->steps++ not_c;"))
    with pytest.raises(LawBuildError, match="does not compile"):
        build(other, state=state)
    left = sorted(p.name for p in (state / "laws").iterdir())
    assert left == [".kept_law-" + out.name.split("-")[1] + ".work", ".lock", out.name], left  # no stub, no lock


def test_make_with_law_refuses_the_repositorys_own_goals() -> None:
    """LAW= (exported in a shell, say) with `make clean`/`make test`: refused naming the goal, nothing run."""
    res = subprocess.run(["make", "-C", str(REPO), f"LAW={LAW}", "clean"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and f"LAW={LAW} clean: with LAW, make builds a law's goals" in res.stderr, res.stderr
    assert (REPO / "build" / "bin").is_dir()  # `make clean` did not run
