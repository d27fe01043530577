"""`bench run` over vcan as a user runs it: candump's own log becomes bus.log, the results
equal a direct run's (summary and traces), and `bench replay` of that log gives them again."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from bench_cli import bench_cli

from bench.eds import default_node_id
from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.outputs import json_default
from bench.scenario import load

SCENARIO = REPO / "tests" / "scenarios" / "parity.toml"
TIMEOUT_S = 900  # Python in the VM is slow


def test_run_over_vcan_equals_direct_and_replays(vcan0: str, tmp_path: Path) -> None:
    # the direct run through the API (the CLI's direct path is tested on the host; Python in the VM is slow)
    direct = run_scenario(load(SCENARIO), RunOptions(bus="direct"), keep_trace=True)
    sd = json.loads(json.dumps(direct.summary, default=json_default))  # as summary.json has it
    td = direct.trace
    assert td is not None
    out = tmp_path / vcan0
    bench_cli("run", SCENARIO, "--bus", vcan0, "--out", out, "--no-viewer", timeout=TIMEOUT_S, expect=0)
    sv, tv = json.loads((out / "summary.json").read_text()), np.load(out / "traces.npy")
    for key in ("status", "periods", "steps", "identified", "plant", "controller", "counters"):
        assert sv[key] == sd[key], key
    assert sv["bus_stats"]["lost_frames"] == 0 and sv["status"] == "ok"
    assert set(tv.dtype.names) == set(td)
    for name in tv.dtype.names:
        if name != "t_s":
            np.testing.assert_array_equal(tv[name], td[name], err_msg=name)
    log = tmp_path / vcan0 / "bus.log"
    first = log.read_text().split("\n", 1)[0]
    assert first.startswith("(") and f" {vcan0} " in first  # candump -L: absolute kernel time stamps
    # candump listened before the bench reset the nodes: the log holds the master's NMT reset of both (in the CAN
    # box it is started with the nodes and awaited; a fixed nap once let the log begin after them)
    frames = [line.split()[2] for line in log.read_text().splitlines() if line.startswith("(")]
    resets = {f for f in frames if f.startswith("000#81")}
    assert resets == {f"000#81{default_node_id(n):02X}" for n in ("plant", "drive")}, frames[:6]
    bench_cli("replay", log, "--no-viewer", timeout=TIMEOUT_S, expect=0)
    sr = json.loads((log.parent / "replay" / "summary.json").read_text())
    for key in ("status", "steps", "identified", "counters"):
        assert sr[key] == sv[key], key
