"""Every refusal a scenario can provoke in a node's configuration is reported the same way on the fast path of a
sweep point (direct bus, expedited SDO transfers in one C call: bench/run/bus/direct_sdo.py) as on python
canopen's own client: the scenario key and value, the node, the EDS object, the period, the SDO abort code and
the EDS's limits (bench/run/loop/configure.py). Each case is provoked by running the point, once on each path.

The cases cover each kind of check a node makes on a written value: the drive's law (a bandwidth against Ts,
a pipeline rule, a command refused in the present state: at configuration and at an event's period), the
drive's own EDS limit on a value the bench derives from the plant, and the plant's model (its dead time
against the PWM period)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from bench.paths import REPO
from bench.run.loop import session
from bench.sweep.point import run_point

YOU = REPO / "scenarios" / "you2019_step.toml"
YAO = REPO / "scenarios" / "yao2020_identification.toml"
PLANT_ID, DRIVE_ID = 0x10, 0x20

CASES = [
    # (scenario, overrides, the key named, node, EDS object, period, abort code, what the EDS says)
    (YOU, {"controller.pi_bandwidth_Hz": "50000"}, "controller.pi_bandwidth_Hz = 50000", DRIVE_ID,
     "Online tuning.pi_bandwidth_Hz", 0, 0x06040043, "range 1 .. 100000"),
    (YOU, {"controller.estimator_bandwidth_Hz": "20000"}, "controller.estimator_bandwidth_Hz = 20000", DRIVE_ID,
     "Online tuning.estimator_bandwidth_Hz", 0, 0x06040043, "1/(2 Ts) = 9090.91"),
    (YOU, {"controller.deadtime_comp_enable": "1", "controller.estimator_enable": "0"},
     "controller.estimator_enable = 0", DRIVE_ID, "Online tuning.estimator_enable", 0, 0x06040043, "range 0 .. 1"),
    # a plant without resistance is a model the plant takes; the drive's estimate starts from it and is refused
    (YOU, {"motor.R_ohm": "0"}, "controller.R_hat_ohm = 0", DRIVE_ID, "Controller.R_hat_ohm", 0, 0x06090032,
     "range 0.0001 .. 1000"),
    (YOU, {"drive.t_dead_s": "1e-4"}, "drive.t_dead_s = 0.0001", PLANT_ID, "Inverter.t_dead_s", 0, 0x06040043,
     "must be < PWM period"),
    # Yao 2020's identification: refused before the loop has run a step, and without the observer at its event
    (YAO, {"controller.ident_command": "1"}, "controller.ident_command = 1", DRIVE_ID, "Yao 2020 DPCC.ident_command",
     0, 0x08000022, "range 0 .. 2"),
    (YAO, {"controller.observer_enable": "0"}, "controller.ident_command = 1", DRIVE_ID,
     "Yao 2020 DPCC.ident_command", 200, 0x06040043, "range 0 .. 2"),
]  # fmt: skip


def _reason(path: Path, overrides: dict[str, str]) -> dict[str, Any]:
    return run_point(path.read_text(), str(path), ["scenario.periods=400"], overrides)


@pytest.mark.parametrize("path,overrides,key,node,obj,period,code,eds", CASES, ids=[str(c[1]) for c in CASES])
def test_a_refusal_is_named_alike_on_both_sdo_paths(
    monkeypatch: pytest.MonkeyPatch,
    path: Path,
    overrides: dict[str, str],
    key: str,
    node: int,
    obj: str,
    period: int,
    code: int,
    eds: str,
) -> None:
    fast = _reason(path, overrides)
    assert fast["status"] == "refused", fast
    reason = fast["reason"]
    assert reason.startswith(f"{key} refused by node 0x{node:02X} (object {obj!r}) at period {period}: "), reason
    assert f"Code 0x{code:08X}" in reason, reason
    assert eds in reason.split("; the EDS says: ", 1)[1], reason
    # python canopen's own client on the same in-process bus: the fast path not installed
    monkeypatch.setattr(session.DirectSdo, "install", lambda self: None)
    slow = _reason(path, overrides)
    assert slow["status"] == "refused" and slow["reason"] == reason
