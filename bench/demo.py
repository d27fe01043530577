"""The README's main job (`make demo`): the headline scenario over vcan, shown in Rerun.

You 2019 motor with L_hat = 0.5 L, a current-step train, online tuning switched on halfway
(scenarios/demo_you2019_tuning.toml), run over vcan0 (the VM supplies it when the host has
no CAN), recorded, summarized; prints the before/after table, the identified gains and the
paths of the recording, traces and plots. It is `bench run` of that scenario (the same
parser, so the same defaults) plus a table made from the run's result in memory.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bench.paths import REPO

SCENARIO = REPO / "scenarios" / "demo_you2019_tuning.toml"


def main(args: argparse.Namespace) -> int:
    from bench.run.command import add_arguments, execute

    out = args.out or Path("runs") / f"demo-{time.strftime('%Y%m%d-%H%M%S')}"
    argv = ["run", str(SCENARIO), "--bus", args.bus, "--out", str(out)]
    argv += [a for o in args.overrides for a in ("--set", o)]
    argv += ["--serve", "--serve-bind", args.serve_bind] if args.serve else []
    argv += ["--no-viewer"] if args.no_viewer else []
    run_parser = argparse.ArgumentParser(prog="bench run")  # `bench run`'s own options (bench/run/command.py)
    add_arguments(run_parser)
    rc, result, out_dir = execute(run_parser.parse_args(argv[1:]))
    if result is None:
        return rc
    summary = result.summary
    before = [s for s in summary["steps"] if not s["tuning_on"]]
    after = [s for s in summary["steps"] if s["tuning_on"]]

    def mean(xs: list[float]) -> float:
        return sum(xs) / len(xs) if xs else float("nan")

    def settle(steps: list[dict[str, object]]) -> str:
        return ", ".join("-" if s["periods_to_settle"] is None else str(s["periods_to_settle"]) for s in steps)

    ident = summary["identified"]
    print()
    print("demo: You 2019 deadbeat current loop, controller L_hat = 0.5 L, online tuning switched on at period 400")
    print(f"  {'':<16}{'periods to settle (2 %)':<28}{'mean overshoot':>16}")
    print(f"  {'tuning off':<16}{settle(before):<28}{mean([s['overshoot_A'] for s in before]):>13.3f} A")
    print(f"  {'tuning on':<16}{settle(after):<28}{mean([s['overshoot_A'] for s in after]):>13.3f} A")
    print(
        "  (the first steps after the switch still carry the error left by the gain change: a mode at the plant "
        "pole, cancelled by the deadbeat zero, decaying with L/R)"
    )
    if ident.get("K1_bar_V_A") is not None:
        print(
            f"  identified gains: K1 {ident['K1_bar_V_A']:.3f} V/A, K2 {ident['K2_bar_V_A']:.3f} V/A, "
            f"L_hat {ident['L_hat_H'] * 1e3:.4f} mH (plant Lq {summary['plant']['Lq_H'] * 1e3:.4f} mH)"
        )
    if (out_dir / "run.rrd").exists():  # without the [view] extra there is none
        print(f"  recording: {out_dir / 'run.rrd'} (rerun {out_dir / 'run.rrd'})")
    print(f"  CAN log:   {out_dir / summary['files']['log']}")
    print(
        f"  traces:    {out_dir / summary['files']['traces']}; summary: {out_dir / 'summary.json'}; "
        f"plots: {out_dir}/*.svg"
    )
    return rc
