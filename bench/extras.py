"""The package's extras (pyproject.toml [project.optional-dependencies]): what each brings, and the one message a
command gives when it needs one that is not installed.

    [view]   rerun-sdk: each run's Rerun recording (run.rrd), the live viewer, bench serve      (~500 MB with pyarrow)
    [sweep]  dask, distributed, bokeh, pyarrow, matplotlib: bench sweep, its Parquet table and plots

The plain install (the runs, their traces, bus logs, SVG plots and summaries, the pytest plugin, the CAN box)
needs neither.
"""

from __future__ import annotations

import importlib.util
import sys

EXTRAS: dict[str, tuple[str, ...]] = {
    "view": ("rerun", "matplotlib"),
    "sweep": ("dask", "distributed", "pyarrow", "matplotlib"),
}


def missing_extra(extra: str, what: str, why: str = "") -> str:
    """'<what> needs the [extra] extra (<why>): pip install "pmsm-hil-bench[extra]"' (in a clone: make setup)."""
    from bench.root import INSTALLED

    fix = f"pip install 'pmsm-hil-bench[{extra}]'" if INSTALLED else f"{sys.executable} -m pip install -e '.[{extra}]'"
    return f"{what} needs the package's [{extra}] extra ({why or 'not installed'}): {fix}"


def lacking(extra: str) -> str | None:
    """The first module of the extra that is not importable here, or None."""
    return next((m for m in EXTRAS[extra] if importlib.util.find_spec(m) is None), None)
