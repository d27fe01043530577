"""Every traced signal of each controller reaches the Rerun recording of a `bench run` (read
back from run.rrd), in the panel of its unit, and the plots exist; the report's checks rely
on the same recording."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rrd_util import read_recording

from bench.pytest_plugin.fixture import HilRunner
from bench.signals import unit_of

SCENARIO = """
[scenario]
name = "{name}"
periods = 400
[motor]
preset = "{preset}"
mech_mode = "locked"
[drive]
t_dead_s = 0.0
encoder_lines = 0
[controller]
controller = "{controller}"
{extra}
[[events]]
at_period = 40
references = {{ iq_ref_A = 1.0 }}
[trace]
pdo3 = {pdo3}
pdo4 = {pdo4}
"""

CASES = {
    "you2019": (
        "you2019",
        "deadbeat_you2019",
        "enable = 1",
        ["Online tuning.det_A2", "Online tuning.K1_hat_V_A"],
        ["Online tuning.K1_active_V_A", "Online tuning.L_hat_H"],
    ),
    "yao2020": (
        "yao2020_low",
        "dpcc_yao2020",
        "observer_enable = 1\nR_hat_ratio = 1.5",
        ["Yao 2020 DPCC.R_hat_ohm", "Yao 2020 DPCC.L_hat_H"],
        ["Yao 2020 DPCC.p_hat_d_A", "Yao 2020 DPCC.p_hat_q_A"],
    ),
    "zhao2022": (
        "zhao2022",
        "incremental_zhao2022",
        "Vmax_V = 16.0",
        ["Zhao 2022.K1_V_A", "Zhao 2022.K2_V_A"],
        ["Zhao 2022.limited"],
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_signal_of_the_controller_is_in_the_recording(hil_run: HilRunner, tmp_path: Path, case: str) -> None:
    preset, controller, extra, pdo3, pdo4 = CASES[case]
    path = tmp_path / f"{case}.toml"
    path.write_text(
        SCENARIO.format(
            name=case, preset=preset, controller=controller, extra=extra, pdo3=json.dumps(pdo3), pdo4=json.dumps(pdo4)
        )
    )
    run = hil_run(path, bus="direct", timeout=300)
    assert run.exit_code == 0, run.stdout + run.stderr
    out = run.folder
    tr = run.traces
    rec = read_recording(out / "run.rrd")
    by_name = {p.rsplit("/", 1)[-1]: (p, v) for p, v in rec.items()}
    signals = [n for n in tr.dtype.names if n not in ("period", "t_s")]
    own = [n for n in signals if n.startswith(("Yao_2020", "Zhao_2022", "det_A2", "K1_", "L_hat"))]
    assert len(own) >= 3, signals  # the controller's own quantities are traced
    for name in signals:
        assert name in by_name, f"{name} missing from run.rrd ({sorted(by_name)})"
        entity, got = by_name[name]
        assert len(got["period"]) == len(tr), name
        np.testing.assert_array_equal(got["value"], tr[name], err_msg=name)
        unit_group = entity.strip("/").split("/")[0]
        assert unit_group, entity
    # one panel per unit: quantities of different units never share an entity group
    groups: dict[str, set[str]] = {}
    for name in signals:
        groups.setdefault(by_name[name][0].strip("/").split("/")[0], set()).add(unit_of(name))
    assert all(len(units) == 1 for units in groups.values()), groups
    assert run.summary["identified"]["controller"] == controller
    assert (out / "overview.svg").stat().st_size > 0 and list(out.glob("step_*.svg"))


def _svg_boxes(path: Path) -> tuple[tuple[float, float], list[tuple[float, float, float, float, str | None]]]:
    """The document's size and each stacked chart's (x, y, width, height, viewBox) as the SVG declares them."""
    import xml.etree.ElementTree as ET

    root = ET.parse(path).getroot()
    vb = [float(v) for v in root.get("viewBox", "").split()]
    assert vb[:2] == [0, 0] and vb[2:] == [float(root.get("width", 0)), float(root.get("height", 0))]
    boxes = []
    for c in root.findall("{http://www.w3.org/2000/svg}svg"):
        w, h = c.get("width"), c.get("height")  # absent: 100% of the document (SVG 1.1, 5.1.2)
        boxes.append(
            (
                float(c.get("x", 0)),
                float(c.get("y", 0)),
                float(w) if w else vb[2],
                float(h) if h else vb[3],
                c.get("viewBox"),
            )
        )
    return (vb[2], vb[3]), boxes


def _plot_inputs() -> tuple[dict[str, Any], dict[str, Any], dict[str, tuple[np.ndarray, ...]]]:
    """A step window, its step and three signals' envelopes, made up: what the plots draw."""
    k = np.arange(-5, 30)
    win = {"at_period": 20, "period": 20 + k, "iq_A": (k > 1).astype(float), "iq_ref_A": (k >= 0).astype(float)}
    win["vq_V"] = 80.0 * (k == 1)
    step = {"at_period": 20, "signal": "iq", "periods_to_settle": 2, "from_A": 0.0, "to_A": 1.0, "overshoot_A": 0.0}
    start = np.arange(0, 400, 4)
    env = {n: (start, np.sin(start / 50.0), np.sin(start / 50.0) + 0.1) for n in ("iq_A", "vq_V", "omega_rad_s")}
    return win, step, env


def test_stacked_plots_declare_each_panel_where_it_is_drawn(tmp_path: Path) -> None:
    """Each panel of a step plot / the overview is a nested <svg>: with its own size it sits in its band of
    the document; without (as before), Chromium scaled each into the whole document: ~600 px blank atop the
    overview, the step plot's voltage panel clipped. Geometry from the SVG itself: the panels tile the
    document, each at the scale 1 of its viewBox."""
    from bench.view.plots import overview_plot, step_plots

    win, step, env = _plot_inputs()
    paths = [*step_plots(tmp_path, [win], [step], "t"), overview_plot(tmp_path, env, "t", 1e-4)]
    assert len(paths) == 2
    for path in paths:
        assert path is not None
        (width, height), boxes = _svg_boxes(path)
        assert len(boxes) >= 2, path.name
        y = 0.0
        for x, top, w, h, vb in boxes:
            assert vb is not None
            assert [float(v) for v in vb.split()] == [0, 0, w, h], (path.name, vb, w, h)  # scale 1, not fitted
            assert x == 0 and top == y and w <= width, (path.name, top, y)  # stacked, no gap, no overlap
            y += h
        assert y == height, path.name  # the panels fill the document: no blank band, none cut off


def test_the_cheap_lookup_draws_pygals_own_svg(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """bench.view.plots.XY (pygal's XY with a cheaper attribute lookup) draws the SVG pygal's own XY draws, but for
    the random ids pygal gives each chart: a pygal whose lookup gives other values for these plots fails here."""
    import re

    import pygal

    from bench.view import plots

    win, step, env = _plot_inputs()

    def drawn(folder: Path) -> list[str]:
        folder.mkdir()
        paths = [*plots.step_plots(folder, [win], [step], "t"), plots.overview_plot(folder, env, "t", 1e-4)]
        ids = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
        return [ids.sub("ID", p.read_text()) for p in paths if p is not None]

    cheap = drawn(tmp_path / "cheap")
    monkeypatch.setattr(plots, "XY", pygal.XY)
    assert len(cheap) == 2 and cheap == drawn(tmp_path / "pygal")


@pytest.mark.parametrize("rows_n", [2, 3, 12])
def test_sweep_heatmap_text_stays_inside_the_figure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, rows_n: int
) -> None:
    """Everything drawn on the sweep's heat-map (the colour bar's label above all: cut at both ends on a
    small grid) lies inside the figure when it is saved: the tight box matplotlib's renderer gives."""
    from matplotlib.figure import Figure

    from bench.sweep.report import heatmap

    seen: list[list[str]] = []
    save = Figure.savefig

    def checked(fig: Figure, *args: object, **kwargs: object) -> None:
        fig.canvas.draw()
        drawn = fig.get_tightbbox(fig.canvas.get_renderer())  # type: ignore[attr-defined]
        page = fig.bbox_inches  # what is drawn (ticks out of view excluded) against the page, inches
        tol = 0.02
        seen.append(
            [
                side
                for side, out in (
                    ("left", drawn.x0 < page.x0 - tol),
                    ("right", drawn.x1 > page.x1 + tol),
                    ("bottom", drawn.y0 < page.y0 - tol),
                    ("top", drawn.y1 > page.y1 + tol),
                )
                if out
            ]
        )
        save(fig, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Figure, "savefig", checked)
    v1 = [f"{0.5 + 0.1 * i:.1f}" for i in range(rows_n)]
    v2 = ["1.0", "1.5"]
    rows = [{"a": a, "b": b, "periods_to_settle": 2 + i} for i, a in enumerate(v1) for b in v2]
    heatmap(tmp_path / "h.png", [("a", v1), ("b", v2)], rows, "periods_to_settle", "t")
    assert seen == [[]], seen
