"""The firmware core is portable: it builds for a Cortex-M4F without a warning and
includes no OS header.

Every firmware_shim/core/*.c is cross-compiled with arm-none-eabi-gcc for the
Cortex-M4F (hard float, single-precision FPU) with -Werror, plus the warnings the
host build of the firmware uses (-Wdouble-promotion matters most here: a double on
the M4F is software-emulated), and arm-none-eabi-size must report code in it.
The toolchain comes with the set-up (`scripts/setup.sh`: gcc-arm-none-eabi); a
missing toolchain fails the test with the command that installs it.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from bench.paths import REPO

CORE = REPO / "firmware_shim" / "core"
LAWS = REPO / "firmware_shim" / "laws"  # the papers' law folders: portable as the cores, their headers their own
GENERATED = REPO / "protocols" / "generated"
# the EDS's names, defaults and enumerations as plain C (protocols/gen_od.py): the core's one generated input
PLAIN_GENERATED = {"od_drive_fields.h"}
SOURCES = sorted(CORE.glob("*.c")) + sorted(LAWS.glob("*/*.c"))
ARM_FLAGS = [
    "-mcpu=cortex-m4",
    "-mthumb",
    "-mfpu=fpv4-sp-d16",
    "-mfloat-abi=hard",
    "-O2",
    "-std=c11",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-Wshadow",
    "-Wstrict-prototypes",
    "-Wdouble-promotion",
    "-Wfloat-conversion",
]
ALLOWED_SYSTEM_HEADERS = {"stdint.h", "stdbool.h", "stddef.h", "math.h", "string.h"}
INCLUDE_RE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.M)


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        pytest.fail(f"{name} not found: apt-get install gcc-arm-none-eabi (or run `make setup`)")
    return path


def test_core_sources_exist() -> None:
    assert SOURCES, f"no C sources in {CORE}"


@pytest.mark.parametrize("src", SOURCES, ids=[p.name for p in SOURCES])
def test_builds_for_cortex_m4f_without_warnings(src: Path, tmp_path: Path) -> None:
    gcc, size = _tool("arm-none-eabi-gcc"), _tool("arm-none-eabi-size")
    obj = tmp_path / (src.stem + ".o")
    res = subprocess.run(
        [gcc, *ARM_FLAGS, f"-I{CORE}", f"-I{src.parent}", f"-I{GENERATED}", "-c", str(src), "-o", str(obj)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, f"{src.name} does not build for the Cortex-M4F:\n{res.stderr}"
    assert res.stderr.strip() == "", f"{src.name}: compiler output:\n{res.stderr}"
    out = subprocess.run([size, "-B", str(obj)], capture_output=True, text=True, timeout=60, check=True).stdout
    text, data, bss = (int(v) for v in out.splitlines()[1].split()[:3])
    assert text > 0, f"{src.name}: arm-none-eabi-size reports no code: {out}"
    assert data >= 0 and bss >= 0


@pytest.mark.parametrize("path", sorted(CORE.glob("*.[ch]")) + sorted(LAWS.glob("*/*.[ch]")), ids=lambda p: p.name)
def test_no_os_headers(path: Path) -> None:
    local = {p.name for p in CORE.glob("*.h")} | {p.name for p in path.parent.glob("*.h")} | PLAIN_GENERATED
    bad = []
    for kind, name in INCLUDE_RE.findall(path.read_text()):
        if kind == "<" and name not in ALLOWED_SYSTEM_HEADERS:
            bad.append(f"<{name}>")
        elif kind == '"' and name not in local:
            bad.append(f'"{name}" (not a header of firmware_shim/core or of its own folder)')
    assert not bad, (
        f"{path.name} includes {', '.join(bad)}; the core may use only "
        f"{sorted(ALLOWED_SYSTEM_HEADERS)}, its own headers and {sorted(PLAIN_GENERATED)}"
    )


@pytest.mark.parametrize("name", sorted(PLAIN_GENERATED))
def test_generated_plain_headers_include_nothing(name: str) -> None:
    """Plain C for the cores: the fixed-width types of the records' structs (<stdint.h>, a freestanding
    header), nothing of CANopen or the OS."""
    includes = INCLUDE_RE.findall((GENERATED / name).read_text())
    assert includes in ([], [("<", "stdint.h")]), f"{name} must stay plain C (<stdint.h> at most): {includes}"
