"""Where the bench finds its own files: the repository, the C build, the EDS files."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BUILD = REPO / "build"
BIN = BUILD / "bin"
EDS_DIR = REPO / "protocols" / "eds"
VECTORS_DIR = REPO / "protocols" / "vectors"


def binary(name: str) -> Path:
    """Path of a C executable built by `make`; a clear error if it is missing. BENCH_BIN_DIR chooses another
    build of the node processes (build/sanitize/bin: ASan + UBSan, `make sanitize`)."""
    import os

    path = Path(os.environ.get("BENCH_BIN_DIR") or BIN) / name
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing: run `make all` (or `make demo`) in {REPO}")
    return path
