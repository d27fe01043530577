"""Every traced signal of each controller reaches the Rerun recording of a `bench run` (read
back from run.rrd), in the panel of its unit, and the plots exist; the report's checks rely
on the same recording."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rrd_util import read_recording

from bench.paths import REPO
from bench.run.signals import unit_of

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
def test_every_signal_of_the_controller_is_in_the_recording(tmp_path: Path, case: str) -> None:
    preset, controller, extra, pdo3, pdo4 = CASES[case]
    path = tmp_path / f"{case}.toml"
    path.write_text(
        SCENARIO.format(
            name=case, preset=preset, controller=controller, extra=extra, pdo3=json.dumps(pdo3), pdo4=json.dumps(pdo4)
        )
    )
    out = tmp_path / "run"
    res = subprocess.run(
        [sys.executable, "-m", "bench.cli", "run", str(path), "--bus", "direct", "--no-viewer", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    tr = np.load(out / "traces.npy")
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
    summary = json.loads((out / "summary.json").read_text())
    assert summary["identified"]["controller"] == controller
    assert (out / "overview.svg").stat().st_size > 0 and list(out.glob("step_*.svg"))
