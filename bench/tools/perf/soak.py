"""`bench perf` soak: 10^6 periods in lockstep over vcan0 with the recorder, as `bench run` runs them (one
VM boot on hosts without CAN); every frame checked on the host (SYNC counters, sample indices, one frame
per PDO per period: recorder_check) and the resident memory of every process of the run sampled once a
second (plant_node, drive_node, candump, the master's Python process): flat, or by how much it grew.

Inside the VM: `python -m bench.tools.perf.soak --out FILE --periods N`."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.paths import REPO
from bench.tools.perf.common import PERF_DIR

SOAK_PERIODS = 1_000_000
WATCH = ("plant_node", "drive_node", "candump")


def _rss_kB(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def _pids() -> dict[str, int]:
    out = {"master (python)": os.getpid()}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            exe = (d / "cmdline").read_bytes().split(b"\0")[0].decode(errors="replace")
        except OSError:
            continue
        base = os.path.basename(exe)
        if base in WATCH and base not in out:
            out[base] = int(d.name)
    return out


class RssSampler(threading.Thread):
    def __init__(self, every_s: float = 1.0) -> None:
        super().__init__(daemon=True, name="soak-rss")
        self.every_s = every_s
        self.samples: dict[str, list[tuple[float, int]]] = {}
        self._halt = threading.Event()
        self.t0 = time.monotonic()

    def run(self) -> None:
        while not self._halt.wait(self.every_s):
            t = time.monotonic() - self.t0
            for name, pid in _pids().items():
                kb = _rss_kB(pid)
                if kb is not None:
                    self.samples.setdefault(name, []).append((t, kb))

    def stop(self) -> None:
        self._halt.set()
        self.join()


def memory_verdict(samples: list[tuple[float, int]]) -> dict[str, Any]:
    """The resident memory over the run: after the first tenth (start-up), its first, last and largest
    value and a linear fit's growth per minute; flat when it grew by less than 1 % (or 256 kB)."""
    if len(samples) < 4:
        return {"samples": len(samples)}
    t = np.array([s[0] for s in samples])
    kb = np.array([s[1] for s in samples], dtype=np.float64)
    keep = t >= t[0] + 0.1 * (t[-1] - t[0])
    t, kb = t[keep], kb[keep]
    slope = float(np.polyfit(t, kb, 1)[0]) * 60.0 if len(t) >= 2 else 0.0
    grew = float(kb[-1] - kb[0])
    return {
        "samples": int(keep.sum()),
        "rss_first_kB": int(kb[0]),
        "rss_last_kB": int(kb[-1]),
        "rss_max_kB": int(kb.max()),
        "growth_kB": grew,
        "slope_kB_per_min": slope,
        "flat": bool(grew < max(256.0, 0.01 * kb[0])),
    }


def inside(periods: int, out: Path) -> int:
    from bench.run import RunOptions, capture_to_log
    from bench.scenario import load

    keep = PERF_DIR / "vm_soak"
    if keep.exists():
        shutil.rmtree(keep)
    keep.mkdir(parents=True)
    sc = load(REPO / "scenarios" / "you2019_step.toml", [f"scenario.periods={periods}", "scenario.name=soak"])
    sampler = RssSampler()
    sampler.start()
    t0 = time.monotonic()
    try:
        run_wall, stopped, _ = capture_to_log(sc, RunOptions(bus="vcan0", out=keep))
    finally:
        sampler.stop()
    (keep / "perf_capture.json").write_text(json.dumps({"periods": periods, "run_wall_s": run_wall}))
    res = {
        "periods": periods,
        "run_wall_s": run_wall,
        "wall_s": time.monotonic() - t0,
        "periods_per_s": periods / run_wall if run_wall else None,
        "stopped": stopped,
        "dir": str(keep.relative_to(REPO)),
        "memory": {name: memory_verdict(s) for name, s in sampler.samples.items()},
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2))
    return 0


def soak(periods: int = SOAK_PERIODS) -> dict[str, Any]:
    """Host side: the run inside the VM (or on the host's vcan0), then every frame of its log checked."""
    from bench.canbus import host_has_vcan
    from bench.run import VmOptions, run_in_vm
    from bench.tools.perf.vcan import recorder_check

    out = PERF_DIR / "soak.json"
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "bench.tools.perf.soak", "--out", str(out), "--periods", str(periods)]
    console = PERF_DIR / "soak_console.log"
    PERF_DIR.mkdir(parents=True, exist_ok=True)
    where = "host vcan0" if host_has_vcan("vcan0") else "virtme-ng VM"
    t0 = time.monotonic()
    with open(console, "w") as fh:
        if where == "host vcan0":
            rc = subprocess.call(cmd, cwd=REPO, stdout=fh, stderr=subprocess.STDOUT)
        else:
            rc = run_in_vm(cmd, VmOptions(timeout_s=3600), cwd=REPO, stdout=fh)
    res: dict[str, Any] = {"where": where, "wall_s_including_boot": time.monotonic() - t0}
    if rc != 0 or not out.exists():
        res["error"] = f"the soak run failed (status {rc}); see {console.relative_to(REPO)}"
        return res
    res.update(json.loads(out.read_text()))
    d = REPO / res["dir"]
    res["recorder"] = recorder_check(d)
    res["log_MB"] = (d / "candump.log").stat().st_size / 1e6
    shutil.rmtree(d, ignore_errors=True)  # hundreds of MB: the figures are kept, the log is not
    return res


def main() -> int:
    p = argparse.ArgumentParser(prog="python -m bench.tools.perf.soak")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--periods", type=int, default=SOAK_PERIODS)
    a = p.parse_args()
    return inside(a.periods, a.out)


if __name__ == "__main__":
    sys.exit(main())


def format_soak(r: dict[str, Any], L: Any) -> None:
    """The soak section of the report (L: report._Lines)."""
    s = L.sec(r, "soak", "soak: 10^6 periods over vcan0 with the recorder")
    if s is None:
        return
    rec = s.get("recorder", {})
    L.append(
        f"  {s['periods']:,} periods in {s['run_wall_s']:.0f} s ({s['periods_per_s']:,.0f} periods/s, {s['where']}); "
        f"log {s.get('log_MB', 0):.0f} MB"
    )
    cont = rec.get("continuity", {})
    L.append(
        f"  frames: {rec.get('loop_frames_recorded', 0):,} of {rec.get('loop_frames_expected', 0):,} loop frames, "
        f"lost {rec.get('lost_frames')}, SYNC-counter gaps {cont.get('sync_counter_gaps')}, sample-index "
        f"mismatches {cont.get('sample_index_mismatches')}, plant missed {rec.get('plant_missed_commands')}"
    )
    for name, m in s.get("memory", {}).items():
        if "rss_first_kB" not in m:
            continue
        L.append(
            f"  {name:<18} RSS {m['rss_first_kB'] / 1024:7.1f} -> {m['rss_last_kB'] / 1024:7.1f} MiB (max "
            f"{m['rss_max_kB'] / 1024:.1f}), {m['slope_kB_per_min']:+.0f} kB/min: {'flat' if m['flat'] else 'GROWS'}"
        )
