"""Direct mode keeps the master's canopen Network and RemoteNodes between the runs of a process
(bench/run/loop/master.py): a run after other runs, whatever they were (another law, trace PDOs mapped, a refusal
in the middle of the configuration, faults), gives the row it gives in a fresh process."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

from canopen.sdo import SdoClient

from bench.eds import default_node_id
from bench.paths import REPO
from bench.run.loop import master
from bench.sweep.point import run_point

SC = REPO / "scenarios"
CASES: list[tuple[str, dict[str, str]]] = [
    ("you2019_step.toml", {"controller.L_hat_ratio": "0.7"}),
    ("yao2020_identification.toml", {}),  # trace TPDO3 and TPDO4 mapped, an identification run
    ("you2019_step.toml", {"controller.pi_bandwidth_Hz": "50000"}),  # refused in the configuration
    ("zhao2022_stability.toml", {}),
    ("faults/you2019_drop_command.toml", {}),  # the fault injector in the loop
]
TIMING = {"loop_s", "point_s", "worker_pid"}


def _row(name: str, overrides: dict[str, str]) -> dict[str, Any]:
    path = SC / name
    row = run_point(path.read_text(), str(path), ["scenario.periods=600"], overrides)
    return {k: v for k, v in row.items() if k not in TIMING}


def _fresh(name: str, overrides: dict[str, str]) -> dict[str, Any]:
    code = (
        "import json, sys; from tests.host.test_kept_master import _row; "
        f"print(json.dumps(_row({name!r}, {overrides!r})))"
    )
    res = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def test_a_run_after_other_runs_is_a_fresh_processs_run() -> None:
    fresh = [_fresh(*c) for c in CASES]
    assert fresh[2]["status"] == "refused" and all(r["status"] != "refused" for i, r in enumerate(fresh) if i != 2)
    ids = (default_node_id("plant"), default_node_id("drive"))
    first = master.take(*ids)
    master.give_back(first)
    for order in (range(len(CASES)), reversed(range(len(CASES)))):
        for i in order:
            got = json.loads(json.dumps(_row(*CASES[i])))  # as the fresh rows went through JSON
            assert got == fresh[i], CASES[i]
    kept = master.take(*ids)
    try:
        assert kept is first  # every run above ran on it and gave it back
        assert master.take(*ids) is not kept  # while taken, a second run at the same time gets its own
        # the fast SDO path of the last run falls back on canopen's own transfers, not on an earlier run's path
        # (a chain one run longer each time: a recursion error a thousand points into a study)
        for n in (kept.plant, kept.drive):
            assert n.sdo.download.__self__._download.__func__ is SdoClient.download
            assert n.sdo.upload.__self__._upload.__func__ is SdoClient.upload
    finally:
        master.give_back(kept)
