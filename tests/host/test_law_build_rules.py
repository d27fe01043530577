"""A current law's C files are compiled the same way for the papers' folders (firmware_shim/laws/<paper>/) and a
user's (`make LAW=DIR`): with their own folder and the law interface on the include path, nothing else of the
firmware, the plant or the CANopen stack (issue 53). Read from make's own commands (`make -n`), so a rule that
gives a law the whole include path again fails here."""

from __future__ import annotations

import subprocess
from pathlib import Path

from bench.paths import REPO

INTERFACE = {"firmware_shim/core"}  # current_law.h, dq_math.h, drive_config.h (and the generated OD fields)


def _compile_includes(args: list[str], source: Path) -> set[str]:
    res = subprocess.run(["make", "-n", "-B", *args], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    line = next((ln for ln in res.stdout.splitlines() if f"-c {source}" in ln), None)
    assert line is not None, f"make compiles no {source}:\n{res.stdout[-2000:]}"
    return {a[2:] for a in line.split() if a.startswith("-I")}


def test_the_papers_law_folders_see_their_folder_and_the_law_interface_only() -> None:
    folders = sorted(p.parent.relative_to(REPO) for p in (REPO / "firmware_shim" / "laws").glob("*/law.eds"))
    assert len(folders) == 3, folders
    for folder in folders:
        for source in sorted(folder.glob("*.c"))[:2]:
            obj = f"build/obj/{source.with_suffix('.o')}"
            assert _compile_includes([obj], source) == {str(folder), "protocols/generated", *INTERFACE}, source


def test_a_users_law_folder_is_compiled_as_the_papers_are(tmp_path: Path) -> None:
    folder = REPO / "examples" / "laws" / "complex_vector_pi"
    source = next(folder.glob("*.c"))
    obj = tmp_path / "obj" / "law" / source.with_suffix(".o").name
    got = _compile_includes([f"LAW={folder}", f"BUILD={tmp_path}", str(obj)], source)
    assert got == {str(folder), str(tmp_path / "generated"), *INTERFACE}
