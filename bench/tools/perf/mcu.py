"""The drive firmware on the Cortex-M4F image, in the loop (`bench run --drive mcu`, as a user runs it): per
controller, the instructions of one current step (0x2208 Step cost: the image's SysTick around every step;
under QEMU -icount shift=0 one instruction is 1 ns of virtual time), the loop's rate through the emulated
MCU and SLCAN, and the image's flash and RAM (arm-none-eabi-size). Yao 2020's identification and its RLS
baseline are each the difference to the same DPCC + observer run without them, side by side with the
paper's own execution times (0.313 us against 18.9 us on a 150 MHz DSP: common.YAO2020_DSP_US)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from bench.mcu import ELF, build
from bench.paths import REPO
from bench.tools.perf.common import YAO2020_DSP_US

YOU = REPO / "scenarios" / "demo_you2019_tuning.toml"
YAO = REPO / "scenarios" / "yao2020_identification.toml"
STEP = REPO / "scenarios" / "you2019_step.toml"
YAO_PLAIN = ["events=[]", "scenario.periods=1500"]
# (key, what runs in the drive, scenario, --set overrides)
RUNS: tuple[tuple[str, str, Path, list[str]], ...] = (
    ("you2019", "You 2019 deadbeat + online gain identification", YOU, ["controller.enable=1"]),
    ("yao2020_plain", "Yao 2020 DPCC + disturbance observer", YAO, YAO_PLAIN),
    ("yao2020_ident", "Yao 2020 DPCC + observer + R/L identification", YAO, []),
    (
        "yao2020_rls",
        "Yao 2020 DPCC + observer + RLS (the paper's baseline)",
        YAO,
        [*YAO_PLAIN, "controller.rls_enable=1"],
    ),
    (
        "zhao2022",
        "Zhao 2022 incremental deadbeat",
        STEP,
        [
            "motor.preset=zhao2022",
            "controller.controller=incremental_zhao2022",
            "controller.Vmax_V=16.16581",  # 28 V / sqrt(3), as bench/claims/zhao2022.py
            "drive.encoder_lines=0",
            "scenario.periods=1500",
            "events=[{at_period = 20, references = {iq_ref_A = 0.3}}]",  # below the preset's 0.57 A trip
        ],
    ),
)


def image_size() -> dict[str, int]:
    """Flash (text + data) and static RAM (data + bss) of build/mcu/drive_mcu.elf."""
    out = subprocess.run(["arm-none-eabi-size", "-B", str(ELF)], capture_output=True, text=True, check=True).stdout
    text, data, bss = (int(x) for x in out.splitlines()[1].split()[:3])
    return {"text": text, "data": data, "bss": bss, "flash_bytes": text + data, "ram_bytes": data + bss}


def _run(scenario: Path, overrides: list[str], out: Path) -> dict[str, Any]:
    cmd = [sys.executable, "-m", "bench.cli", "run", str(scenario), "--bus", "vcan0", "--drive", "mcu"]
    cmd += ["--no-viewer", "--out", str(out)]
    for o in overrides:
        cmd += ["--set", o]
    res = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[2:])} failed ({res.returncode}): {res.stderr[-800:]}")
    return json.loads((out / "summary.json").read_text())  # type: ignore[no-any-return]


def mcu_in_the_loop() -> dict[str, Any]:
    build()
    tmp = Path(tempfile.mkdtemp(prefix="perf-mcu-"))
    runs: dict[str, Any] = {}
    try:
        for key, what, scenario, overrides in RUNS:
            s = _run(scenario, overrides, tmp / key)
            cost, t = s["step_cost"], s["timing"]
            runs[key] = {
                "what": what,
                "command": f"bench run {scenario.relative_to(REPO)} --bus vcan0 --drive mcu"
                + "".join(f" --set {o}" for o in overrides),
                "controller": cost["controller"],
                "steps": cost["steps_measured"],
                "instructions_mean": cost["step_mean_s"] * 1e9,  # -icount shift=0: 1 instruction = 1 ns
                "instructions_max": cost["step_max_s"] * 1e9,
                "periods": s["periods"],
                "loop_periods_per_s": t.get("periods_per_s"),
                "whole_command_s": t.get("wall_s"),
                "status": s["status"],
            }
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    plain = runs["yao2020_plain"]["instructions_mean"]
    ident = runs["yao2020_ident"]["instructions_mean"] - plain
    rls = runs["yao2020_rls"]["instructions_mean"] - plain
    dsp = YAO2020_DSP_US
    return {
        "image": image_size(),
        "runs": runs,
        "yao2020_identification_vs_rls": {
            "identification_instructions": ident,
            "rls_instructions": rls,
            "rls_over_identification": rls / ident if ident > 0 else None,
            "paper_identification_cycles": dsp["proposed"] * dsp["clock_MHz"],
            "paper_rls_cycles": dsp["rls"] * dsp["clock_MHz"],
            "paper_rls_over_identification": dsp["rls"] / dsp["proposed"],
        },
        "note": "instructions = SysTick ticks x 40 under QEMU -icount shift=0 (resolution 40 per step, averaged "
        "over every step of the run); they are not cycles of a real M4F (no pipeline, flash wait states or "
        "FPU latencies modelled). The identification's and the RLS's cost: the run with it minus the same "
        "DPCC + observer run without it.",
    }
