"""Cost of the cores, each in isolation: the plant core (plant_perf), plant + controller in-process
(bare cores and the direct mode with its CANopen slaves, with its resident memory), the firmware
core (drive_perf timing and callgrind instruction counts), the Yao 2020 identification against
RLS (callgrind), and the Cortex-M4F build size of firmware_shim/core."""

from __future__ import annotations

import ctypes
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.paths import BUILD, REPO, binary
from bench.run import enable_cia402
from bench.tools.perf.common import TARGET_LOOP_MPS, TARGET_PLANT_MPS, YAO2020_DSP_US, first_line, run, statm_pages

ARM_FLAGS = [
    "-mcpu=cortex-m4",
    "-mthumb",
    "-mfpu=fpv4-sp-d16",
    "-mfloat-abi=hard",
    "-O2",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-std=c11",
    "-c",
]

# Sizes of the runs (kept short: 2 shared cores).
PLANT_PERF_PERIODS = 2_000_000
CORE_LOOP_PERIODS = 2_000_000
DIRECT_PERIODS = 1_000_000
DRIVE_PERF_STEPS = 1_000_000
CALLGRIND_STEPS = (20_000, 40_000)


# ---------------------------------------------------------------------- plant core
PLANT_RE = re.compile(
    r"^(?P<label>.+?)\s+step:\s+(?P<step>[\d.]+) ns/period.*?sample\+step:\s+(?P<both>[\d.]+) ns"
    r".*\[rk4 substeps (?P<sub>\d+)\]"
)


def plant_core() -> dict[str, Any]:
    out = run([str(binary("plant_perf")), str(PLANT_PERF_PERIODS)])
    cases = []
    for line in out.splitlines():
        m = PLANT_RE.match(line)
        if m:
            step, both = float(m["step"]), float(m["both"])
            cases.append(
                {
                    "case": m["label"].strip(),
                    "step_ns": step,
                    "step_Mps": 1e3 / step,
                    "sample_step_ns": both,
                    "sample_step_Mps": 1e3 / both,
                    "rk4_substeps": int(m["sub"]),
                    "meets_target": 1e3 / both >= TARGET_PLANT_MPS,
                }
            )
    mem = re.search(
        r"after warm-up (\d+), after 10\^6 periods (\d+), after 2\*10\^6 periods (\d+) \(growth (-?\d+)\)", out
    )
    res: dict[str, Any] = {
        "periods_per_case": PLANT_PERF_PERIODS,
        "target_Mps": TARGET_PLANT_MPS,
        "cases": cases,
        "metric": "sample+step (what one SYNC costs the plant)",
    }
    if mem:
        res["rss_pages"] = {
            "warm": int(mem[1]),
            "after_1e6": int(mem[2]),
            "after_2e6": int(mem[3]),
            "growth": int(mem[4]),
        }
    if not cases:
        raise RuntimeError(f"unexpected plant_perf output: {out!r}")
    return res


# ---------------------------------------------------------------------- closed loop in-process
# The bare cores' plant (core_loop_perf.c: plant_config_ideal, locked rotor) as SDO writes to the plant's EDS
# records: the direct mode run on it costs what the CANopen slaves and the bus add, nothing of the model.
BARE_CORES_PLANT = {
    ("Inverter", "t_dead_s"): 0.0,
    ("Inverter", "I_trip_A"): 0.0,
    ("Sensors", "encoder_lines"): 0,
    ("Motor model", "sat_enable"): 0,
    ("Motor model", "mech_mode"): 1,
}


def _bare_cores() -> dict[str, Any]:
    """plant_sample -> drive_current_step -> plant_step in one C loop, no CANopen."""
    lib = ctypes.CDLL(str(BUILD / "libhil.so"))
    lib.hil_core_loop_ns.argtypes = [ctypes.c_uint32]
    lib.hil_core_loop_ns.restype = ctypes.c_double
    lib.hil_core_loop_iq_A.restype = ctypes.c_double
    lib.hil_core_loop_ns(CORE_LOOP_PERIODS // 10)  # warm-up
    ns = min(lib.hil_core_loop_ns(CORE_LOOP_PERIODS) for _ in range(2))
    return {
        "periods": CORE_LOOP_PERIODS,
        "ns_per_period": ns,
        "Mperiods_per_s": 1e3 / ns,
        "iq_end_A": lib.hil_core_loop_iq_A(),
        "iq_ref_A": 1.0,
        "target_Mps": TARGET_LOOP_MPS,
        "meets_target": 1e3 / ns >= TARGET_LOOP_MPS,
        "what": "plant_sample -> drive_current_step -> plant_step, You 2019 ideal, locked rotor, deadbeat",
    }


def _direct(plant_sdo: dict[tuple[str, str], float | int]) -> dict[str, Any]:
    """Both node apps, the CANopen slaves and the in-process bus (libhil.so), configured by SDO only for the
    plant_sdo writes, the CiA 402 enable, NMT start and the reference (everything else at the EDS defaults);
    10^6 periods timed after a warm-up, then 10^6 more for the resident memory."""
    import canopen

    from bench.eds import default_node_id, eds_path
    from bench.run import DirectBus, Hil

    hil = Hil()
    net = canopen.Network()
    net.bus = DirectBus(hil)
    net.connect()
    try:
        plant = canopen.RemoteNode(default_node_id("plant"), str(eds_path("plant")))
        drive = canopen.RemoteNode(default_node_id("drive"), str(eds_path("drive")))
        net.add_node(plant)
        net.add_node(drive)
        for (record, entry), value in plant_sdo.items():
            plant.sdo[record][entry].raw = value
        plant.sdo["Run control"]["run_periods"].raw = DIRECT_PERIODS * 2 + DIRECT_PERIODS // 10
        enable_cia402(drive)  # CiA 402: the power stage acts in OPERATION ENABLED only
        for n in (plant, drive):
            n.nmt.send_command(0x01)
        drive.sdo["References"]["iq_ref_A"].raw = 1.0
        hil.run(DIRECT_PERIODS // 10)
        frames0 = hil.frames()
        size0, rss0 = statm_pages()
        t0 = time.perf_counter()
        ran = hil.run(DIRECT_PERIODS)
        wall = time.perf_counter() - t0
        frames = hil.frames() - frames0
        size1, rss1 = statm_pages()
        hil.run(DIRECT_PERIODS)
        size2, rss2 = statm_pages()
        steps = drive.sdo["Drive status"]["current_steps"].raw
        missed = plant.sdo["Run control"]["missed_commands"].raw
    finally:
        net.disconnect()
    return {
        "periods": ran,
        "wall_s": wall,
        "ns_per_period": 1e9 * wall / ran,
        "periods_per_s": ran / wall,
        "Mperiods_per_s": ran / wall / 1e6,
        "target_Mps": TARGET_LOOP_MPS,
        "meets_target": ran / wall / 1e6 >= TARGET_LOOP_MPS,
        "drive_current_steps": steps,
        "plant_missed_commands": missed,
        "frames_per_period": frames / ran,
        "plant_sdo": {f"{r}.{e}": v for (r, e), v in plant_sdo.items()},
        "what": "plant_app + drive_app + CANopen slave on co_membus (libhil.so), no recorder",
        "_statm": (size0, rss0, size1, rss1, size2, rss2),
    }


def closed_loop() -> dict[str, Any]:
    """The bare cores, then direct mode on the same plant as the bare cores (what CANopen and the bus cost) and on
    the EDS defaults (dead time, encoder, trip: what a user's default run costs), and the resident memory."""
    bare = _bare_cores()
    same = _direct(BARE_CORES_PLANT)
    same.pop("_statm")
    direct = _direct({})
    size0, rss0, size1, rss1, size2, rss2 = direct.pop("_statm")
    page_kB = os.sysconf("SC_PAGE_SIZE") / 1024
    memory = {
        "periods": 2 * direct["periods"],
        "page_kB": page_kB,
        "rss_pages": {"before": rss0, "after_1e6": rss1, "after_2e6": rss2},
        "vm_size_pages": {"before": size0, "after_1e6": size1, "after_2e6": size2},
        "rss_growth_kB_over_1e6": (rss1 - rss0) * page_kB,
        "rss_growth_kB_over_2e6": (rss2 - rss0) * page_kB,
        "rss_growth_kB_second_1e6": (rss2 - rss1) * page_kB,
        # Flat: nothing over the second 10^6 periods (the first may still fault in a few
        # rarely used code pages of libm/libhil, which are file-backed and bounded).
        "flat": rss2 == rss1 and rss1 - rss0 <= 4,
    }
    return {"bare_cores": bare, "direct_mode_bare_plant": same, "direct_mode": direct, "memory": memory}


# ---------------------------------------------------------------------- firmware
DRIVE_PERF_KEYS = {
    "deadbeat current step": "deadbeat_step_ns",
    "deadbeat + identification step": "deadbeat_ident_step_ns",
    "PI current step": "pi_step_ns",
    "identification sample (You 2019 Eq. 24-27, per call)": "ident_sample_ns",
    "identification update (You 2019 Eq. 28-32)": "ident_update_ns",
}


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
    run(
        ["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}", str(binary("drive_perf")), str(steps)],
        timeout=300,
    )
    ann = run(["callgrind_annotate", "--inclusive=yes", "--auto=yes", str(cg)], timeout=120)
    total = int(re.search(r"^([\d,]+) \(100\.0%\)\s+PROGRAM TOTALS", ann, re.M)[1].replace(",", ""))  # type: ignore[index]
    sections = re.split(r"^-- Auto-annotated source: ", ann, flags=re.M)
    # A file can appear twice (absolute and relative debug path); take the one with the call sites.
    cands = [s for s in sections[1:] if s.splitlines() and s.splitlines()[0].strip().endswith("drive_perf.c")]
    src = max(cands, key=lambda s: len(re.findall(r"=> \S+:bench \(1x\)", s)), default="")
    bench_calls = [
        int(m[1].replace(",", "")) for m in re.finditer(r"^\s*([\d,]+) \([\d. ]+%\)\s+=> \S+:bench \(1x\)", src, re.M)
    ]
    avg = re.search(r"^\s*([\d,]+) \([\d. ]+%\)\s+=> \S+:you2019_identification_average \(", src, re.M)
    smp = re.search(r"^\s*([\d,]+) \([\d. ]+%\)\s+=> \S+:you2019_identification_sample \(", src, re.M)
    if len(bench_calls) != 3 or not avg or not smp:
        raise RuntimeError("cannot find drive_perf's call sites in callgrind_annotate's output")
    return {
        "total": total,
        "deadbeat": bench_calls[0],
        "deadbeat_ident": bench_calls[1],
        "pi": bench_calls[2],
        "ident_update": int(avg[1].replace(",", "")),
        "ident_sample": int(smp[1].replace(",", "")),
    }


def firmware() -> dict[str, Any]:
    out = run([str(binary("drive_perf")), str(DRIVE_PERF_STEPS)])
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
    run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}", str(binary(exe)), str(steps)], timeout=300)
    ann = run(["callgrind_annotate", "--inclusive=yes", str(cg)], timeout=120)
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
    fns = ("yao2020_identification_update", "yao2020_rls_update", "yao2020_dpcc_step")
    n1, n2 = 10000, 20000
    with tempfile.TemporaryDirectory() as td:
        a = _fn_inclusive(n1, "yao2020_perf", fns, Path(td))
        b = _fn_inclusive(n2, "yao2020_perf", fns, Path(td))
    per = {fn: (b[fn] - a[fn]) / (n2 - n1) for fn in fns}
    return {
        "step_counts": [n1, n2],
        "instructions_per_call": per,
        "rls_over_proposed": per["yao2020_rls_update"] / per["yao2020_identification_update"],
        "paper_us_on_150MHz_DSP": {**YAO2020_DSP_US, "ratio": YAO2020_DSP_US["rls"] / YAO2020_DSP_US["proposed"]},
    }


# ---------------------------------------------------------------------- Cortex-M4F
def cortex_m4() -> dict[str, Any]:
    gcc, size = shutil.which("arm-none-eabi-gcc"), shutil.which("arm-none-eabi-size")
    if not gcc or not size:
        raise RuntimeError("arm-none-eabi-gcc not installed (apt-get install gcc-arm-none-eabi)")
    core = REPO / "firmware_shim" / "core"
    objs = []
    with tempfile.TemporaryDirectory() as td:
        # the drive's cores and the papers' law folders (each on its own include path)
        for src in sorted(core.glob("*.c")) + sorted((REPO / "firmware_shim" / "laws").glob("*/*.c")):
            obj = Path(td) / (src.stem + ".o")
            inc = [f"-I{core}", f"-I{src.parent}", f"-I{REPO / 'protocols' / 'generated'}"]
            r = subprocess.run(
                [gcc, *ARM_FLAGS, *inc, str(src), "-o", str(obj)],
                capture_output=True,
                text=True,
                timeout=120,
            )
            if r.returncode != 0:
                raise RuntimeError(f"arm-none-eabi-gcc failed on {src.name}: {r.stderr}")
            objs.append(obj)
        out = run([size, "-B", *map(str, objs)])
    rows = []
    for line in out.splitlines()[1:]:
        f = line.split()
        if len(f) >= 6:
            rows.append({"object": Path(f[5]).name, "text": int(f[0]), "data": int(f[1]), "bss": int(f[2])})
    total = {k: sum(r[k] for r in rows) for k in ("text", "data", "bss")}
    return {"compiler": first_line([gcc, "--version"]), "flags": " ".join(ARM_FLAGS), "objects": rows, "total": total}
