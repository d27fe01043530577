"""`bench perf`: every performance figure of the bench in one run, with the machine.

Sections (each labelled in the output; timings are reported, never asserted), by module:

* common        machine: CPU model, cores, kernel, compilers
* cores         plant core (plant_perf, target >= 10 M periods/s); plant + controller in-process: bare
                cores (libhil.so hil_core_loop_ns) and the direct mode (both node apps and the CANopen
                slaves on the in-process bus, target >= 5 M periods/s) with its resident memory over
                10^6 periods; firmware (drive_perf ns per step, instructions per step under callgrind);
                Yao 2020 identification vs RLS (callgrind); Cortex-M4F sizes (arm-none-eabi-gcc)
* mcu           the drive firmware as the Cortex-M4F image in the loop (`bench run --drive mcu`, one VM boot
                per run): instructions per current step per controller (Yao 2020's identification and RLS
                beside the paper's DSP times), loop rate, flash and RAM of the image
* canopen_cost  co_perf ns per frame
* sweep         `bench sweep` on Dask: 1,000 points on 1 and 2 workers, a 10^4-point study
* live          Rerun's served live buffer for 10^6 periods x 16 signals; the VM live view's cost per update
* pipeline      what the user waits for, side by side: whole `bench run` processes (1 s scenario, 10^6
                periods with every output), run_scenario with a sweep's outputs at 10^6 / 10^7 periods
                against the loop's own rate, peak RSS of each, and the peer (peers: gym-electric-motor on
                the same 1 s scenario); a table of the targets
* vcan          ONE VM boot (or the host's vcan0): the real lockstep loop beside lockstep_floor (same frames,
                no stack), and a longer run whose every frame is checked from the SYNC counters
* box           the CAN box (issue 38), whole commands as a user runs them where the host has no kernel CAN:
                the box's boot, `bench run` of the 200-period step over vcan0, `bench demo` and one vcan test
                through the pytest plugin, with the box up against a VM per run (BENCH_BOX=0) and direct mode,
                interleaved (~12 minutes; --repetitions N box runs of each, default 3)
* soak          10^6 periods over vcan0 with the recorder (one VM boot): every frame checked (SYNC counters,
                sample indices) and the resident memory of every process sampled once a second: flat or not
* realtime      10^6 periods of `bench run` in direct real time at Ts = 100 us and 55 us, each beside cyclictest
                at the same interval and priority (SCHED_FIFO 80, mlockall): SYNC lateness p50/p99/p99.9/max of
                both, the bench's overruns and turnaround, the ratios and the issue 29 targets (needs rt-tests)
* report        format_report

`bench perf --json` prints the same as JSON; `--quick` skips the vcan, box, soak and mcu parts and shrinks the pipeline
section (10^5 periods, one repetition, no 10^7, no peers) and the realtime section (2 x 10^4 periods). Inside the
VM the helper `python -m bench.tools.perf --inside-vm --out FILE` runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench.tools.perf.common import PERF_DIR, VM_LOCKSTEP_PERIODS, VM_LONG_BUDGET_S, machine, section

if TYPE_CHECKING:
    from bench.tools.perf.realtime import RtSizes

SECTIONS = (
    "plant_core",
    "motor_models",
    "closed_loop",
    "firmware",
    "yao2020_identification",
    "cortex_m4",
    "mcu",
    "canopen",
    "sweep_scaling",
    "rerun_live",
    "pipeline",
    "vcan",
    "box",
    "soak",
    "realtime",
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    from bench.tools.perf.common import REALTIME_PERIODS, REALTIME_QUICK_PERIODS, REALTIME_TS_US, TARGET_LONG_PERIODS

    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument(
        "--quick",
        action="store_true",
        help="skip the vcan and mcu parts (no VM boot); pipeline section at 10^5 periods, once, no 10^7, no peers",
    )
    p.add_argument(
        "--only", default=None, metavar="SECTION[,SECTION...]", help=f"run only these sections ({', '.join(SECTIONS)})"
    )
    p.add_argument(
        "--repetitions",
        type=int,
        default=None,
        help="whole-process runs of the 1 s scenario in the pipeline section (default 5; --quick 1)",
    )
    p.add_argument("--no-peers", action="store_true", help="pipeline section without the peer simulator")
    p.add_argument(
        "--lockstep-periods",
        type=int,
        default=VM_LOCKSTEP_PERIODS,
        help=f"periods of the real lockstep loop and of the floor over vcan (default {VM_LOCKSTEP_PERIODS})",
    )
    p.add_argument(
        "--long-budget-s",
        type=float,
        default=VM_LONG_BUDGET_S,
        help="wall-time budget of the long frame-continuity run in the VM "
        f"(periods = measured rate x budget, at most {TARGET_LONG_PERIODS}; "
        f"default {VM_LONG_BUDGET_S:.0f})",
    )
    p.add_argument(
        "--soak-periods",
        type=int,
        default=1_000_000,
        help="periods of the soak run over vcan (default 10^6: every frame checked, memory of every process sampled)",
    )
    p.add_argument(
        "--realtime-periods",
        type=int,
        default=None,
        help=f"periods of each real-time run and cyclictest's loops (default {REALTIME_PERIODS:,}; "
        f"--quick {REALTIME_QUICK_PERIODS:,})",
    )
    p.add_argument(
        "--realtime-ts-us",
        default=",".join(f"{t:g}" for t in REALTIME_TS_US),
        metavar="US[,US...]",
        help="the periods of the realtime section, us (default %(default)s)",
    )
    p.add_argument(
        "--realtime-burners",
        type=int,
        default=0,
        metavar="N",
        help="run the realtime section under N busy loops (started and killed by the section; default 0: idle)",
    )
    p.add_argument(
        "--realtime-runs",
        type=int,
        default=1,
        metavar="N",
        help="rounds of the realtime section per Ts, each cyclictest then the bench, every one reported (default 1)",
    )
    p.add_argument(
        "--realtime-against",
        type=Path,
        default=None,
        metavar="CHECKOUT",
        help="a second built checkout of the bench (e.g. `git worktree add /tmp/before REV && make -C /tmp/before "
        "all`), run beside this one in each round of the realtime section, their order alternating",
    )
    p.add_argument(
        "--realtime-motor",
        type=Path,
        default=None,
        metavar="DIR",
        help="also run the realtime section's bench with this motor folder (its flux-map plant, docs/YOUR_MOTOR.md), "
        "e.g. examples/motors/saturating_you2019",
    )
    p.add_argument(
        "--realtime-fmu",
        action="store_true",
        help="also run the realtime section's bench with the example FMU as the plant (examples/fmu/linear_pmsm, "
        "built by the section)",
    )
    p.add_argument(
        "--realtime-serve",
        action="store_true",
        help="run the realtime section's bench with its live view (--serve --serve-for 0)",
    )
    p.add_argument("--save", type=Path, default=PERF_DIR / "perf.json", help="also write the JSON here")
    p.add_argument("--inside-vm", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--out", type=Path, default=None, help=argparse.SUPPRESS)


def _functions(args: argparse.Namespace, note: Any) -> dict[str, Any]:
    from bench.tools.perf.box import box
    from bench.tools.perf.canopen_cost import canopen_cost
    from bench.tools.perf.cores import closed_loop, cortex_m4, firmware, plant_core, yao2020_identification_cost
    from bench.tools.perf.live import rerun_live
    from bench.tools.perf.mcu import mcu_in_the_loop
    from bench.tools.perf.motors import motor_models
    from bench.tools.perf.pipeline import Sizes, pipeline
    from bench.tools.perf.realtime import realtime
    from bench.tools.perf.soak import soak
    from bench.tools.perf.sweep import sweep_scaling
    from bench.tools.perf.vcan import vcan

    sizes = Sizes.quick() if args.quick else Sizes()
    if args.repetitions is not None:
        sizes.repetitions = max(1, args.repetitions)
    if args.no_peers:
        sizes.peers = False
    return {
        "plant_core": plant_core,
        "motor_models": motor_models,
        "closed_loop": closed_loop,
        "firmware": firmware,
        "yao2020_identification": yao2020_identification_cost,
        "cortex_m4": cortex_m4,
        "mcu": mcu_in_the_loop,
        "canopen": canopen_cost,
        "sweep_scaling": sweep_scaling,
        "rerun_live": rerun_live,
        "pipeline": lambda: pipeline(sizes, note=note),
        "vcan": lambda: vcan(args),
        "box": lambda: box(args),
        "soak": lambda: soak(args.soak_periods),
        "realtime": lambda: realtime(realtime_sizes(args), note=note),
    }


def realtime_sizes(args: argparse.Namespace) -> RtSizes:
    """The realtime section's sizes from the options (ValueError with the option's name when bad)."""
    from bench.tools.perf.common import REALTIME_PERIODS, REALTIME_QUICK_PERIODS
    from bench.tools.perf.realtime import RtSizes

    periods = getattr(args, "realtime_periods", None)
    if periods is None:
        periods = REALTIME_QUICK_PERIODS if getattr(args, "quick", False) else REALTIME_PERIODS
    try:
        ts = tuple(float(t) for t in str(getattr(args, "realtime_ts_us", "100,55")).split(","))
    except ValueError:
        raise ValueError(f"--realtime-ts-us {args.realtime_ts_us!r}: need periods in us, e.g. 100,55") from None
    if periods < 1 or not ts or any(not 1.0 <= t <= 100_000.0 for t in ts):
        raise ValueError("--realtime-periods needs >= 1 and --realtime-ts-us periods of 1 .. 100000 us")
    burners = max(0, int(getattr(args, "realtime_burners", 0) or 0))
    runs = getattr(args, "realtime_runs", None)
    runs = 1 if runs is None else int(runs)
    if runs < 1:
        raise ValueError(f"--realtime-runs {runs}: need at least 1")
    against = getattr(args, "realtime_against", None)
    if against is not None:
        against = Path(against).resolve()
        missing = [f for f in ("bench/cli.py", "build/libhil.so") if not (against / f).is_file()]
        if missing:
            raise ValueError(
                f"--realtime-against {against}: not a built checkout of the bench (no {', '.join(missing)}; "
                f"run `make -C {against} all`)"
            )
    serve = bool(getattr(args, "realtime_serve", False))
    motor = getattr(args, "realtime_motor", None)
    if motor is not None:
        motor = Path(motor).resolve()
        if not (motor / "motor.toml").is_file():
            raise ValueError(f"--realtime-motor {motor}: not a motor folder (no motor.toml; docs/YOUR_MOTOR.md)")
    return RtSizes(
        periods=periods,
        ts_us=ts,
        burners=burners,
        runs=runs,
        serve=serve,
        against=str(against) if against else None,
        motor=str(motor) if motor else None,
        fmu=bool(getattr(args, "realtime_fmu", False)),
    )


def main(args: argparse.Namespace) -> int:
    from bench.tools.perf.report import format_report

    if getattr(args, "inside_vm", False):
        from bench.tools.perf.vcan import inside_vm

        if args.out is None:
            print("bench perf: --inside-vm needs --out FILE", file=sys.stderr)
            return 64
        return inside_vm(args)
    only = [s.strip() for s in args.only.split(",")] if getattr(args, "only", None) else list(SECTIONS)
    unknown = [s for s in only if s not in SECTIONS]
    if unknown:
        print(f"bench perf: unknown section(s) {', '.join(unknown)}; known: {', '.join(SECTIONS)}", file=sys.stderr)
        return 64
    if "realtime" in only:
        from bench.tools.perf.realtime import MISSING, have_cyclictest

        if not have_cyclictest():
            print(MISSING, file=sys.stderr)
            return 69
        try:
            realtime_sizes(args)
        except ValueError as exc:
            print(f"bench perf: {exc}", file=sys.stderr)
            return 64
    t0 = time.monotonic()
    quiet = args.json

    def note(msg: str) -> None:
        if not quiet:
            print(f"bench perf: {msg}", file=sys.stderr, flush=True)

    argv = " ".join(a for a in sys.argv[1:] if a != "perf")
    res: dict[str, Any] = {"command": f"bench perf {argv}".strip()}
    note("machine")
    res["machine"] = machine()
    fns = _functions(args, note)
    for name in SECTIONS:
        if name not in only:
            continue
        if name in ("vcan", "box", "mcu", "soak") and args.quick:
            res[name] = None
            continue
        note(
            {"vcan": "vcan (one VM boot, ~2 min)", "box": "box (~12 min: a VM per run is measured too)"}.get(name, name)
        )
        res[name] = section(fns[name])
    res["wall_s"] = time.monotonic() - t0
    if args.save:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        res["saved"] = str(args.save)
        args.save.write_text(json.dumps(res, indent=2))
    print(json.dumps(res, indent=2) if args.json else format_report(res))
    errors = [k for k, s in res.items() if isinstance(s, dict) and ("error" in s or s.get("errors"))]
    return 1 if errors else 0
