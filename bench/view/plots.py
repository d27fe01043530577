"""Plots of a run, from its result (no file read back): one per reference step, and an
overview of the whole run (min/max envelopes: a run of any length costs the same); a real-time
run's overview ends with a timing panel (its envelopes named by bench/run/verdict/realtime.py).

SVG through pygal: it imports in ~0.1 s where matplotlib takes ~1 s, which is most of a short
run's wall time; SVG is what browsers, the reports and GitHub show, and it stays sharp when
zoomed. No script is embedded (the files work offline and inside <img>)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pygal
from pygal.style import Style

from bench.run.verdict.realtime import ENVELOPE, LATENESS_ENV, PLANT_ENV, TURNAROUND_ENV
from bench.signals import unit_of

LOG_FLOOR_US = 0.1  # the timing panel's logarithmic axis starts here (a SYNC on its grid is 0 us late)
# Bus bookkeeping, not signals of the loop: in the summary, not in the overview.
BOOKKEEPING = {"sync_counter", "sample_index"}
STYLE = Style(
    background="white",
    plot_background="white",
    font_family="DejaVu Sans, sans-serif",
    title_font_size=13,
    label_font_size=10,
    major_label_font_size=10,
    legend_font_size=10,
    colors=(
        "#000000",
        "#1f77b4",
        "#d62728",
        "#2ca02c",
        "#ff7f0e",
        "#9467bd",
        "#8c564b",
        "#e377c2",
        "#7f7f7f",
        "#17becf",
    ),
)


class XY(pygal.XY):
    """pygal's XY chart with its attribute lookup made cheap: pygal's (3.1) BaseGraph.__getattribute__ looks every
    attribute up in the chart's render state through two more Python-level lookups, ~9 per plotted value (180,000
    calls for the overview of a short run: 0.135 s of its 0.15 s). The same lookup, in the same order (the render
    state's own values first, then the chart's), without the recursion: the same SVG (its class name is pygal's
    "xy-graph" still), in half the time."""

    def __getattribute__(self, name: str) -> Any:
        state = object.__getattribute__(self, "__dict__").get("state")
        if state is not None and name != "state" and name[:2] != "__":
            values = state.__dict__
            if name in values:
                return values[name]
        return object.__getattribute__(self, name)


def _chart(title: str, x_title: str, y_title: str, width: int = 760, height: int = 330) -> pygal.XY:
    return XY(
        title=title,
        x_title=x_title,
        y_title=y_title,
        width=width,
        height=height,
        style=STYLE,
        show_dots=False,
        stroke_style={"width": 1.4},
        js=[],
        disable_xml_declaration=True,
        legend_at_bottom=True,
        # pygal lays the bottom legend out as if there were no x title: room for it, or it is cut off
        margin_bottom=40 if x_title else None,
        legend_at_bottom_columns=4,
        truncate_legend=-1,
        x_labels_major_count=8,
        show_minor_x_labels=False,
        y_labels_major_count=6,
        show_minor_y_labels=False,
        print_values=False,
        allow_interruptions=True,
        dynamic_print_values=False,
        value_formatter=lambda v: f"{v:.4g}",
        x_value_formatter=lambda v: f"{v:.4g}",
    )


def _pts(x: np.ndarray, y: np.ndarray, steps: bool = False) -> list[tuple[float, float | None]]:
    """(x, y) points; None where y is not finite (a gap); `steps` draws a zero-order hold."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if steps and len(x) > 1:
        x = np.repeat(x, 2)[1:]
        y = np.repeat(y, 2)[:-1]
    return [(float(a), float(b) if np.isfinite(b) else None) for a, b in zip(x, y, strict=True)]


def _svg(*charts: pygal.XY) -> str:
    """One SVG document with the charts stacked (pygal draws one chart per document)."""
    parts, y, width = [], 0, 0
    for c in charts:
        body = c.render(is_unicode=True)
        h, w = c.config.height, c.config.width
        # its own width and height: a nested <svg> without them is 100% of the document (SVG 1.1 5.1.2),
        # its viewBox then scaled into the whole stack and centred (blank bands, the next panel clipped)
        body = re.sub(r"^<svg ", f'<svg x="0" y="{y}" width="{w}" height="{h}" ', body, count=1)
        parts.append(body)
        y += h
        width = max(width, w)
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
        f'width="{width}" height="{y}" viewBox="0 0 {width} {y}">' + "".join(parts) + "</svg>\n"
    )


def step_plots(
    out: Path, windows: list[dict[str, Any]], steps: list[dict[str, Any]], title: str, limit: int = 12
) -> list[Path]:
    """One figure per reference step (the first `limit`): the sampled current against its reference,
    and the voltage command below it."""
    paths = []
    for i, s in enumerate(steps[:limit]):
        p, sig = int(s["at_period"]), str(s["signal"])
        w = next((w for w in windows if int(w["at_period"]) == p and f"{sig}_A" in w), None)
        if w is None:
            continue
        k = w["period"] - p
        settle = s["periods_to_settle"]
        cur = _chart(
            f"{title}: {sig} {s['from_A']:.3g} -> {s['to_A']:.3g} A at period {p}: settles in "
            f"{'never' if settle is None else settle} periods, overshoot {s['overshoot_A']:.3g} A",
            "",
            "current (A)",
        )
        cur.add(f"{sig}* (A)", _pts(k, w[f"{sig}_ref_A"], steps=True))
        cur.add(f"{sig} sampled (A)", _pts(k, w[f"{sig}_A"]), show_dots=True, dots_size=2)
        charts = [cur]
        vname = "vq_V" if sig == "iq" else "vd_V"
        if vname in w:
            volt = _chart("", "control periods after the reference step", "voltage command (V)", height=270)
            volt.add(f"{vname[:2]}* (V)", _pts(k, w[vname], steps=True))
            charts.append(volt)
        path = out / f"step_{i:02d}_{sig}_p{p}.svg"
        path.write_text(_svg(*charts))
        paths.append(path)
    return paths


def _coarser(start: np.ndarray, lo: np.ndarray, hi: np.ndarray, points: int) -> tuple[np.ndarray, ...]:
    """Merge neighbouring buckets until at most `points` remain (min of the minima, max of the maxima)."""
    k = int(np.ceil(len(start) / points))
    if k <= 1:
        return start, lo, hi
    n = len(start) // k * k
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN buckets stay NaN
            return (start[:n:k], np.nanmin(lo[:n].reshape(-1, k), axis=1), np.nanmax(hi[:n].reshape(-1, k), axis=1))


def overview_plot(
    out: Path,
    envelopes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    title: str,
    ts_s: float,
    name: str = "overview.svg",
    max_panels: int = 8,
) -> Path | None:
    """Every traced signal over the whole run, one panel per unit (as in the Rerun view): the min and
    the max over each bucket of periods (equal where a bucket is one period); references as lines. A
    real-time run's timing last (`timing_chart`)."""
    by_unit: dict[str, list[str]] = {}
    for n in envelopes:
        if n not in BOOKKEEPING and not n.startswith(ENVELOPE):
            by_unit.setdefault(unit_of(n), []).append(n)
    order = sorted(by_unit, key=lambda u: (u not in ("A", "V"), u != "A", u))[:max_panels]
    timing = timing_chart(envelopes, ts_s)
    if not order and timing is None:
        return None
    charts = []
    last = len(order) - 1 if timing is None else len(order)
    for j, unit in enumerate(order):
        c = _chart(title if j == 0 else "", "simulated time (s)" if j == last else "", unit, height=250)
        for n in by_unit[unit]:
            start, lo, hi = _coarser(*envelopes[n], points=250)
            t = start * ts_s
            if n.endswith("_ref_A") or np.array_equal(lo, hi, equal_nan=True):
                c.add(n, _pts(t, hi, steps=True))
            else:
                c.add(f"{n} max", _pts(t, hi, steps=True))
                c.add(f"{n} min", _pts(t, lo, steps=True))
        charts.append(c)
    if timing is not None:
        if not order:
            timing.config.title = f"{title}: {timing.config.title}"
        charts.append(timing)
    path = out / name
    path.write_text(_svg(*charts))
    return path


def timing_chart(envelopes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], ts_s: float) -> pygal.XY | None:
    """A real-time run's timing, per bucket of periods: the bus-side SYNC lateness (its grid anchored per segment)
    and the turnaround (SYNC to the command), the largest of each bucket, with the period Ts as a line; the plant's
    own p99 and max in the title. A logarithmic axis (decades, values below LOG_FLOOR_US drawn at it) when the worst
    is far beyond the usual. None in lockstep."""
    series = [
        (n, label) for n, label in ((LATENESS_ENV, "SYNC lateness"), (TURNAROUND_ENV, "turnaround")) if n in envelopes
    ]
    if not series:
        return None
    ts_us = ts_s * 1e6
    curves = {label: _coarser(*envelopes[n], points=250) for n, label in series}
    peaks = np.concatenate([hi for _, _, hi in curves.values()])
    peaks = peaks[np.isfinite(peaks) & (peaks > 0)]
    log = bool(len(peaks)) and float(peaks.max()) > 20.0 * max(float(np.median(peaks)), LOG_FLOOR_US)
    start = next(iter(curves.values()))[0]
    c = _chart(_timing_title(envelopes), "simulated time (s)", f"µs, {_bucket(start)}", height=290)
    c.config.legend_at_bottom_columns = 3

    def y(v: np.ndarray) -> np.ndarray:  # pygal's XY scales x too when logarithmic: decades drawn by hand
        return np.log10(np.maximum(v, LOG_FLOOR_US)) if log else v

    if log:
        top = max(float(peaks.max()), ts_us)
        c.config.y_labels = list(range(int(np.log10(LOG_FLOOR_US)), int(np.ceil(np.log10(top))) + 1))
        c.config.value_formatter = lambda v: f"{10**v:.6g}"
        c.config.y_title += " (log)"
    t_end = 0.0
    for label, (start, _, hi) in curves.items():
        t = start * ts_s
        t_end = max(t_end, float(t[-1]) if len(t) else 0.0)
        c.add(f"{label} (bus)", _pts(t, y(hi), steps=True))
    c.add(f"Ts = {ts_us:.4g} µs", _pts(np.array([0.0, t_end]), y(np.array([ts_us, ts_us]))))
    return c


def _bucket(start: np.ndarray) -> str:
    """What a point is: one period, or the largest of a bucket of periods."""
    k = int(start[1] - start[0]) if len(start) > 1 else 1
    return "per period" if k == 1 else f"max per {k} periods"


def _timing_title(envelopes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]) -> str:
    """'real-time timing; plant: SYNC lateness p99 12.0 µs, max 412.3 µs; turnaround p99 ..., max ...'."""

    def fig(name: str) -> str:
        env = envelopes.get(PLANT_ENV + name)
        return "-" if env is None or not len(env[2]) else f"{float(env[2][0]):.4g} µs"

    parts = [
        f"{what} p99 {fig(f'{key}_p99_us')}, max {fig(f'{key}_max_us')}"
        for what, key in (("SYNC lateness", "sync_lateness"), ("turnaround", "turnaround"))
    ]
    plant = any(n.startswith(PLANT_ENV) for n in envelopes)
    return "real-time timing" + (f"; plant: {'; '.join(parts)}" if plant else "")
