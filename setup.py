"""The C half of `pip install`: the package carries what the C build needs and builds it at install time.

pyproject.toml holds the project's metadata; this file only adds one step to setuptools' build_py: the
sources of the nodes (Makefile, protocols/, plant_rt/, firmware_shim/, bench/direct/) and the scenarios are
copied into the package as bench/_root, and `make package` builds there the node processes, libhil.so, the
tools and, when arm-none-eabi-gcc is installed, the Cortex-M4F image (bench/root.py finds them). The build
keeps no object file and no path of the machine that built it (-ffile-prefix-map), so a wheel can be
installed elsewhere. An editable install (`pip install -e .`, what `make setup` does in a clone) builds
nothing: a clone uses its own build/ (`make all`).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

try:
    from setuptools.command.bdist_wheel import bdist_wheel
except ImportError:  # setuptools < 70.1: the wheel package's
    from wheel.bdist_wheel import bdist_wheel

HERE = Path(__file__).resolve().parent
# What the C build of an installed package reads (and the scenarios `bench demo`/`perf` run).
SOURCES = ("Makefile", "protocols", "plant_rt", "firmware_shim", "bench/direct", "scenarios")
SKIP = shutil.ignore_patterns("tests", "fuzz", "__pycache__", "*.pyc", ".*")
# Of the build, what a run uses: the rest (objects, dependency files, archives) stays out of the package.
DROP = ("obj", "deps", "eds-cache", "mcu/obj")
TOOLS = (("make", "make"), ("gcc", "gcc (or set CC)"))
APT = "apt-get install build-essential (Debian, Ubuntu), dnf install gcc make (Fedora)"
MCU_MISSING = (
    "pmsm-hil-bench: arm-none-eabi-gcc not found: the Cortex-M4F image (bench run --drive mcu) is not built; "
    "apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi, then reinstall to have it"
)


class BinaryDistribution(Distribution):
    """The wheel holds compiled programs: a platform wheel, not pure Python."""

    def has_ext_modules(self) -> bool:
        return True


class PlatformWheel(bdist_wheel):
    """py3-none-<platform>: the programs and libhil.so (loaded by ctypes) use no Python ABI, so one wheel serves
    every Python the project supports on this platform."""

    def get_tag(self) -> tuple[str, str, str]:
        return ("py3", "none", super().get_tag()[2])


def _check_tools() -> None:
    cc = os.environ.get("CC", "gcc")
    for tool, what in TOOLS:
        name = cc if tool == "gcc" else tool
        if shutil.which(name) is None:
            sys.exit(
                f"pmsm-hil-bench builds its C nodes at install time and needs {what}: `{name}` is not installed.\n"
                f"Install a C compiler and make first: {APT}"
            )


def build_native(root: Path) -> None:
    """Copy the C sources into `root` and run `make package` there; nothing of the build machine is kept."""
    _check_tools()
    if any(c.isspace() for c in str(root)):
        sys.exit(
            f"pmsm-hil-bench: cannot build in {root}: make cannot take a path with white space; "
            "install from a folder whose path has none"
        )
    if root.exists():
        shutil.rmtree(root)
    for rel in SOURCES:
        src, dst = HERE / rel, root / rel
        if src.is_dir():
            shutil.copytree(src, dst, ignore=SKIP)
        else:
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
    cmd = ["make", "-C", str(root), "package", f"-j{os.cpu_count() or 1}", f"PYTHON={sys.executable}"]
    cmd.append(f"PATHMAP=-ffile-prefix-map={root}=.")
    print("pmsm-hil-bench: building the C nodes:", " ".join(cmd), file=sys.stderr, flush=True)
    res = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if res.returncode != 0:
        sys.exit(f"pmsm-hil-bench: the C build failed (make package):\n{res.stdout[-4000:]}")
    if shutil.which("arm-none-eabi-gcc") is None:
        print(MCU_MISSING, file=sys.stderr)
    build = root / "build"
    for rel in DROP:
        shutil.rmtree(build / rel, ignore_errors=True)
    for lib in build.glob("*.a"):
        lib.unlink()
    for junk in build.rglob("*.d"):
        junk.unlink()


class BuildWithNodes(build_py):
    """build_py, then the C nodes into bench/_root of the build (not for an editable install)."""

    def run(self) -> None:
        super().run()
        if not getattr(self, "editable_mode", False):
            build_native(Path(self.build_lib).resolve() / "bench" / "_root")


setup(
    cmdclass={"build_py": BuildWithNodes, "bdist_wheel": PlatformWheel},
    distclass=BinaryDistribution,
    options={"build": {"build_base": "build/setuptools"}},
)
