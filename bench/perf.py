"""`bench perf`: every performance figure of the bench in one run, with the machine.

Sections (each labelled in the output; timings are reported, never asserted):

* machine          CPU model, cores, kernel, compilers
* plant core       build/bin/plant_perf: ns/period per option set (target >= 10 M periods/s)
* closed loop      bare cores in-process (plant_sample -> drive_current_step -> plant_step,
                   libhil.so hil_core_loop_ns) and the direct mode (both node apps and the
                   CANopen slave on the in-process bus, bench.direct.Hil) (target >= 5 M periods/s)
* memory           resident memory of the direct mode over 10^6 periods (/proc/self/statm)
* firmware         build/bin/drive_perf ns per step, and instructions per step under
                   valgrind --tool=callgrind (difference of two step counts: repeatable)
* cortex-m4f       firmware_shim/core/*.c cross-compiled with arm-none-eabi-gcc, sizes
* canopen          build/bin/co_perf ns per frame
* vcan             ONE VM boot (or the host's vcan0 if it has one): the real lockstep loop
                   (bench.runner.capture) next to lockstep_floor (same frames, no stack),
                   and a longer run whose every frame is checked from the SYNC counters.

`bench perf --json` prints the same as JSON; `--quick` skips the vcan part.
Inside the VM the helper `python -m bench.perf --inside-vm --out FILE` runs; the host
decodes the recorded candump logs (Python in the VM is ~50x slower).
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from .paths import BUILD, REPO, binary

PERF_DIR = BUILD / "perf"
ARM_FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-O2", "-Wall", "-Wextra",
             "-Werror", "-std=c11", "-c"]
TARGET_PLANT_MPS = 10.0
TARGET_LOOP_MPS = 5.0
TARGET_VCAN_RATIO = 0.8
TARGET_LONG_PERIODS = 100_000

# Sizes of the runs (kept short: 2 shared cores, the whole command within ~3 minutes).
PLANT_PERF_PERIODS = 2_000_000
CORE_LOOP_PERIODS = 2_000_000
DIRECT_PERIODS = 1_000_000
DRIVE_PERF_STEPS = 1_000_000
CALLGRIND_STEPS = (20_000, 40_000)
CO_PERF_FRAMES = 1_000_000
VM_LOCKSTEP_PERIODS = 5_000
VM_LONG_BUDGET_S = 60.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--quick", action="store_true", help="skip the vcan part (no VM boot)")
    p.add_argument("--lockstep-periods", type=int, default=VM_LOCKSTEP_PERIODS,
                   help=f"periods of the real lockstep loop and of the floor over vcan (default {VM_LOCKSTEP_PERIODS})")
    p.add_argument("--long-budget-s", type=float, default=VM_LONG_BUDGET_S,
                   help="wall-time budget of the long frame-continuity run in the VM "
                        f"(periods = measured rate x budget, at most {TARGET_LONG_PERIODS}; default {VM_LONG_BUDGET_S:.0f})")
    p.add_argument("--save", type=Path, default=PERF_DIR / "perf.json", help="also write the JSON here")
    p.add_argument("--inside-vm", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--out", type=Path, default=None, help=argparse.SUPPRESS)


# ---------------------------------------------------------------------- helpers
def _run(argv: list[str], timeout: float = 300.0, **kw: Any) -> str:
    r = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, **kw)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed ({r.returncode}): {r.stdout}{r.stderr}")
    return r.stdout


def _first_line(argv: list[str]) -> str | None:
    try:
        r = subprocess.run(argv, capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired):
        return None
    text = (r.stdout or r.stderr).strip()
    return text.splitlines()[0] if text else None


def _section(fn: Any, *a: Any) -> dict[str, Any]:
    """Run one section; a failure is reported in the section, never aborts the others."""
    t0 = time.monotonic()
    try:
        res = fn(*a)
    except Exception as exc:  # noqa: BLE001 - reported, the other sections still run
        res = {"error": f"{type(exc).__name__}: {exc}"}
    res["section_wall_s"] = round(time.monotonic() - t0, 2)
    return res


def _statm_pages() -> tuple[int, int]:
    size, res = Path("/proc/self/statm").read_text().split()[:2]
    return int(size), int(res)


# ---------------------------------------------------------------------- machine
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
        "gcc": _first_line(["gcc", "--version"]),
        "arm_none_eabi_gcc": _first_line(["arm-none-eabi-gcc", "--version"]),
        "clang": _first_line(["clang", "--version"]),
        "valgrind": _first_line(["valgrind", "--version"]),
        "python": platform.python_version(),
        "make_opt": "-O2 -g (Makefile OPT)",
    }


# ---------------------------------------------------------------------- plant core
PLANT_RE = re.compile(r"^(?P<label>.+?)\s+step:\s+(?P<step>[\d.]+) ns/period.*?sample\+step:\s+(?P<both>[\d.]+) ns"
                      r".*\[rk4 substeps (?P<sub>\d+)\]")


def plant_core() -> dict[str, Any]:
    out = _run([str(binary("plant_perf")), str(PLANT_PERF_PERIODS)])
    cases = []
    for line in out.splitlines():
        m = PLANT_RE.match(line)
        if m:
            step, both = float(m["step"]), float(m["both"])
            cases.append({"case": m["label"].strip(), "step_ns": step, "step_Mps": 1e3 / step,
                          "sample_step_ns": both, "sample_step_Mps": 1e3 / both, "rk4_substeps": int(m["sub"]),
                          "meets_target": 1e3 / both >= TARGET_PLANT_MPS})
    mem = re.search(r"after warm-up (\d+), after 10\^6 periods (\d+), after 2\*10\^6 periods (\d+) \(growth (-?\d+)\)",
                    out)
    res: dict[str, Any] = {"periods_per_case": PLANT_PERF_PERIODS, "target_Mps": TARGET_PLANT_MPS, "cases": cases,
                           "metric": "sample+step (what one SYNC costs the plant)"}
    if mem:
        res["rss_pages"] = {"warm": int(mem[1]), "after_1e6": int(mem[2]), "after_2e6": int(mem[3]),
                            "growth": int(mem[4])}
    if not cases:
        raise RuntimeError(f"unexpected plant_perf output: {out!r}")
    return res


# ---------------------------------------------------------------------- closed loop in-process
def closed_loop() -> dict[str, Any]:
    import canopen

    from .direct import DirectBus, Hil
    from .eds import eds_path

    # Bare cores, no CANopen.
    lib = ctypes.CDLL(str(BUILD / "libhil.so"))
    lib.hil_core_loop_ns.argtypes = [ctypes.c_uint32]
    lib.hil_core_loop_ns.restype = ctypes.c_double
    lib.hil_core_loop_iq_A.restype = ctypes.c_double
    lib.hil_core_loop_ns(CORE_LOOP_PERIODS // 10)  # warm-up
    ns = min(lib.hil_core_loop_ns(CORE_LOOP_PERIODS) for _ in range(2))
    bare = {"periods": CORE_LOOP_PERIODS, "ns_per_period": ns, "Mperiods_per_s": 1e3 / ns,
            "iq_end_A": lib.hil_core_loop_iq_A(), "iq_ref_A": 1.0, "target_Mps": TARGET_LOOP_MPS,
            "meets_target": 1e3 / ns >= TARGET_LOOP_MPS,
            "what": "plant_sample -> drive_current_step -> plant_step, You 2019 ideal, locked rotor, deadbeat"}

    # Direct mode: both node apps + CANopen slave + in-process bus; configured by SDO only
    # for NMT start and the reference (everything else at the EDS defaults).
    hil = Hil()
    net = canopen.Network()
    net.bus = DirectBus(hil)
    net.connect()
    try:
        plant = canopen.RemoteNode(0x10, str(eds_path("plant")))
        drive = canopen.RemoteNode(0x20, str(eds_path("drive")))
        net.add_node(plant)
        net.add_node(drive)
        total = DIRECT_PERIODS * 2 + DIRECT_PERIODS // 10
        plant.sdo["Run control"]["run_periods"].raw = total
        for n in (plant, drive):
            n.nmt.send_command(0x01)
        drive.sdo["References"]["iq_ref_A"].raw = 1.0
        warm = hil.run(DIRECT_PERIODS // 10)
        size0, rss0 = _statm_pages()
        t0 = time.perf_counter()
        ran = hil.run(DIRECT_PERIODS)
        wall = time.perf_counter() - t0
        size1, rss1 = _statm_pages()
        ran2 = hil.run(DIRECT_PERIODS)
        size2, rss2 = _statm_pages()
        steps = drive.sdo["Drive status"]["current_steps"].raw
        missed = plant.sdo["Run control"]["missed_commands"].raw
    finally:
        net.disconnect()
    page_kB = os.sysconf("SC_PAGE_SIZE") / 1024
    direct = {"periods": ran, "wall_s": wall, "ns_per_period": 1e9 * wall / ran, "periods_per_s": ran / wall,
              "Mperiods_per_s": ran / wall / 1e6, "target_Mps": TARGET_LOOP_MPS,
              "meets_target": ran / wall / 1e6 >= TARGET_LOOP_MPS,
              "drive_current_steps": steps, "plant_missed_commands": missed,
              "what": "plant_app + drive_app + CANopen slave on co_membus (libhil.so), 4 frames/period, no recorder"}
    memory = {"periods": ran + ran2, "warm_up_periods": warm, "page_kB": page_kB,
              "rss_pages": {"before": rss0, "after_1e6": rss1, "after_2e6": rss2},
              "vm_size_pages": {"before": size0, "after_1e6": size1, "after_2e6": size2},
              "rss_growth_kB_over_1e6": (rss1 - rss0) * page_kB, "rss_growth_kB_over_2e6": (rss2 - rss0) * page_kB,
              "rss_growth_kB_second_1e6": (rss2 - rss1) * page_kB,
              # Flat: nothing over the second 10^6 periods (the first may still fault in a few
              # rarely used code pages of libm/libhil, which are file-backed and bounded).
              "flat": rss2 == rss1 and rss1 - rss0 <= 4}
    return {"bare_cores": bare, "direct_mode": direct, "memory": memory}


# ---------------------------------------------------------------------- firmware
DRIVE_PERF_KEYS = {"deadbeat current step": "deadbeat_step_ns",
                   "deadbeat + identification step": "deadbeat_ident_step_ns",
                   "PI current step": "pi_step_ns",
                   "gain_id_sample (Eq. 24-27, per call)": "gain_id_sample_ns",
                   "identification update (Eq. 28-32)": "ident_update_ns"}


def _parse_drive_perf(out: str) -> dict[str, float]:
    res: dict[str, float] = {}
    for line in out.splitlines():
        label, _, val = line.partition(":")
        key = DRIVE_PERF_KEYS.get(label.strip())
        if key:
            res[key] = float(val.split()[0])
    return res


def _callgrind(steps: int, tmp: Path) -> dict[str, Any]:
    """Inclusive instruction counts of drive_perf's call sites (from the annotated source of
    drive_perf.c, in call order: deadbeat, deadbeat + identification, PI; then the
    identification average and the per-sample update of bench_average)."""
    cg = tmp / f"callgrind.{steps}"
    _run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}", str(binary("drive_perf")), str(steps)],
         timeout=300)
    ann = _run(["callgrind_annotate", "--inclusive=yes", "--auto=yes", str(cg)], timeout=120)
    total = int(re.search(r"^([\d,]+) \(100\.0%\)\s+PROGRAM TOTALS", ann, re.M)[1].replace(",", ""))  # type: ignore[index]
    sections = re.split(r"^-- Auto-annotated source: ", ann, flags=re.M)
    # A file can appear twice (absolute and relative debug path); take the one with the call sites.
    cands = [s for s in sections[1:] if s.splitlines() and s.splitlines()[0].strip().endswith("drive_perf.c")]
    src = max(cands, key=lambda s: len(re.findall(r"=> \S+:bench \(1x\)", s)), default="")
    bench_calls = [int(m[1].replace(",", "")) for m in re.finditer(r"^\s*([\d,]+) \([\d. ]+%\)\s+=> \S+:bench \(1x\)",
                                                                   src, re.M)]
    avg = re.search(r"^\s*([\d,]+) \([\d. ]+%\)\s+=> \S+:gain_id_average \(", src, re.M)
    smp = re.search(r"^\s*([\d,]+) \([\d. ]+%\)\s+=> \S+:gain_id_sample \(", src, re.M)
    if len(bench_calls) != 3 or not avg or not smp:
        raise RuntimeError("cannot find drive_perf's call sites in callgrind_annotate's output")
    return {"total": total, "deadbeat": bench_calls[0], "deadbeat_ident": bench_calls[1], "pi": bench_calls[2],
            "ident_update": int(avg[1].replace(",", "")), "ident_sample": int(smp[1].replace(",", ""))}


def firmware() -> dict[str, Any]:
    out = _run([str(binary("drive_perf")), str(DRIVE_PERF_STEPS)])
    res: dict[str, Any] = {"steps": DRIVE_PERF_STEPS, "timing_ns": _parse_drive_perf(out)}
    if shutil.which("valgrind") and shutil.which("callgrind_annotate"):
        n1, n2 = CALLGRIND_STEPS
        with tempfile.TemporaryDirectory() as td:
            a, b = _callgrind(n1, Path(td)), _callgrind(n2, Path(td))
        d = n2 - n1
        d_avg = n2 // 8 - n1 // 8
        res["callgrind"] = {
            "step_counts": [n1, n2],
            "method": "Ir(n2) - Ir(n1) over (n2 - n1) steps, inclusive counts of drive_perf's call sites; "
                      "includes drive_perf's own first-order plant and set-point lines (a few instructions)",
            "instructions_per_step": {
                "deadbeat": (b["deadbeat"] - a["deadbeat"]) / d,
                "deadbeat_ident": (b["deadbeat_ident"] - a["deadbeat_ident"]) / d,
                "pi": (b["pi"] - a["pi"]) / d,
                "ident_update": (b["ident_update"] - a["ident_update"]) / d_avg,
                "ident_sample": (b["ident_sample"] - a["ident_sample"]) / (8 * d_avg),
                "whole_program_per_drive_perf_step": (b["total"] - a["total"]) / d,
            },
            "raw": {str(n1): a, str(n2): b},
        }
    else:
        res["callgrind"] = {"error": "valgrind / callgrind_annotate not installed"}
    return res


def _fn_inclusive(steps: int, exe: str, functions: tuple[str, ...], tmp: Path) -> dict[str, int]:
    cg = tmp / f"cg.{exe}.{steps}"
    _run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}", str(binary(exe)), str(steps)], timeout=300)
    ann = _run(["callgrind_annotate", "--inclusive=yes", str(cg)], timeout=120)
    out = {}
    for fn in functions:
        m = re.search(r"^\s*([\d,]+) \([\d. ]+%\)\s+\S+:" + re.escape(fn) + r"\b", ann, re.M)
        if not m:
            raise RuntimeError(f"{fn} not found in callgrind_annotate's output of {exe}")
        out[fn] = int(m[1].replace(",", ""))
    return out


def yao2020_identification_cost() -> dict[str, Any]:
    """Yao 2020 claim 5: instructions per call of the proposed identification update against the RLS
    baseline (the paper, on a 150 MHz DSP: 0.313 us against 18.9 us)."""
    if not (shutil.which("valgrind") and shutil.which("callgrind_annotate")):
        return {"error": "valgrind / callgrind_annotate not installed"}
    fns = ("yao_dpcc_ident_update", "yao_rls_update", "yao_dpcc_step")
    n1, n2 = 10000, 20000
    with tempfile.TemporaryDirectory() as td:
        a = _fn_inclusive(n1, "yao2020_perf", fns, Path(td))
        b = _fn_inclusive(n2, "yao2020_perf", fns, Path(td))
    per = {fn: (b[fn] - a[fn]) / (n2 - n1) for fn in fns}
    return {"step_counts": [n1, n2], "instructions_per_call": per,
            "rls_over_proposed": per["yao_rls_update"] / per["yao_dpcc_ident_update"],
            "paper_us_on_150MHz_DSP": {"proposed": 0.313, "rls": 18.9, "ratio": 18.9 / 0.313}}


def sweep_scaling() -> dict[str, Any]:
    """`bench sweep` on 1 process vs all cores: the same 8-point grid, wall time and speed-up."""
    from .sweep import run_grid

    scenario = REPO / "scenarios" / "you2019_step.toml"
    grid = [("controller.L_hat_ratio", ["0.5", "0.8", "1.0", "1.2"]), ("controller.R_hat_ratio", ["0.5", "1.5"])]
    cores = os.cpu_count() or 1
    walls = {}
    for jobs in sorted({1, cores}):
        t0 = time.monotonic()
        run_grid(scenario, grid, [], jobs, progress=False)
        walls[jobs] = time.monotonic() - t0
    return {"points": 8, "cores": cores, "wall_s": walls, "speedup": walls[1] / walls[cores]}


_RERUN_CHILD = r"""
import json, resource, sys, time
import numpy as np
import rerun as rr
periods, signals, batch, decimate, limit = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
def rss_kB():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4
rec = rr.RecordingStream("bench-perf-live", recording_id="live")
rec.serve_grpc(server_memory_limit=limit)   # the buffer a live viewer is served from
before = rss_kB()
t0 = time.monotonic()
k = np.arange(periods, dtype=np.int64)
sent = 0
for a in range(0, periods, batch):
    sl = slice(a, min(periods, a + batch), decimate)
    times = [rr.TimeColumn("period", sequence=k[sl])]
    for s in range(signals):
        rec.send_columns(f"/sig/{s}", indexes=times, columns=rr.Scalars.columns(scalars=np.sin(k[sl] * 1e-3 * (s + 1))))
    sent += len(k[sl])
rec.flush()
wall = time.monotonic() - t0
print(json.dumps({"rss_before_kB": before, "rss_after_kB": rss_kB(), "peak_rss_kB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "wall_s": wall, "periods_per_s": periods / wall, "samples_sent": sent * signals}))
"""


def rerun_live(periods: int = 1_000_000, signals: int = 16) -> dict[str, Any]:
    """Memory of the live-view buffer (Rerun's gRPC server, what a viewer is served from) for 10^6 periods x
    16 signals, logged with send_columns in batches, at full rate and decimated by 10, with a 1 GiB cap."""
    out = {}
    for decimate in (1, 10):
        r = _run([sys.executable, "-c", _RERUN_CHILD, str(periods), str(signals), "10000", str(decimate), "1GiB"],
                 timeout=600)
        out[f"decimate_{decimate}"] = json.loads(r.strip().splitlines()[-1])
    return {"periods": periods, "signals": signals, "server_memory_limit": "1GiB", **out}


# ---------------------------------------------------------------------- Cortex-M4F
def cortex_m4() -> dict[str, Any]:
    gcc, size = shutil.which("arm-none-eabi-gcc"), shutil.which("arm-none-eabi-size")
    if not gcc or not size:
        raise RuntimeError("arm-none-eabi-gcc not installed (apt-get install gcc-arm-none-eabi)")
    core = REPO / "firmware_shim" / "core"
    objs = []
    with tempfile.TemporaryDirectory() as td:
        for src in sorted(core.glob("*.c")):
            obj = Path(td) / (src.stem + ".o")
            r = subprocess.run([gcc, *ARM_FLAGS, f"-I{core}", str(src), "-o", str(obj)], capture_output=True,
                               text=True, timeout=120)
            if r.returncode != 0:
                raise RuntimeError(f"arm-none-eabi-gcc failed on {src.name}: {r.stderr}")
            objs.append(obj)
        out = _run([size, "-B", *map(str, objs)])
    rows = []
    for line in out.splitlines()[1:]:
        f = line.split()
        if len(f) >= 6:
            rows.append({"object": Path(f[5]).name, "text": int(f[0]), "data": int(f[1]), "bss": int(f[2])})
    total = {k: sum(r[k] for r in rows) for k in ("text", "data", "bss")}
    return {"compiler": _first_line([gcc, "--version"]), "flags": " ".join(ARM_FLAGS), "objects": rows,
            "total": total}


# ---------------------------------------------------------------------- CANopen
def canopen_cost() -> dict[str, Any]:
    out = _run([str(binary("co_perf")), str(CO_PERF_FRAMES)])
    res: dict[str, Any] = {"frames_each": CO_PERF_FRAMES}
    for m in re.finditer(r"^co_perf: (\w+)_ns ([\d.]+)", out, re.M):
        res[f"{m[1]}_ns"] = float(m[2])
    if len(res) < 2:
        raise RuntimeError(f"unexpected co_perf output: {out!r}")
    return res


# ---------------------------------------------------------------------- vcan (inside the VM)
FLOOR_RE = re.compile(r"periods (\d+) frames_per_period (\d+) wall_s ([\d.]+) periods_per_s ([\d.]+) "
                      r"rtt_us mean ([\d.]+) min ([\d.]+) median ([\d.]+) p99 ([\d.]+) max ([\d.]+)")


def _floor(iface: str, periods: int, extra: int, record: Path | None) -> dict[str, Any]:
    exe = str(binary("lockstep_floor"))
    rec = None
    fh = None
    if record is not None:
        fh = open(record, "wb")  # noqa: SIM115 - closed below
        rec = subprocess.Popen(["candump", "-L", "-r", str(8 << 20), iface], stdout=fh, stderr=subprocess.DEVNULL)
        time.sleep(0.3)
    drive = subprocess.Popen([exe, "drive", iface, str(periods), str(extra)], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    try:
        assert drive.stdout is not None
        if drive.stdout.readline().strip() != "ready":
            raise RuntimeError("lockstep_floor drive did not start")
        plant = subprocess.run([exe, "plant", iface, str(periods), str(extra)], capture_output=True, text=True,
                               timeout=600)
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
    m = FLOOR_RE.search(plant.stdout)
    if plant.returncode != 0 or drive.returncode != 0 or not m:
        raise RuntimeError(f"lockstep_floor failed: plant rc {plant.returncode} {plant.stdout}{plant.stderr}; "
                           f"drive rc {drive.returncode} {drive_out}")
    res: dict[str, Any] = {"periods": int(m[1]), "frames_per_period": int(m[2]), "wall_s": float(m[3]),
                           "periods_per_s": float(m[4]),
                           "rtt_us": {"mean": float(m[5]), "min": float(m[6]), "median": float(m[7]),
                                      "p99": float(m[8]), "max": float(m[9])},
                           "recorder": record is not None}
    if record is not None:
        with open(record, "rb") as f:
            res["frames_recorded"] = sum(1 for _ in f)
        res["frames_expected"] = int(m[1]) * int(m[2])
        record.unlink()
    return res


def _vm_capture(sc: Any, iface: str, tmp: Path, keep: Path | None, record: bool = True) -> dict[str, Any]:
    """bench.runner.capture over vcan; candump's log is kept raw (decoded on the host: decoding it
    with python-can inside the VM would take minutes). record=False: no recorder at all."""
    from . import runner

    out = tmp / sc.name
    if out.exists():
        shutil.rmtree(out)
    t0 = time.monotonic()
    cap = runner.capture(sc, runner.RunOptions(bus=iface, out=out, record=record, decode_log=False))
    wall = time.monotonic() - t0
    if keep is not None:
        keep.mkdir(parents=True, exist_ok=True)
        for name in ("candump.log", "layout.json", "capture.json"):
            shutil.copyfile(out / name, keep / name)
    shutil.rmtree(out, ignore_errors=True)
    return {"periods": cap.periods, "run_wall_s": cap.run_wall_s, "wall_s": wall,
            "periods_per_s": cap.periods / cap.run_wall_s if cap.run_wall_s > 0 else None,
            "counters": cap.counters, "dir": str(keep.relative_to(REPO)) if keep else None}


def inside_vm(args: argparse.Namespace) -> int:
    """Runs next to a real vcan0 (in the VM): floors and real loop, results to args.out (JSON)."""
    from . import scenario as scn

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

    base = scn.load(REPO / "scenarios" / "you2019_step.toml")
    base.periods = n
    step("lockstep", lambda: _vm_capture(base, iface, tmp, PERF_DIR / "vm_lockstep"))
    step("lockstep_unrecorded", lambda: _vm_capture(base, iface, tmp, None, record=False))
    rate = (res["lockstep"].get("periods_per_s") or 0) if isinstance(res.get("lockstep"), dict) else 0
    long_n = int(min(TARGET_LONG_PERIODS, max(n, rate * args.long_budget_s)) // 1000 * 1000)
    res["long_choice"] = {"periods": long_n, "budget_s": args.long_budget_s, "measured_rate": rate,
                          "target_periods": TARGET_LONG_PERIODS}
    long_sc = scn.load(REPO / "scenarios" / "you2019_step.toml")
    long_sc.periods = long_n
    long_sc.name = "you2019-step-long"
    step("long", lambda: _vm_capture(long_sc, iface, tmp, PERF_DIR / "vm_long"))
    shutil.rmtree(tmp, ignore_errors=True)
    res["vm_helper_wall_s"] = time.monotonic() - t_start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2))
    return 0


# ---------------------------------------------------------------------- vcan (host side)
def _read_candump(path: Path) -> Any:
    """candump -L log -> the bench's frame array (fast path for long logs)."""
    import numpy as np

    from .direct import FRAME_DTYPE

    lines = path.read_bytes().splitlines()
    arr = np.zeros(len(lines), dtype=FRAME_DTYPE)
    t0 = None
    k = 0
    for line in lines:
        parts = line.split()
        if len(parts) < 3 or b"#" not in parts[2]:
            continue
        ts = float(parts[0][1:-1])
        if t0 is None:
            t0 = ts
        cid, _, data = parts[2].partition(b"#")
        if data[:1] == b"R":  # remote frame
            continue
        raw = bytes.fromhex(data.decode())
        arr[k]["t_us"] = int(round((ts - t0) * 1e6))
        arr[k]["seq"] = k
        arr[k]["cob_id"] = int(cid, 16) & 0x7FF
        arr[k]["dlc"] = len(raw)
        arr[k]["sender"] = 255
        arr[k]["data"][: len(raw)] = np.frombuffer(raw, dtype=np.uint8)
        k += 1
    return arr[:k]


def _continuity(d: Path) -> dict[str, Any]:
    import numpy as np

    from .layout import BusLayout
    from .traces import check_continuity, decode

    cap = json.loads((d / "capture.json").read_text())
    layout = BusLayout.load(d / "layout.json")
    frames = _read_candump(d / "candump.log")
    pp, ts = int(cap["plant"].get("pole_pairs", 1)), float(cap["plant"].get("Ts_s", 1.0))
    refs = [tuple(r) for r in cap["references"]]
    # candump's log order is the order frames reached its socket; on a 2-CPU vcan a frame sent
    # on one CPU can be queued after a later one sent on the other. The kernel time stamps
    # give the bus order: decode in that order (stable sort), and count the log-order artefacts.
    cont_log = check_continuity(decode(frames, layout, pp, ts, refs))  # type: ignore[arg-type]
    order = np.argsort(frames["t_us"], kind="stable")
    reordered = int((order != np.arange(len(order))).sum())
    frames = frames[order]
    tr = decode(frames, layout, pp, ts, refs)  # type: ignore[arg-type]
    cont = check_continuity(tr)
    periods = int(cap["periods"])
    pdo_cobs = [p.cob_id for p in layout.pdos]
    per_cob = {f"0x{c:03X}": int((frames["cob_id"] == c).sum()) for c in [layout.sync_cob_id, *pdo_cobs]}
    loop_frames = int(np.isin(frames["cob_id"], [layout.sync_cob_id, *pdo_cobs]).sum())
    # The drive's synchronous trace TPDOs are sent at SYNC k with the state after step k-1.
    expected = periods * (1 + len(pdo_cobs))
    return {"periods_expected": periods, "syncs_recorded": int(cont["periods"]), "frames_total": int(len(frames)),
            "loop_frames_recorded": loop_frames, "loop_frames_expected": expected,
            "frames_per_period": {"pdos_plus_sync": 1 + len(pdo_cobs), "by_cob_id": per_cob},
            "continuity": cont, "continuity_in_log_order": cont_log, "frames_out_of_time_order_in_log": reordered,
            "lost_frames": cont["sync_counter_gaps"] + cont["missing_measurements"] + cont["missing_commands"]
            + (periods - int(cont["periods"]))}


def vcan(args: argparse.Namespace) -> dict[str, Any]:
    from .canbus import host_has_vcan
    from .vm import VmOptions, run_in_vm

    out = PERF_DIR / "vm.json"
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "bench.perf", "--inside-vm", "--out", str(out), "--lockstep-periods",
           str(args.lockstep_periods), "--long-budget-s", str(args.long_budget_s)]
    PERF_DIR.mkdir(parents=True, exist_ok=True)
    console = PERF_DIR / "vm_console.log"
    t0 = time.monotonic()
    where = "host vcan0" if host_has_vcan("vcan0") else "virtme-ng VM"
    with open(console, "w") as fh:
        if where == "host vcan0":
            rc = subprocess.call(cmd, cwd=REPO, stdout=fh, stderr=subprocess.STDOUT)
        else:
            rc = run_in_vm(cmd, VmOptions(timeout_s=600), cwd=REPO, stdout=fh)
    res: dict[str, Any] = {"where": where, "wall_s_including_boot": time.monotonic() - t0,
                           "console_log": str(console.relative_to(REPO))}
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
        if "dir" in part:
            try:
                part["recorder"] = _continuity(REPO / part["dir"])
            except Exception as exc:  # noqa: BLE001
                part["recorder"] = {"error": f"{type(exc).__name__}: {exc}"}
    return res


# ---------------------------------------------------------------------- report
def _fmt_target(ok: bool | None) -> str:
    return "" if ok is None else ("meets" if ok else "MISSED")


def format_report(r: dict[str, Any]) -> str:
    L: list[str] = []

    def head(title: str) -> None:
        L.append("")
        L.append(f"== {title} " + "=" * max(0, 70 - len(title)))

    def err(sec: dict[str, Any]) -> bool:
        if "error" in sec:
            L.append(f"  ERROR: {sec['error']}")
            return True
        return False

    m = r["machine"]
    head("machine")
    for k in ("cpu_model", "logical_cpus", "cores", "kernel", "gcc", "arm_none_eabi_gcc", "clang", "valgrind",
              "python"):
        L.append(f"  {k:<20} {m.get(k)}")
    L.append(f"  {'command':<20} {r['command']}")

    p = r["plant_core"]
    head(f"plant core (plant_perf, {p.get('periods_per_case', '?')} periods/case; target >= {TARGET_PLANT_MPS:.0f} M periods/s)")
    if not err(p):
        L.append(f"  {'option set':<42}{'step ns':>9}{'M/s':>8}{'sample+step ns':>16}{'M/s':>8}  target")
        for c in p["cases"]:
            L.append(f"  {c['case']:<42}{c['step_ns']:>9.1f}{c['step_Mps']:>8.2f}{c['sample_step_ns']:>16.1f}"
                     f"{c['sample_step_Mps']:>8.2f}  {_fmt_target(c['meets_target'])}")
        if "rss_pages" in p:
            L.append(f"  plant_perf resident pages: {p['rss_pages']}")

    cl = r["closed_loop"]
    head(f"plant + controller in-process (target >= {TARGET_LOOP_MPS:.0f} M periods/s)")
    if not err(cl):
        b, d = cl["bare_cores"], cl["direct_mode"]
        L.append(f"  bare cores (hil_core_loop_ns)        {b['ns_per_period']:8.1f} ns/period  "
                 f"{b['Mperiods_per_s']:6.2f} M periods/s  {_fmt_target(b['meets_target'])}"
                 f"  (iq at end {b['iq_end_A']:.4f} A for 1 A)")
        L.append(f"  direct mode (libhil.so + CANopen)    {d['ns_per_period']:8.1f} ns/period  "
                 f"{d['Mperiods_per_s']:6.2f} M periods/s  {_fmt_target(d['meets_target'])}"
                 f"  ({d['periods']} periods, missed commands {d['plant_missed_commands']})")
        mem = cl["memory"]
        head("resident memory, direct mode (/proc/self/statm)")
        L.append(f"  RSS pages before {mem['rss_pages']['before']}, after 10^6 periods {mem['rss_pages']['after_1e6']}, "
                 f"after 2x10^6 {mem['rss_pages']['after_2e6']}")
        L.append(f"  growth {mem['rss_growth_kB_over_1e6']:.0f} kB over the first 10^6, "
                 f"{mem['rss_growth_kB_second_1e6']:.0f} kB over the second -> {'flat' if mem['flat'] else 'NOT flat'}")

    fw = r["firmware"]
    head("firmware core (drive_perf, host)")
    if not err(fw):
        t = fw["timing_ns"]
        for k, label in (("deadbeat_step_ns", "deadbeat current step"),
                         ("deadbeat_ident_step_ns", "deadbeat + identification step"),
                         ("pi_step_ns", "PI current step"), ("gain_id_sample_ns", "identification sample (per call)"),
                         ("ident_update_ns", "identification update (Eq. 28-32)")):
            if k in t:
                L.append(f"  {label:<40} {t[k]:8.1f} ns")
        cg = fw.get("callgrind", {})
        if "error" in cg:
            L.append(f"  callgrind: {cg['error']}")
        else:
            ips = cg["instructions_per_step"]
            L.append(f"  callgrind instructions (Ir, steps {cg['step_counts'][0]} vs {cg['step_counts'][1]}):")
            for k, label in (("deadbeat", "deadbeat current step"), ("deadbeat_ident", "deadbeat + identification"),
                             ("pi", "PI current step"), ("ident_sample", "identification sample"),
                             ("ident_update", "identification update")):
                L.append(f"    {label:<38} {ips[k]:8.1f} instructions")

    sw = r.get("sweep_scaling")
    head("bench sweep scaling (8 direct runs; target >= 1.8x on 2 cores)")
    if sw and not err(sw):
        w = sw["wall_s"]
        L.append("  " + ", ".join(f"{j} process(es): {t:.1f} s" for j, t in w.items())
                 + f"; speed-up {sw['speedup']:.2f}x on {sw['cores']} cores "
                 + ("meets" if sw["speedup"] >= 1.8 else "MISSED"))

    rl = r.get("rerun_live")
    head("Rerun live view: 10^6 periods x 16 signals into the served (viewer-side) buffer")
    if rl and not err(rl):
        for key in ("decimate_1", "decimate_10"):
            d = rl[key]
            L.append(f"  {key.replace('_', ' ')}: {d['samples_sent']:,} samples in {d['wall_s']:.1f} s "
                     f"({d['periods_per_s']:,.0f} periods/s), RSS +{(d['rss_after_kB'] - d['rss_before_kB']) / 1024:.0f} MiB "
                     f"(peak {d['peak_rss_kB'] / 1024:.0f} MiB), server memory limit {rl['server_memory_limit']}")

    yc = r.get("yao2020_identification")
    head("Yao 2020 identification vs RLS (callgrind, instructions per call)")
    if yc and not err(yc):
        ipc = yc["instructions_per_call"]
        L.append(f"  proposed identification update (yao_dpcc_ident_update)  {ipc['yao_dpcc_ident_update']:8.1f}")
        L.append(f"  RLS baseline update (yao_rls_update, Eq. 46-48)           {ipc['yao_rls_update']:8.1f}")
        L.append(f"  whole DPCC step (yao_dpcc_step)                           {ipc['yao_dpcc_step']:8.1f}")
        L.append(f"  RLS / proposed: {yc['rls_over_proposed']:.1f}x  (paper on a 150 MHz DSP: 0.313 us vs 18.9 us, "
                 f"{yc['paper_us_on_150MHz_DSP']['ratio']:.0f}x)")

    cm = r["cortex_m4"]
    head("Cortex-M4F build of firmware_shim/core (arm-none-eabi-gcc)")
    if not err(cm):
        L.append(f"  {cm['compiler']}; flags: {cm['flags']}")
        L.append(f"  {'object':<26}{'text':>8}{'data':>8}{'bss':>8}")
        for o in cm["objects"]:
            L.append(f"  {o['object']:<26}{o['text']:>8}{o['data']:>8}{o['bss']:>8}")
        tot = cm["total"]
        L.append(f"  {'total':<26}{tot['text']:>8}{tot['data']:>8}{tot['bss']:>8}")

    co = r["canopen"]
    head("CANopen frame handling (co_perf, in-process)")
    if not err(co):
        for k, v in co.items():
            if k.endswith("_ns"):
                L.append(f"  {k[:-3]:<40} {v:8.1f} ns")

    v = r.get("vcan")
    head("lockstep over vcan0")
    if v is None:
        L.append("  skipped (--quick)")
    elif not err(v):
        L.append(f"  where: {v['where']} (kernel {v.get('kernel')}, {v.get('logical_cpus')} CPUs), "
                 f"{v['wall_s_including_boot']:.0f} s including boot")
        lock = v.get("lockstep", {})
        if "error" in lock:
            L.append(f"  real loop ERROR: {lock['error']}")
        else:
            L.append(f"  real loop (bench.runner.capture, {lock['periods']} periods): {lock['periods_per_s']:.0f} periods/s "
                     f"(run_wall_s {lock['run_wall_s']:.2f}; missed commands "
                     f"{lock['counters'].get('plant_missed_commands')})")
        unrec = v.get("lockstep_unrecorded", {})
        if unrec and "error" not in unrec:
            fl6 = v.get("floor_6", {}).get("periods_per_s")
            ratio_u = unrec["periods_per_s"] / fl6 if fl6 else None
            L.append(f"  real loop without the recorder:            {unrec['periods_per_s']:8.0f} periods/s"
                     + (f"; / floor of the same 6 frames {ratio_u:.2f}" if ratio_u else ""))
        for key, label in (("floor_4", "floor, 4 frames (SYNC, 2 meas, cmd)"),
                           ("floor_6", "floor, 6 frames (+2 drive trace PDOs)"),
                           ("floor_6_recorded", "floor, 6 frames + candump recorder")):
            fl = v.get(key, {})
            if "error" in fl:
                L.append(f"  {label}: ERROR {fl['error']}")
                continue
            ratio = fl.get("real_over_floor")
            extra = ""
            if "frames_recorded" in fl:
                extra = f", recorded {fl['frames_recorded']}/{fl['frames_expected']} frames"
            L.append(f"  {label:<40} {fl['periods_per_s']:8.0f} periods/s  RTT median {fl['rtt_us']['median']:.0f} us "
                     f"p99 {fl['rtt_us']['p99']:.0f} us" + (f"; real/floor {ratio:.2f}" if ratio else "") + extra)
        # Same frames on the same bus: the loop without its recorder against the 6-frame floor, and the
        # recorded loop against the 6-frame floor with the same recorder.
        fl6 = (v.get("floor_6", {}) or {}).get("periods_per_s")
        unrec_rate = (v.get("lockstep_unrecorded", {}) or {}).get("periods_per_s")
        rec_ratio = (v.get("floor_6_recorded", {}) or {}).get("real_over_floor")
        same = [r for r in ((unrec_rate / fl6) if unrec_rate and fl6 else None, rec_ratio) if r is not None]
        L.append(f"  target real/floor of the same frames >= {TARGET_VCAN_RATIO}: "
                 + (", ".join(f"{x:.2f}" for x in same) + " -> " + _fmt_target(min(same) >= TARGET_VCAN_RATIO)
                    if same else "not measured"))
        ch = v.get("long_choice", {})
        L.append(f"  long run: {ch.get('periods')} periods chosen (measured rate x {ch.get('budget_s')} s budget, "
                 f"target {ch.get('target_periods')})")
        for key in ("lockstep", "long"):
            part = v.get(key, {})
            rec = part.get("recorder")
            if "error" in part:
                L.append(f"  {key}: ERROR {part['error']}")
            elif rec is None:
                continue
            elif "error" in rec:
                L.append(f"  {key} recorder: ERROR {rec['error']}")
            else:
                c = rec["continuity"]
                L.append(f"  {key:<9} recorder: SYNCs {rec['syncs_recorded']}/{rec['periods_expected']}, loop frames "
                         f"{rec['loop_frames_recorded']}/{rec['loop_frames_expected']}, lost {rec['lost_frames']} "
                         f"(sync gaps {c['sync_counter_gaps']}, missing meas {c['missing_measurements']}, "
                         f"missing cmds {c['missing_commands']}, index mismatches {c['sample_index_mismatches']}); "
                         f"{part['periods_per_s']:.0f} periods/s")
                cl = rec["continuity_in_log_order"]
                L.append(f"            decoded by kernel time stamp; in candump's log order "
                         f"{rec['frames_out_of_time_order_in_log']} frames are out of time order -> "
                         f"{cl['missing_commands']} commands would look missing, {cl['missing_measurements']} measurements")
    L.append("")
    L.append(f"total wall time {r['wall_s']:.0f} s; JSON saved to {r.get('saved')}")
    return "\n".join(L)


def main(args: argparse.Namespace) -> int:
    if getattr(args, "inside_vm", False):
        if args.out is None:
            print("bench perf: --inside-vm needs --out FILE", file=sys.stderr)
            return 64
        return inside_vm(args)
    t0 = time.monotonic()
    quiet = args.json

    def note(msg: str) -> None:
        if not quiet:
            print(f"bench perf: {msg}", file=sys.stderr, flush=True)

    res: dict[str, Any] = {"command": "bench perf" + (" --quick" if args.quick else "") + (" --json" if args.json else "")}
    note("machine")
    res["machine"] = machine()
    for name, fn in (("plant_core", plant_core), ("closed_loop", closed_loop), ("firmware", firmware),
                     ("yao2020_identification", yao2020_identification_cost), ("cortex_m4", cortex_m4),
                     ("canopen", canopen_cost), ("sweep_scaling", sweep_scaling), ("rerun_live", rerun_live)):
        note(name)
        res[name] = _section(fn)
    if args.quick:
        res["vcan"] = None
    else:
        note("vcan (one VM boot, ~2 min)")
        res["vcan"] = _section(vcan, args)
    res["wall_s"] = time.monotonic() - t0
    if args.save:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        res["saved"] = str(args.save)
        args.save.write_text(json.dumps(res, indent=2))
    print(json.dumps(res, indent=2) if args.json else format_report(res))
    errors = [k for k, s in res.items() if isinstance(s, dict) and "error" in s]
    return 1 if errors else 0


if __name__ == "__main__":
    _ap = argparse.ArgumentParser(prog="bench perf", description=__doc__.splitlines()[0])
    add_arguments(_ap)
    sys.exit(main(_ap.parse_args()))
