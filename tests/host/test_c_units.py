"""Every C unit-test executable built by `make` (plant, firmware, CANopen cores) must pass.

Each is a standalone program that prints what it measured and exits non-zero on a failed check.
"""

from __future__ import annotations

import subprocess

import pytest

from bench.paths import BUILD, REPO

UNIT_TESTS = sorted((BUILD / "tests").glob("*"))


def test_unit_tests_were_built() -> None:
    names = {p.name for p in UNIT_TESTS}
    assert any(n.startswith("plant_") for n in names), names
    assert any(n.startswith("fw_") for n in names), names


@pytest.mark.parametrize("exe", UNIT_TESTS, ids=[p.name for p in UNIT_TESTS])
def test_c_unit(exe) -> None:  # type: ignore[no-untyped-def]
    res = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300, cwd=REPO)
    print(res.stdout[-4000:])
    assert res.returncode == 0, f"{exe.name} failed:\n{res.stdout[-3000:]}\n{res.stderr[-2000:]}"
