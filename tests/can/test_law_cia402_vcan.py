"""CiA 402 through a user's current law (issue 26: the profile works for a user's law unchanged):
`bench run --drive-profile cia402 --law DIR` over vcan0 against the stand-in drive (tests/can/cia402_standin.py)
built with the example law examples/laws/complex_vector_pi (make LAW=DIR) and running it. The master does
not know the law: it drives the CiA 402 state machine and the CST target torque; the torque is the law's.
On a host without kernel CAN the stand-in runs in the CAN box and the master on the host, on the slot's tap
(tests/can/test_cia402_master_vcan.py).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import canopen
import pytest
from bench_cli import bench_cli
from can_site import Site
from cia402_standin import DRIVE_ID, StandIn

from bench.eds import value_names
from bench.law import build, law_name
from bench.paths import REPO

CYCLE_MS = 50  # as tests/can/test_cia402_master_vcan.py: the box's guest stalls processes up to ~150 ms
LAW = REPO / "examples" / "laws" / "complex_vector_pi"
STEP = REPO / "scenarios" / "you2019_step.toml"


def _select_law(eds: Path):  # type: ignore[no-untyped-def]
    def select(drive: canopen.RemoteNode, bandwidth_Hz: float) -> int:
        drive.sdo["Complex vector PI"]["bandwidth_Hz"].raw = bandwidth_Hz  # its check is against Ts
        return value_names(eds, drive.sdo["Controller"]["controller"].od).index(law_name(LAW))

    return select


@pytest.fixture
def law_build(site: Site) -> Path:
    return build(LAW, REPO)


@pytest.fixture
def standin(law_build: Path, site: Site, monkeypatch: pytest.MonkeyPatch) -> Iterator[StandIn]:
    monkeypatch.setenv("BENCH_BIN_DIR", str(law_build / "bin"))  # the stand-in's node binaries: the law's
    eds = law_build / "eds" / "drive.eds"
    with StandIn(CYCLE_MS / 1000, site, eds_dir=law_build / "eds", law=_select_law(eds)) as s:
        yield s


def test_cst_step_through_a_users_law(standin: StandIn, law_build: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["run", str(STEP), *standin.master_args(), "--drive-profile", "cia402"]
    args += ["--cycle-ms", str(CYCLE_MS), "--law", str(LAW), "--out", str(out), "--set", "scenario.periods=80"]
    bench_cli(*args, timeout=900, expect=0)
    summary = json.loads((out / "summary.json").read_text())
    assert "OPERATION ENABLED" in summary["states_passed"], summary["states_passed"]
    step = [t for t in summary["tracking"] if t["target_permille"] == 250]
    assert step and step[0]["mean_actual_permille"] is not None, summary["tracking"]
    assert abs(step[0]["relative_error"]) <= 0.25, step
    # the drive ran the user's law all along: selected, and its status (its gains) written by the law
    net = canopen.Network()
    net.connect(**standin.site.bus_kwargs())
    try:
        eds = law_build / "eds" / "drive.eds"
        node = canopen.RemoteNode(DRIVE_ID, str(eds))
        node.sdo.RESPONSE_TIMEOUT = 5.0
        net.add_node(node)
        names = value_names(eds, node.sdo["Controller"]["controller"].od)
        assert names[int(node.sdo["Controller"]["controller"].raw)] == law_name(LAW)
        assert float(node.sdo["Complex vector PI"]["Kp_V_A"].raw) > 0.0
    finally:
        net.disconnect()
    assert standin.alive()
