"""A study from Python, notebook style: You 2019's deadbeat step with the drive's inductance estimate off by -30 %
to +30 %, each point a direct run in this process (bench.api.run: no process per point, no files), the step's
figures and the last periods' current gathered in a table.

    .venv/bin/python examples/library/inductance_study.py            # the table
    .venv/bin/python examples/library/inductance_study.py --plot     # and inductance_study.svg (pygal)

The matched estimate settles in two periods (You 2019, file 000); an estimate above L overshoots, one below it settles
slower. Every figure is the run's own, nothing is written down. In a notebook, the loop body is a cell."""

from __future__ import annotations

import argparse
from pathlib import Path

from bench.api import run

SCENARIO = "scenarios/you2019_step.toml"  # the bench's own (bench.api.run finds it from any folder)
RATIOS = (0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3)


def study(ratios: tuple[float, ...] = RATIOS, periods: int = 200) -> list[dict[str, object]]:
    rows = []
    for ratio in ratios:
        r = run(SCENARIO, {"scenario.periods": periods, "controller.L_hat_ratio": ratio})
        step = r.step("iq")
        rows.append(
            {
                "L_hat_ratio": ratio,
                "status": r.status,
                "settles_in": step.periods_to_settle,
                "overshoot_pct": step.overshoot_pct,
                "iq_last_A": float(r["iq_A"][-1]),
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--periods", type=int, default=200, help="periods per run (default 200)")
    p.add_argument("--plot", type=Path, nargs="?", const=Path("inductance_study.svg"), help="write an SVG plot")
    args = p.parse_args(argv)
    rows = study(periods=args.periods)
    print(f"{'L_hat/L':>8} {'status':>8} {'settles in':>10} {'overshoot %':>12} {'iq end A':>10}")
    for row in rows:
        settle = "never" if row["settles_in"] is None else f"{row['settles_in']} per."
        over = "n/a" if row["overshoot_pct"] is None else f"{row['overshoot_pct']:.3g}"
        print(f"{row['L_hat_ratio']:>8} {row['status']:>8} {settle:>10} {over:>12} {row['iq_last_A']:>10.6f}")
    if args.plot is not None:
        import pygal

        chart = pygal.XY(
            title="You 2019 step: overshoot against the inductance estimate",
            x_title="L_hat / L",
            y_title="overshoot (%)",
        )
        chart.add("overshoot", [(r["L_hat_ratio"], r["overshoot_pct"] or 0.0) for r in rows])
        chart.render_to_file(str(args.plot))
        print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
