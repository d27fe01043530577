"""Where the bench's own files are, with no environment read: a clone, or an installed package.

From a clone (`make demo`, `make test`, `pip install -e .`), REPO is the clone: its sources, EDS files,
scenarios and build/. An installed package (`pip install <repository>`, a wheel) carries a copy of what the
C build needs and its result under bench/_root (setup.py builds it at install time): REPO is that copy.

STATE is where the bench writes its own working files (a law's build, the VM's job folders, the EDS
cache): the clone's build/ from a clone; from a package, $BENCH_CACHE_DIR, else $XDG_CACHE_HOME/pmsm-hil-bench
(~/.cache/pmsm-hil-bench), since an installed package's folder may not be writable.
"""

from __future__ import annotations

import os
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
_CLONE = PACKAGE.parent
INSTALLED = not ((_CLONE / "Makefile").is_file() and (_CLONE / "protocols" / "eds").is_dir())
REPO = PACKAGE / "_root" if INSTALLED else _CLONE


def _state() -> Path:
    if not INSTALLED:
        return REPO / "build"
    env = os.environ.get("BENCH_CACHE_DIR")
    if env:
        return Path(env).resolve()
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache").resolve() / "pmsm-hil-bench"


STATE = _state()
