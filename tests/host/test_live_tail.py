"""The live view of a run in the VM follows the recorder's file: frames appended in pieces
(even cut mid-line) are decoded and streamed period by period, exactly once."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from bench.live import LiveTail
from bench.paths import REPO


def test_live_tail_streams_every_period_once(tmp_path: Path) -> None:
    run = tmp_path / "run"
    res = subprocess.run([sys.executable, "-m", "bench.cli", "run", str(REPO / "scenarios" / "you2019_step.toml"),
                          "--bus", "direct", "--out", str(run), "--no-viewer"], capture_output=True, text=True,
                         cwd=REPO, timeout=300)
    assert res.returncode == 0, res.stderr
    # Pretend the run is in progress: the recorder's file grows in arbitrary pieces.
    live = tmp_path / "live"
    live.mkdir()
    for name in ("layout.json", "capture.json"):
        (live / name).write_text((run / name).read_text())
    import json

    (live / "plant.json").write_text(json.dumps(json.loads((run / "capture.json").read_text())["plant"]))
    text = (run / "bus.log").read_text()
    got: list[tuple[int, int]] = []
    seen: dict[int, float] = {}

    def on_traces(tr: dict[str, np.ndarray], a: int, b: int) -> None:
        got.append((a, b))
        for k in range(a, b):
            assert k not in seen
            seen[k] = float(tr["iq_A"][k])

    tail = LiveTail(live, on_traces)
    with open(live / "candump.log", "w") as fh:
        for i in range(0, len(text), 997):  # cuts lines in the middle on purpose
            fh.write(text[i:i + 997])
            fh.flush()
            tail.poll()
    tail.poll()
    final = np.load(run / "traces.npz")
    n = len(final["period"])
    assert sorted(seen) == list(range(n - 1))  # all but the last (possibly incomplete) period
    np.testing.assert_array_equal(np.array([seen[k] for k in range(n - 1)]), final["iq_A"][: n - 1])
    assert len(got) > 5  # streamed in many batches
