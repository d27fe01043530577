"""What every perf section shares: subprocess helpers (with the child's own peak RSS), the
section wrapper, the machine description and the targets."""

from __future__ import annotations

import contextlib
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.paths import BUILD

PERF_DIR = BUILD / "perf"

# Targets (reported beside the measurements, never asserted).
TARGET_PLANT_MPS = 10.0
TARGET_LOOP_MPS = 5.0
TARGET_VCAN_RATIO = 0.8
TARGET_LONG_PERIODS = 100_000

# The vcan section's sizes (inside the VM).
VM_LOCKSTEP_PERIODS = 5_000
VM_LONG_BUDGET_S = 60.0

# The realtime section's sizes: periods of each real-time run (and cyclictest's loops), and the periods Ts in us.
REALTIME_PERIODS = 1_000_000
REALTIME_QUICK_PERIODS = 20_000
REALTIME_TS_US = (100.0, 55.0)


def run(argv: list[str], timeout: float = 300.0, **kw: Any) -> str:
    r = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, **kw)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed ({r.returncode}): {r.stdout}{r.stderr}")
    return r.stdout


def first_line(argv: list[str]) -> str | None:
    try:
        r = subprocess.run(argv, capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired):
        return None
    text = (r.stdout or r.stderr).strip()
    return text.splitlines()[0] if text else None


def section(fn: Any, *a: Any) -> dict[str, Any]:
    """Run one section; a failure is reported in the section, never aborts the others."""
    t0 = time.monotonic()
    try:
        res = fn(*a)
    except Exception as exc:  # noqa: BLE001 - reported, the other sections still run
        res = {"error": f"{type(exc).__name__}: {exc}"}
    res["section_wall_s"] = round(time.monotonic() - t0, 2)
    return res


def statm_pages() -> tuple[int, int]:
    size, res = Path("/proc/self/statm").read_text().split()[:2]
    return int(size), int(res)


@dataclass
class Measured:
    """One child process, timed from the outside: what a user waits for and the memory it took."""

    returncode: int
    wall_s: float
    peak_rss_kB: int  # ru_maxrss of that process and the descendants it waited for (wait4)
    stdout: str
    stderr: str

    def check(self, what: str) -> Measured:
        if self.returncode != 0:
            tail = "\n".join((self.stderr or self.stdout).strip().splitlines()[-8:])
            raise RuntimeError(f"{what} failed (status {self.returncode}): {tail}")
        return self


# A small launcher between this process and the measured one. Peak RSS (ru_maxrss) carries over
# fork and exec on Linux: a child spawned straight from this process reports at least this process's
# own high-water mark (subprocess's vfork lends it our address space until exec, and exec keeps the
# larger of the old and new marks). Spawned from a fresh small interpreter, the child starts from that
# interpreter's mark (~10 MB), like a command typed in a shell; wait4 gives its rusage alone.
_LAUNCHER = r"""
import json, os, subprocess, sys, time
out, err, res = sys.argv[1:4]
with open(out, "wb") as o, open(err, "wb") as e:
    t0 = time.perf_counter()
    p = subprocess.Popen(sys.argv[4:], stdout=o, stderr=e, stdin=subprocess.DEVNULL)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
with open(res, "w") as r:
    json.dump({"wall_s": wall, "returncode": os.waitstatus_to_exitcode(status), "maxrss_kB": ru.ru_maxrss}, r)
"""


def measure(
    argv: list[str], timeout: float = 600.0, cwd: Path | None = None, env: dict[str, str] | None = None
) -> Measured:
    """Run argv to its end, as a user would: wall time from spawn to reaping and the peak RSS of
    that process alone (and of the children it waited for), through _LAUNCHER."""
    import json
    import signal

    with tempfile.TemporaryDirectory(prefix="bench-perf-measure-") as td:
        out, err, res = (Path(td) / n for n in ("stdout", "stderr", "result.json"))
        launcher = subprocess.Popen(
            [sys.executable, "-c", _LAUNCHER, str(out), str(err), str(res), *argv],
            stdin=subprocess.DEVNULL,
            cwd=cwd,
            env=env,
            start_new_session=True,
        )
        try:
            launcher.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(launcher.pid, signal.SIGKILL)
            launcher.wait()
            raise RuntimeError(f"{' '.join(argv)}: no end after {timeout:.0f} s") from None
        if launcher.returncode != 0 or not res.exists():
            raise RuntimeError(
                f"could not run {' '.join(argv)} (launcher status {launcher.returncode}): "
                f"{err.read_text(errors='replace') if err.exists() else ''}"
            )
        r = json.loads(res.read_text())
        return Measured(
            int(r["returncode"]),
            float(r["wall_s"]),
            int(r["maxrss_kB"]),
            out.read_text(errors="replace"),
            err.read_text(errors="replace"),
        )


def stats(values: list[float]) -> dict[str, Any]:
    v = sorted(values)
    n = len(v)
    med = v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])
    return {"n": n, "min": v[0], "median": med, "max": v[-1], "all": values}


def machine() -> dict[str, Any]:
    model = None
    physical: set[tuple[str, str]] = set()
    phys_id = "0"
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, val = line.partition(":")
            key, val = key.strip(), val.strip()
            if key == "model name" and model is None:
                model = val
            elif key == "physical id":
                phys_id = val
            elif key == "core id":
                physical.add((phys_id, val))
    return {
        "cpu_model": model,
        "logical_cpus": os.cpu_count(),
        "cores": len(physical) or None,
        "kernel": f"{platform.system()} {platform.release()} {platform.version()}",
        "machine": platform.machine(),
        "gcc": first_line(["gcc", "--version"]),
        "arm_none_eabi_gcc": first_line(["arm-none-eabi-gcc", "--version"]),
        "clang": first_line(["clang", "--version"]),
        "valgrind": first_line(["valgrind", "--version"]),
        "python": platform.python_version(),
        "make_opt": "-O2 -g (Makefile OPT)",
    }


# Yao 2020's own execution times on its 150 MHz DSP: the proposed R/L identification against the RLS baseline
YAO2020_DSP_US = {"clock_MHz": 150.0, "proposed": 0.313, "rls": 18.9}
