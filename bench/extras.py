"""The package's extras (pyproject.toml [project.optional-dependencies]): what each brings, and the one message a
command gives when it needs one that is not installed.

    [view]   rerun-sdk, matplotlib: each run's Rerun recording (run.rrd), the live viewer, bench serve, the
             reproduction report's figures                                              (~500 MB with pyarrow)
    [sweep]  dask, distributed, bokeh, pyarrow, matplotlib: bench sweep, its Parquet table and plots
    [fmu]    FMPy: FMU plants ([motor.fmu]) and bench motor fmu-build

The plain install (the runs, their traces, bus logs, SVG plots and summaries, the pytest plugin, the CAN box)
needs none of them.

The install line a message gives adds the extra to the bench as it is installed: from the source it came from
(its PEP 610 direct_url.json: a git URL at the installed commit, a local folder, an archive; without one an index
such as PyPI, at the installed version; in a clone, the clone, editable), with the installed numpy kept
(`numpy==X`), so that adding an extra never moves a team's numpy (the extras' ranges take numpy 1.26 and 2.x).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import shlex
import sys
from typing import Any
from urllib.parse import unquote, urlparse

from bench.root import INSTALLED, PACKAGE

DIST = "pmsm-hil-bench"
# the modules a command imports from each extra
EXTRAS: dict[str, tuple[str, ...]] = {
    "view": ("rerun", "matplotlib"),
    "sweep": ("dask", "distributed", "pyarrow", "matplotlib"),
    "fmu": ("fmpy",),
}
# the distributions each extra installs (pyproject.toml's lists; bench doctor shows their versions)
DISTS: dict[str, tuple[str, ...]] = {
    "view": ("rerun-sdk", "pyarrow", "matplotlib"),
    "sweep": ("dask", "distributed", "bokeh", "pyarrow", "matplotlib"),
    "fmu": ("fmpy",),
}
# what each extra brings, in a few words (bench doctor's lines)
PURPOSE: dict[str, str] = {
    "view": "run.rrd, the live viewer, bench serve, the report's figures",
    "sweep": "bench sweep, its Parquet table",
    "fmu": "FMU plants, bench motor fmu-build",
}


def _direct_url(dist: importlib.metadata.Distribution) -> dict[str, Any] | None:
    text = dist.read_text("direct_url.json")
    try:
        data = json.loads(text) if text else None
    except ValueError:
        return None
    return data if isinstance(data, dict) and isinstance(data.get("url"), str) else None


def _path(url: str) -> str:
    return unquote(urlparse(url).path)


def origin() -> tuple[str, str]:
    """Where the bench was installed from: (kind, where) with kind 'git' (where: the URL at the installed commit),
    'editable' or 'folder' (a local path), 'archive' (a wheel's or sdist's URL), 'index' (PyPI or the index pip
    was given; where: the version) or 'clone' (the bench runs from a clone, installed editable or not; where: its
    path: a clone's own pmsm_hil_bench.egg-info, found first from its folder, has no direct_url.json)."""
    if not INSTALLED:
        return "clone", str(PACKAGE.parent)
    try:
        dist = importlib.metadata.distribution(DIST)
    except importlib.metadata.PackageNotFoundError:  # imported from a copy pip did not install
        return "folder", str(PACKAGE.parent)
    info = _direct_url(dist)
    if info is None:
        return "index", dist.version
    url = info["url"]
    vcs = info.get("vcs_info")
    if isinstance(vcs, dict):
        kind = str(vcs.get("vcs", "git"))
        at = vcs.get("commit_id") or vcs.get("requested_revision")
        where = (url if url.startswith(kind + "+") else f"{kind}+{url}") + (f"@{at}" if at else "")
        if info.get("subdirectory"):
            where += f"#subdirectory={info['subdirectory']}"
        return kind, where
    dir_info = info.get("dir_info")
    if isinstance(dir_info, dict):
        return ("editable" if dir_info.get("editable") else "folder"), _path(url)
    return "archive", url


def describe_origin() -> str:
    """The origin in words (bench doctor): 'git+https://...@<commit>', '/path (a clone)', 'an index (...), 0.1.0'."""
    kind, where = origin()
    if kind == "index":
        return f"an index (PyPI or the one pip was given), version {where}"
    named = {"clone": "a clone", "editable": "an editable install", "folder": "a folder"}
    return f"{where} ({named[kind]})" if kind in named else where


def requirement(extra: str = "") -> list[str]:
    """pip's arguments that add `extra` to the bench from where it came (no extra: the bench with its own
    dependencies), the installed numpy pinned."""
    kind, where = origin()
    ex = f"[{extra}]" if extra else ""
    if kind in ("editable", "clone"):
        args = ["-e", f"{where}{ex}"]
    elif kind == "folder":
        args = [f"{where}{ex}"]
    elif kind == "index":
        args = [f"{DIST}{ex}=={where}"]
    else:  # a VCS URL or an archive
        args = [f"{DIST}{ex} @ {where}"]
    try:
        args.append(f"numpy=={importlib.metadata.version('numpy')}")
    except importlib.metadata.PackageNotFoundError:
        pass
    return args


def install_command(extra: str = "") -> str:
    """The shell line that installs `extra` (or the bench's own dependencies) into this interpreter's environment."""
    return shlex.join([sys.executable, "-m", "pip", "install", *requirement(extra)])


def missing_extra(extra: str, what: str, why: str = "") -> str:
    """'<what> needs the package's [extra] extra (<why>): <install_command(extra)>'."""
    return f"{what} needs the package's [{extra}] extra ({why or 'not installed'}): {install_command(extra)}"


def lacking(extra: str) -> str | None:
    """The first module of the extra that is not importable here, or None."""
    return next((m for m in EXTRAS[extra] if importlib.util.find_spec(m) is None), None)
