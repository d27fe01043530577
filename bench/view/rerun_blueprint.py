"""The layout of a run's Rerun recording: entities grouped by SI unit, `/{unit_slug}/{column}` (`/A/iq_A`,
`/V_per_A/K1_active_V_A`, `/H/L_hat_H`, `/count_or_ratio/sync_counter`), and a blueprint with one time-series
view per unit, so quantities of different units never share an axis; in a real-time run a timing view of the SYNC
lateness and the turnaround per period (`/timing/...`, us); with faults, an events panel under the plots
(bench/view/rerun_sink.py logs into both)."""

from __future__ import annotations

import math
import re
from typing import Any

import rerun as rr
import rerun.blueprint as rrb

from bench.signals import SignalInfo

# The [view] extra installs rerun-sdk 0.41 beside numpy 2 and 0.23.1 beside numpy 1.x (pyproject.toml). The bench's
# calls are the same in both but for what 0.23 lacks: TimePanel's timeline (here), spawn()'s server_memory_limit and
# executable_path and flush()'s timeout (bench/view/rerun_sink.py). The one version check, used where they differ.
RERUN_0_23 = tuple(int(x) for x in rr.__version__.split(".")[:2] if x.isdigit()) < (0, 24)

# A readable view name per unit (the quantity plotted); any other unit is named by itself.
QUANTITY_OF_UNIT: dict[str, str] = {
    "A": "currents",
    "V": "voltages",
    "V/A": "gains",
    "H": "inductances",
    "Ω": "resistances",
    "A²": "squared currents",
    "Wb": "flux linkages",
    "rad": "angles",
    "rad/s": "speeds",
    "rad/s²": "accelerations",
    "N·m": "torques",
    "kg·m²": "inertias",
    "Hz": "frequencies",
    "J": "energies",
    "s": "times",
    "Ω/(V·s)": "adaptation gains",
    "H/(V·s)": "adaptation gains",
}
# Order of the views: currents and voltages on top (large), the others in a grid below in this
# order, then any unit not listed here alphabetically.
TOP_UNITS = ("A", "V")
GRID_ORDER = (
    "V/A",
    "H",
    "Ω",
    "A²",
    "Wb",
    "rad",
    "rad/s",
    "rad/s²",
    "N·m",
    "kg·m²",
    "Hz",
    "J",
    "s",
    "Ω/(V·s)",
    "H/(V·s)",
    "1",
)
TIMING = "timing"  # the entities of a real-time run's timing, /timing/sync_lateness_us and /timing/turnaround_us
TIMING_VIEW = "real-time timing (µs): SYNC lateness, turnaround"


def unit_slug(unit: str) -> str:
    """An entity-path-safe name of a unit: 'V/A' -> 'V_per_A', 'Ω' -> 'ohm', 'A²' -> 'A2', '1' -> 'count_or_ratio'."""
    if unit in ("1", ""):
        return "count_or_ratio"
    s = unit.replace("Ω", "ohm").replace("µ", "u").replace("°", "deg").replace("²", "2").replace("³", "3")
    s = s.replace("/", "_per_").replace("·", "_").replace("*", "_").replace(" ", "_")
    s = re.sub(r"[^A-Za-z0-9_]", "_", s)
    s = re.sub(r"_+", "_", s).strip("_")
    return s or "unitless"


def view_name(unit: str) -> str:
    """'A' -> 'currents (A)', '1' -> 'counts and ratios', an unknown unit -> the unit itself."""
    if unit in ("1", ""):
        return "counts and ratios"
    quantity = QUANTITY_OF_UNIT.get(unit)
    return f"{quantity} ({unit})" if quantity else unit


def entity_path(signal: SignalInfo) -> str:
    return f"/{unit_slug(signal.unit)}/{signal.name}"


def _unit_order(unit: str) -> tuple[int, str]:
    order = TOP_UNITS + GRID_ORDER
    return (order.index(unit), "") if unit in order else (len(order), unit)


def _time_panel(timeline: str) -> rrb.TimePanel:
    """The time panel, collapsed, on `timeline` (rerun-sdk 0.23: on the recording's first timeline, `period`)."""
    return rrb.TimePanel(state="collapsed") if RERUN_0_23 else rrb.TimePanel(state="collapsed", timeline=timeline)


def _window(seconds: float | None) -> dict[str, Any]:
    """A view's time range: the last `seconds` of simulated time before the time cursor (None: the whole run).

    A live viewer that draws the whole run at every frame falls behind as the run grows (a 10^6-period run at 100 us,
    watched in headless Chromium: 5 s behind after 12 s, 22 s after 102 s); a window keeps what each frame draws
    constant. The cursor follows the live edge, so the window scrolls with the run."""
    if seconds is None:
        return {}
    start = rrb.TimeRangeBoundary.cursor_relative(seconds=-seconds)
    return {"time_ranges": [rrb.VisibleTimeRange("sim_time", start=start, end=rrb.TimeRangeBoundary.cursor_relative())]}


def blueprint_for(signals: list[SignalInfo], timing: bool = False, window_s: float | None = None) -> rrb.Blueprint:
    """One TimeSeriesView per unit present (origin `/{unit_slug}`): currents and voltages large on
    top, the other units in a grid below; `timing` (a real-time run): the timing view under the top ones. `window_s`
    (the live viewer's): each view shows the last `window_s` simulated seconds before the time cursor."""
    units = sorted({s.unit for s in signals}, key=_unit_order)
    win = _window(window_s)
    views = {
        u: rrb.TimeSeriesView(origin=f"/{unit_slug(u)}", contents="$origin/**", name=view_name(u), **win) for u in units
    }
    top = [views[u] for u in TOP_UNITS if u in views]
    rest = [views[u] for u in units if u not in TOP_UNITS]
    parts: list[rrb.Container | rrb.View] = list(top)
    shares = [3.0] * len(top)
    if timing:
        parts.append(rrb.TimeSeriesView(origin=f"/{TIMING}", contents="$origin/**", name=TIMING_VIEW, **win))
        shares.append(2.0)
    if rest:
        columns = min(len(rest), 3)
        parts.append(rrb.Grid(*rest, grid_columns=columns))
        shares.append(2.0 * math.ceil(len(rest) / columns))
    if not parts:
        root: rrb.Container = rrb.Vertical()
    elif len(parts) == 1 and isinstance(parts[0], rrb.Container):
        root = parts[0]
    else:
        root = rrb.Vertical(*parts, row_shares=shares)
    return rrb.Blueprint(
        root,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        _time_panel("sim_time"),
        auto_views=False,
    )


def events_blueprint(signals: list[SignalInfo], timing: bool = False, window_s: float | None = None) -> rrb.Blueprint:
    """The blueprint of `blueprint_for` with a text-log panel of the faults and the nodes' reactions
    (origin `/events`) under the plots, on the period timeline."""
    views = blueprint_for(signals, timing, window_s)
    panel = rrb.TextLogView(origin="/events", name="Faults and reactions")
    return rrb.Blueprint(
        rrb.Vertical(views.root_container, panel, row_shares=[4.0, 1.0]) if views.root_container else panel,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        _time_panel("period"),
        auto_views=False,
    )
