"""Where the bench finds its own files: the repository (or an installed package's copy: bench/root.py), the C
build, the EDS files.

BENCH_BUILD_DIR chooses another build: a user's law (`bench run ... --law DIR`, bench/law.py, builds
laws/<law name>-<hash>/ of the working folder STATE), whose node binaries, libhil.so, MCU image and merged
EDS files (its eds/) the bench then uses; the repository's own build's are protocols/generated/eds/ (the
papers' law folders merged into protocols/eds/drive.eds by protocols/gen_od.py). Read once, at import: the CLI
sets it before any module reads an EDS (`bench vm` forwards it into the VM, as every BENCH_* variable).
"""

from __future__ import annotations

import os
from pathlib import Path

from bench.root import INSTALLED, REPO, STATE

BUILD = Path(os.environ.get("BENCH_BUILD_DIR") or REPO / "build").resolve()
BIN = BUILD / "bin"
# The EDS files as built: drive.eds with the law folders merged (protocols/gen_law.py), plant.eds, common.ini.
EDS_DIR = BUILD / "eds" if os.environ.get("BENCH_BUILD_DIR") else REPO / "protocols" / "generated" / "eds"
VECTORS_DIR = REPO / "protocols" / "vectors"
MISSING_BUILD = (
    "reinstall pmsm-hil-bench (its C build is made at install time: pip install --force-reinstall <repository>)"
    if INSTALLED
    else f"run `make all` (or `make demo`) in {REPO}"
)
__all__ = ["BIN", "BUILD", "EDS_DIR", "MISSING_BUILD", "REPO", "STATE", "VECTORS_DIR", "binary", "lost_in_vm"]


def binary(name: str) -> Path:
    """Path of a C executable built by `make`; a clear error if it is missing. BENCH_BIN_DIR chooses another
    build of the node processes (build/sanitize/bin: ASan + UBSan, `make sanitize`)."""
    path = Path(os.environ.get("BENCH_BIN_DIR") or BIN) / name
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing: {MISSING_BUILD}")
    return path


def lost_in_vm(path: Path) -> str | None:
    """Inside the VM of `bench vm` (BENCH_IN_VM=1): why writing `path` would lose it - a folder the VM
    does not share with the host is the guest's own (its /tmp too), gone when the VM powers off - or
    None when it reaches the host (or when not in the VM)."""
    shared = os.environ.get("BENCH_VM_SHARED")
    if os.environ.get("BENCH_IN_VM") != "1" or shared is None:
        return None
    dirs = [Path(d) for d in shared.split(os.pathsep) if d]
    if any(path.resolve().is_relative_to(d) for d in dirs):
        return None
    return (
        f"{path} is inside the VM's own file system and would be lost when it stops; write under a folder "
        f"shared with the host ({', '.join(map(str, dirs))}; `bench vm --rwdir DIR` shares another)"
    )
