"""Lockstep over a real vcan0: ONE VM boot (or the host's vcan0 if it has one) runs the real loop
(the run pipeline's bus half, `capture_to_log`: C nodes, the Python master, candump) beside
lockstep_floor (the same frames between two C processes, no stack), and a longer run whose
every frame is checked from the SYNC counters.

Inside the VM `python -m bench.tools.perf --inside-vm --out FILE` runs (`inside_vm`); the host
decodes the recorded candump logs with the run pipeline's own reader and decoder
(bench.run.record.canlog.read_frames, bench.run.pipeline.Pipeline): Python in the VM is ~50x slower.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.paths import REPO, binary
from bench.tools.perf.common import PERF_DIR, TARGET_LONG_PERIODS, TARGET_VCAN_RATIO

FLOOR_RE = (
    r"periods (\d+) frames_per_period (\d+) wall_s ([\d.]+) periods_per_s ([\d.]+) "
    r"rtt_us mean ([\d.]+) min ([\d.]+) median ([\d.]+) p99 ([\d.]+) max ([\d.]+)"
)


# ---------------------------------------------------------------------- inside the VM
def _floor(iface: str, periods: int, extra: int, record: Path | None) -> dict[str, Any]:
    import re

    exe = str(binary("lockstep_floor"))
    rec = None
    fh = None
    if record is not None:
        fh = open(record, "wb")  # noqa: SIM115 - closed below
        rec = subprocess.Popen(["candump", "-L", "-r", str(8 << 20), iface], stdout=fh, stderr=subprocess.DEVNULL)
        time.sleep(0.3)
    drive = subprocess.Popen(
        [exe, "drive", iface, str(periods), str(extra)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        assert drive.stdout is not None
        if drive.stdout.readline().strip() != "ready":
            raise RuntimeError("lockstep_floor drive did not start")
        plant = subprocess.run(
            [exe, "plant", iface, str(periods), str(extra)], capture_output=True, text=True, timeout=600
        )
        drive_out, _ = drive.communicate(timeout=30)
    finally:
        if drive.poll() is None:
            drive.kill()
        if rec is not None:
            time.sleep(0.3)
            rec.terminate()
            rec.wait(timeout=10)
        if fh is not None:
            fh.close()
    m = re.search(FLOOR_RE, plant.stdout)
    if plant.returncode != 0 or drive.returncode != 0 or not m:
        raise RuntimeError(
            f"lockstep_floor failed: plant rc {plant.returncode} {plant.stdout}{plant.stderr}; "
            f"drive rc {drive.returncode} {drive_out}"
        )
    res: dict[str, Any] = {
        "periods": int(m[1]),
        "frames_per_period": int(m[2]),
        "wall_s": float(m[3]),
        "periods_per_s": float(m[4]),
        "rtt_us": {
            "mean": float(m[5]),
            "min": float(m[6]),
            "median": float(m[7]),
            "p99": float(m[8]),
            "max": float(m[9]),
        },
        "recorder": record is not None,
    }
    if record is not None:
        with open(record, "rb") as f:
            res["frames_recorded"] = sum(1 for _ in f)
        res["frames_expected"] = int(m[1]) * int(m[2])
        record.unlink()
    return res


def _capture(sc: Any, iface: str, keep: Path) -> dict[str, Any]:
    """The bus half of `bench run` (bench.run.pipeline.capture_to_log: nodes, master, candump's
    log into `keep`); the host decodes the log."""
    from bench.run import RunOptions, capture_to_log

    if keep.exists():
        shutil.rmtree(keep)
    keep.mkdir(parents=True)
    t0 = time.monotonic()
    run_wall, stopped, _ = capture_to_log(sc, RunOptions(bus=iface, out=keep))
    if stopped:
        raise RuntimeError(f"the perf run stopped early: {stopped['message']}")
    wall = time.monotonic() - t0
    meta = {"periods": sc.periods, "run_wall_s": run_wall}
    (keep / "perf_capture.json").write_text(json.dumps(meta))
    return {
        **meta,
        "wall_s": wall,
        "periods_per_s": sc.periods / run_wall if run_wall > 0 else None,
        "dir": str(keep.relative_to(REPO)),
    }


def _unrecorded(sc: Any, iface: str) -> dict[str, Any]:
    """The same loop with no recorder at all (what RunOptions(record=False) means over a bus)."""
    from bench.run import RunOptions, Session

    sess = Session(sc, RunOptions(bus=iface, record=False))
    t0 = time.monotonic()
    try:
        sess.open()
        sess.reset_nodes()
        sess.configure()
        run_wall = sess.run()
        st = sess.statuses()
    finally:
        sess.close()
    return {
        "periods": sc.periods,
        "run_wall_s": run_wall,
        "wall_s": time.monotonic() - t0,
        "periods_per_s": sc.periods / run_wall if run_wall > 0 else None,
        "counters": {
            "plant_missed_commands": st.get("plant.Run control.missed_commands"),
            "drive_current_steps": st.get("drive.Drive status.current_steps"),
        },
    }


def inside_vm(args: argparse.Namespace) -> int:
    """Runs next to a real vcan0 (in the VM): floors and real loop, results to args.out (JSON)."""
    from bench.scenario import load

    iface = "vcan0"
    n = args.lockstep_periods
    res: dict[str, Any] = {"kernel": platform.release(), "logical_cpus": os.cpu_count(), "iface": iface}
    tmp = Path(tempfile.mkdtemp(prefix="bench-perf-"))
    t_start = time.monotonic()

    def step(name: str, fn: Any) -> None:
        t0 = time.monotonic()
        try:
            res[name] = fn()
        except Exception as exc:  # noqa: BLE001 - reported to the host
            res[name] = {"error": f"{type(exc).__name__}: {exc}"}
        print(f"bench perf (vm): {name} done in {time.monotonic() - t0:.1f} s", flush=True)

    step("floor_4", lambda: _floor(iface, n, 0, None))
    step("floor_6", lambda: _floor(iface, n, 2, None))
    step("floor_6_recorded", lambda: _floor(iface, n, 2, tmp / "floor.log"))

    scenario = REPO / "scenarios" / "you2019_step.toml"
    base = load(scenario, [f"scenario.periods={n}"])
    step("lockstep", lambda: _capture(base, iface, PERF_DIR / "vm_lockstep"))
    step("lockstep_unrecorded", lambda: _unrecorded(base, iface))
    rate = (res["lockstep"].get("periods_per_s") or 0) if isinstance(res.get("lockstep"), dict) else 0
    long_n = max(1000, int(min(TARGET_LONG_PERIODS, max(n, rate * args.long_budget_s)) // 1000 * 1000))
    res["long_choice"] = {
        "periods": long_n,
        "budget_s": args.long_budget_s,
        "measured_rate": rate,
        "target_periods": TARGET_LONG_PERIODS,
    }
    long_sc = load(scenario, [f"scenario.periods={long_n}", "scenario.name=you2019-step-long"])
    step("long", lambda: _capture(long_sc, iface, PERF_DIR / "vm_long"))
    shutil.rmtree(tmp, ignore_errors=True)
    res["vm_helper_wall_s"] = time.monotonic() - t_start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2))
    return 0


# ---------------------------------------------------------------------- host side
class _FrameCount:
    """A frame sink of the Pipeline: frames per COB-ID, and frames that came in the log after a
    frame with a later kernel time stamp (candump's log order is the order frames reached its
    socket; on a 2-CPU vcan a frame sent on one CPU can be queued after a later one from the other)."""

    def __init__(self) -> None:
        self.by_cob = np.zeros(2048, dtype=np.int64)
        self.late = 0
        self._max_t = 0

    def write(self, frames: np.ndarray) -> None:
        self.by_cob += np.bincount(frames["cob_id"], minlength=2048)[:2048]
        t = frames["t_us"].astype(np.int64)
        if len(t) == 0:
            return
        before = np.maximum.accumulate(np.concatenate([[self._max_t], t[:-1]]))  # latest stamp before each
        self.late += int((t < before).sum())
        self._max_t = max(int(before[-1]), int(t[-1]))

    def close(self) -> None:
        pass


def recorder_check(d: Path) -> dict[str, Any]:
    """Every frame of a recorded lockstep run, checked: decoded in kernel time-stamp order (as
    `bench run` and `bench replay` do) and in candump's log order, SYNC-counter gaps, missing
    measurements and commands, per COB-ID counts against what the periods should have sent."""
    from bench.run import HOLD_TPDO, Pipeline, read_frames, replay_log

    meta = json.loads((d / "perf_capture.json").read_text())
    periods = int(meta["periods"])
    log = d / "candump.log"
    count = _FrameCount()
    pipe = Pipeline(None, None, frame_sinks=[count])  # the EDS's node-IDs
    for chunk in read_frames(log):
        pipe.feed(chunk)
    in_log_order = pipe.finish("log order", "vcan0").summary["bus_stats"]
    res = replay_log(log)
    bs = res.summary["bus_stats"]
    layout = pipe.dec.layout
    if layout is None:
        raise RuntimeError(f"{log}: no SYNC recorded")
    # One frame per period each: the SYNC and every PDO but the plant's hold announcement (sent once
    # per run segment, bench/run/loop/session.py).
    per_period = [p.cob_id for p in layout.pdos if not (p.node == "plant" and p.pdo == f"TPDO{HOLD_TPDO}")]
    cobs = [layout.sync_cob_id, *per_period]
    keys = ("sync_counter_gaps", "missing_measurements", "missing_commands", "sample_index_mismatches")
    return {
        "periods_expected": periods,
        "syncs_recorded": int(res.summary["periods"]),
        "frames_total": int(bs["frames"]),
        "loop_frames_recorded": int(sum(count.by_cob[c] for c in cobs)),
        "loop_frames_expected": periods * len(cobs),
        "frames_per_period": {
            "pdos_plus_sync": len(cobs),
            "by_cob_id": {f"0x{c:03X}": int(count.by_cob[c]) for c in cobs},
        },
        "continuity": {k: int(bs[k]) for k in keys},
        "continuity_in_log_order": {k: int(in_log_order[k]) for k in keys},
        "frames_out_of_time_order_in_log": count.late,
        "plant_missed_commands": bs["plant_missed_commands"],
        "lost_frames": int(bs["lost_frames"]) + max(0, periods - int(res.summary["periods"])),
    }


def vcan(args: argparse.Namespace) -> dict[str, Any]:
    from bench.canbus import host_has_vcan
    from bench.run import VmOptions, run_in_vm

    out = PERF_DIR / "vm.json"
    out.unlink(missing_ok=True)
    cmd = [
        sys.executable,
        "-m",
        "bench.tools.perf",
        "--inside-vm",
        "--out",
        str(out),
        "--lockstep-periods",
        str(args.lockstep_periods),
        "--long-budget-s",
        str(args.long_budget_s),
    ]
    PERF_DIR.mkdir(parents=True, exist_ok=True)
    console = PERF_DIR / "vm_console.log"
    t0 = time.monotonic()
    where = "host vcan0" if host_has_vcan("vcan0") else "virtme-ng VM"
    with open(console, "w") as fh:
        if where == "host vcan0":
            rc = subprocess.call(cmd, cwd=REPO, stdout=fh, stderr=subprocess.STDOUT)
        else:
            rc = run_in_vm(cmd, VmOptions(timeout_s=600), cwd=REPO, stdout=fh)
    res: dict[str, Any] = {
        "where": where,
        "wall_s_including_boot": time.monotonic() - t0,
        "console_log": str(console.relative_to(REPO)),
    }
    if rc != 0 or not out.exists():
        res["error"] = f"the vcan helper failed (status {rc}); see {console}"
        return res
    res.update(json.loads(out.read_text()))
    lock = res.get("lockstep", {})
    for key in ("floor_4", "floor_6", "floor_6_recorded"):
        fl = res.get(key, {})
        if lock.get("periods_per_s") and fl.get("periods_per_s"):
            fl["real_over_floor"] = lock["periods_per_s"] / fl["periods_per_s"]
    res["target_ratio"] = TARGET_VCAN_RATIO
    for key in ("lockstep", "long"):
        part = res.get(key, {})
        if part.get("dir"):
            try:
                part["recorder"] = recorder_check(REPO / part["dir"])
            except Exception as exc:  # noqa: BLE001
                part["recorder"] = {"error": f"{type(exc).__name__}: {exc}"}
    return res
