"""`bench perf`'s report, its realtime section: per period Ts (and round) the plant's SYNC lateness (summary.json
"realtime") beside cyclictest's wake-up latency at the same interval, priority and CPU, the bench's overruns and
their causes, the ratios bench / cyclictest and issue 40's targets; with --realtime-against, the other checkout's
run of the same round beside it (bench/tools/perf/realtime.py measures them)."""

from __future__ import annotations

from typing import Any

from bench.tools.perf.cyclictest import PRIORITY
from bench.tools.perf.realtime import (
    TARGET_OVERRUN_FACTOR,
    TARGET_OVERRUN_TS_US,
    TARGET_P99_RATIO,
    TARGET_P99_RATIO_OTHER,
    TARGET_P999_RATIO,
)

COLS = ("p50", "p99", "p99_9", "max")
SIDES = (
    ("bench", "compare", "bench"),
    ("against", "compare_against", "against"),
    ("motor", "compare_motor", "flux map"),  # --realtime-motor DIR: the same run on a motor folder's flux-map plant
    ("fmu", "compare_fmu", "FMU"),  # --realtime-fmu: the same run with the example FMU as the plant
)


def _us(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def _x(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}x"


def _verdict(ok: bool | None) -> str:
    return "not judged" if ok is None else ("met" if ok else "NOT met")


def _bench_row(label: str, b: dict[str, Any]) -> str:
    lat, cnt, tr = b["lateness_us"], b["counts"], b["turnaround_us"]
    return (
        f"  {label:<30}"
        + "".join(f"{_us(lat.get(k)):>8}" for k in COLS)
        + f"{cnt.get('overruns')!s:>10}{cnt.get('sync_overruns')!s:>10}"
        + f"   {_us(tr.get('p50'))} / {_us(tr.get('p99'))} / {_us(tr.get('max'))}"
    )


def _ratio_row(label: str, cmp_: dict[str, Any]) -> str:
    return (
        f"  {label:<30}{'':>8}{_x(cmp_.get('p99_ratio')):>8}{_x(cmp_.get('p99_9_ratio')):>8}"
        f"{_x(cmp_.get('max_ratio')):>8}"
    )


def table_lines(s: dict[str, Any]) -> list[str]:
    """The side-by-side table: for each Ts (and round) a bench row (and the other checkout's), a cyclictest row and
    a ratio row per bench row."""
    out = [
        f"  {'lateness us':<30}"
        + "".join(f"{c.replace('_', '.'):>8}" for c in COLS)
        + f"{'overruns':>10}{'sync ovr':>10}   turnaround us p50 / p99 / max"
    ]
    for key, row in s["runs"].items():
        ts = f"Ts {key} us"
        c = row["cyclictest"]
        for side, _cmp, name in SIDES:
            if side not in row:
                continue
            label = f"{ts:<14}{name}"
            b = row[side]
            out.append(f"  {label:<30}ERROR {b['error']}" if "error" in b else _bench_row(label, b))
        if "error" in c:
            out.append(f"  {'':<14}{'cyclictest':<16}ERROR {c['error']}")
        else:
            lat = c["lateness_us"]
            out.append(
                f"  {'':<14}{'cyclictest':<16}"
                + "".join(f"{_us(lat.get(k)):>8}" for k in COLS)
                + f"{'':>10}{c.get('over_period', '-')!s:>10}"
            )
        for _side, cmp_key, name in SIDES:
            if cmp_key in row:
                out.append(_ratio_row(f"{'':<14}{name} / cyclictest", row[cmp_key]))
    return out


def _details(s: dict[str, Any]) -> list[str]:
    """Per run: the bench's status and exit status, its overruns by cause, the host's floor it probed, what it said
    about its priority, its bus-side view."""
    out = []
    for key, row in s["runs"].items():
        for side, _cmp, name in SIDES:
            b = row.get(side)
            if not b or "error" in b:
                continue
            cnt = b["counts"]
            rt = b.get("realtime") or {}
            causes = (rt.get("bus") or {}).get("overrun_causes")
            why = ", ".join(f"{k} {v}" for k, v in causes.items()) if causes else "not named (this checkout)"
            out.append(
                f"  Ts {key} us, {name}: status {b['status']} (exit {b['exit_status']}), {b['periods']:,} periods in "
                f"{b['wall_s']:.0f} s whole process; missed {cnt.get('missed_commands')}, late "
                f"{cnt.get('late_commands')}, worst period {b.get('worst_period')}; overruns by cause: {why}"
            )
            bus = b.get("bus") or {}
            sl, iv = bus.get("sync_lateness_us") or {}, bus.get("sync_interval_us") or {}
            if sl:
                out.append(
                    f"    bus view (frame stamps): SYNC lateness p99 {_us(sl.get('p99'))} max {_us(sl.get('max'))} "
                    f"us; SYNC interval min {_us(iv.get('min'))} p50 {_us(iv.get('p50'))} max {_us(iv.get('max'))} us"
                )
            out.extend(f"    {n}" for n in b.get("notes", []))
    return out


def _targets(s: dict[str, Any]) -> list[str]:
    out = [
        f"  targets (issue 40): at Ts = {TARGET_OVERRUN_TS_US:g} us idle p99 <= {TARGET_P99_RATIO:g}x, p99.9 <= "
        f"{TARGET_P999_RATIO:g}x cyclictest's and overruns <= {TARGET_OVERRUN_FACTOR:g}x its wake-ups >= a period "
        f"(10^6 periods); p99 <= {TARGET_P99_RATIO_OTHER:g}x at other Ts and under load"
    ]
    for key, row in s["runs"].items():
        c = row["cyclictest"]
        for side, cmp_key, name in SIDES:
            if cmp_key not in row:
                continue
            cmp_ = row[cmp_key]
            b = row[side]
            over = "-" if "error" in b else b["counts"].get("overruns")
            limit = cmp_.get("overrun_limit")
            ovr = _verdict(cmp_.get("overrun_target_met"))
            if limit is not None:
                ovr += f" ({over} vs {limit:g} = {TARGET_OVERRUN_FACTOR:g} x {c.get('over_period')})"
            elif cmp_.get("overrun_target_note"):
                ovr += f" ({cmp_['overrun_target_note']})"
            if cmp_.get("overrun_periods_ratio") is not None:
                ovr += f"; {_x(cmp_['overrun_periods_ratio'])} the periods cyclictest's late wake-ups passed"
            out.append(
                f"  Ts {key} us, {name}: p99 {_x(cmp_.get('p99_ratio'))} {_verdict(cmp_.get('p99_target_met'))}; "
                f"p99.9 {_x(cmp_.get('p99_9_ratio'))} {_verdict(cmp_.get('p99_9_target_met'))}; overruns {ovr}"
            )
    return out


def format_realtime(r: dict[str, Any], L: Any) -> None:
    """The realtime section of the report (L: report._Lines); nothing when it was not run."""
    s = L.sec(r, "realtime", f"real time: SYNC lateness beside cyclictest (SCHED_FIFO {PRIORITY}, mlockall)")
    if s is None:
        return
    against = (s.get("sizes") or {}).get("against")
    L.append(
        f"  {s['sizes']['periods']:,} periods at each Ts; load: {s['load']}; bench: `bench run {s['scenario']} "
        "--bus direct --set scenario.timing=realtime`, cyclictest: one thread, same interval, loops, priority and CPU"
        + (f"; against: the checkout {against}, in each round beside this one" if against else "")
    )
    L.extend(table_lines(s))
    L.extend(_details(s))
    L.extend(_targets(s))
