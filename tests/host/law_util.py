"""The tests' user law, tests/laws/zero_law, under a name of its own (its own build folder: tests may run side by
side): the law.eds key CurrentLaws and the C descriptor current_law_<name> renamed."""

from __future__ import annotations

import shutil
from pathlib import Path

ZERO_LAW = Path(__file__).resolve().parents[1] / "laws" / "zero_law"


def rename(law: Path, name: str) -> None:
    """A copy of zero_law, in place, as the law `name`."""
    for f in law.iterdir():
        text = f.read_text().replace("CurrentLaws=zero_law", f"CurrentLaws={name}")
        f.write_text(text.replace("current_law_zero_law", f"current_law_{name}"))


def zero_law_as(dst: Path, name: str) -> Path:
    """zero_law copied to `dst` as the law `name`; `dst`."""
    shutil.copytree(ZERO_LAW, dst)
    rename(dst, name)
    return dst
