"""`bench perf`'s report, its realtime section: per period Ts the plant's SYNC lateness (summary.json "realtime")
beside cyclictest's wake-up latency at the same interval and priority, the bench's overruns and turnaround, the
ratios bench / cyclictest and the issue's two targets (bench/tools/perf/realtime.py measures them)."""

from __future__ import annotations

from typing import Any

from bench.tools.perf.realtime import PRIORITY, TARGET_OVERRUN_TS_US, TARGET_P99_RATIO

COLS = ("p50", "p99", "p99_9", "max")


def _us(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def _x(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}x"


def _verdict(ok: bool | None) -> str:
    return "not judged" if ok is None else ("met" if ok else "NOT met")


def table_lines(s: dict[str, Any]) -> list[str]:
    """The side-by-side table: for each Ts a bench row, a cyclictest row and a ratio row."""
    out = [
        f"  {'lateness us':<30}"
        + "".join(f"{c.replace('_', '.'):>8}" for c in COLS)
        + f"{'overruns':>10}{'sync ovr':>10}   turnaround us p50 / p99 / max"
    ]
    for key, row in s["runs"].items():
        b, c, cmp_ = row["bench"], row["cyclictest"], row["compare"]
        ts = f"Ts {key} us"
        if "error" in b:
            out.append(f"  {ts:<11}{'bench':<19}ERROR {b['error']}")
        else:
            lat, cnt, tr = b["lateness_us"], b["counts"], b["turnaround_us"]
            out.append(
                f"  {ts:<11}{'bench':<19}"
                + "".join(f"{_us(lat.get(k)):>8}" for k in COLS)
                + f"{cnt.get('overruns')!s:>10}{cnt.get('sync_overruns')!s:>10}"
                + f"   {_us(tr.get('p50'))} / {_us(tr.get('p99'))} / {_us(tr.get('max'))}"
            )
        if "error" in c:
            out.append(f"  {'':<11}{'cyclictest':<19}ERROR {c['error']}")
        else:
            lat = c["lateness_us"]
            out.append(
                f"  {'':<11}{'cyclictest':<19}"
                + "".join(f"{_us(lat.get(k)):>8}" for k in COLS)
                + f"{'':>10}{c.get('over_period', '-')!s:>10}"
            )
        out.append(
            f"  {'':<11}{'bench / cyclictest':<19}{'':>8}{_x(cmp_.get('p99_ratio')):>8}{'':>8}"
            f"{_x(cmp_.get('max_ratio')):>8}"
        )
    return out


def _details(s: dict[str, Any]) -> list[str]:
    """Per Ts: the bench's status and exit status, what it said about its priority, its bus-side view."""
    out = []
    for key, row in s["runs"].items():
        b = row["bench"]
        if "error" in b:
            continue
        cnt = b["counts"]
        out.append(
            f"  Ts {key} us: status {b['status']} (exit {b['exit_status']}), {b['periods']:,} periods in "
            f"{b['wall_s']:.0f} s whole process; missed {cnt.get('missed_commands')}, late "
            f"{cnt.get('late_commands')}, worst period {b.get('worst_period')}"
        )
        bus = b.get("bus") or {}
        sl, iv = bus.get("sync_lateness_us") or {}, bus.get("sync_interval_us") or {}
        if sl:
            out.append(
                f"    bus view (frame stamps): SYNC lateness p99 {_us(sl.get('p99'))} max {_us(sl.get('max'))} us; "
                f"SYNC interval min {_us(iv.get('min'))} p50 {_us(iv.get('p50'))} max {_us(iv.get('max'))} us"
            )
        out.extend(f"    {n}" for n in b.get("notes", []))
    return out


def _targets(s: dict[str, Any]) -> list[str]:
    p99 = "; ".join(
        f"Ts {k} us {_x(r['compare'].get('p99_ratio'))} {_verdict(r['compare'].get('p99_target_met'))}"
        for k, r in s["runs"].items()
    )
    out = [f"  target: plant lateness p99 <= {TARGET_P99_RATIO:g}x cyclictest's p99: {p99}"]
    for k, r in s["runs"].items():
        if r["ts_us"] != TARGET_OVERRUN_TS_US:
            continue
        cmp_ = r["compare"]
        note = f" ({cmp_['overrun_target_note']})" if cmp_.get("overrun_target_note") else ""
        out.append(
            f"  target: 0 overruns at Ts = {k} us when cyclictest's max < the period: "
            f"{_verdict(cmp_.get('overrun_target_met'))}{note}"
        )
    return out


def format_realtime(r: dict[str, Any], L: Any) -> None:
    """The realtime section of the report (L: report._Lines); nothing when it was not run."""
    s = L.sec(r, "realtime", f"real time: SYNC lateness beside cyclictest (SCHED_FIFO {PRIORITY}, mlockall)")
    if s is None:
        return
    L.append(
        f"  {s['sizes']['periods']:,} periods at each Ts; load: {s['load']}; bench: `bench run {s['scenario']} "
        "--bus direct --set scenario.timing=realtime`, cyclictest: one thread, same interval, loops and priority"
    )
    L.extend(table_lines(s))
    L.extend(_details(s))
    L.extend(_targets(s))
