"""The example law of docs/YOUR_CONTROLLER.md (examples/laws/complex_vector_pi), built from a copy of its
folder outside the repository, over vcan: in lockstep its traces are the direct run's bit for bit (the
same C in the drive node as in-process). The law as the Cortex-M4F image (`--drive mcu`: the image runs on
the host under qemu-system-arm, not nested in this VM) is tests/host/test_example_law.py's."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.paths import REPO

LAW = REPO / "examples" / "laws" / "complex_vector_pi"
STEP = REPO / "examples" / "scenarios" / "complex_vector_pi_step.toml"


@pytest.fixture(scope="module")
def law_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("user") / "complex_vector_pi"
    shutil.copytree(LAW, d)
    res = subprocess.run(["make", f"LAW={d}"], cwd=REPO, capture_output=True, text=True, timeout=1800)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return d


def run(law: Path, out: Path, *args: str) -> tuple[dict[str, Any], Any]:
    bench_cli("run", STEP, "--law", law, "--no-viewer", "--out", out, *args, timeout=1800, expect=0)
    return json.loads((out / "summary.json").read_text()), np.load(out / "traces.npy")


def test_lockstep_over_vcan_equals_direct_bit_for_bit(law_copy: Path, vcan0: str, tmp_path: Path) -> None:
    _, direct = run(law_copy, tmp_path / "direct", "--bus", "direct")
    summary, vcan = run(law_copy, tmp_path / "vcan", "--bus", vcan0)
    assert summary["status"] == "ok" and summary["bus_stats"]["lost_frames"] == 0
    assert set(vcan.dtype.names) == set(direct.dtype.names)
    for col in direct.dtype.names:
        np.testing.assert_array_equal(vcan[col], direct[col], err_msg=col)
    assert np.nanmax(direct["iq_A"]) > 0.9  # the step happened
