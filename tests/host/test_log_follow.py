"""Following a growing candump log (the VM's live view and the host's decoding of a VM run):
pieces cut anywhere, even mid-line, give every frame exactly once, and each poll costs what
was appended (the decoder keeps its state: it never re-decodes what it saw)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from bench.paths import REPO
from bench.run import RunOptions, run_scenario
from bench.run.pipeline import Pipeline
from bench.run.record.canlog import CandumpWriter
from bench.run.record.sources import LogFollower
from bench.run.sinks import FrameCollector
from bench.scenario import load


def test_follower_decodes_a_growing_log_once(tmp_path: Path) -> None:
    sc = load(REPO / "scenarios" / "demo_you2019_tuning.toml")
    frames = FrameCollector()
    ref = run_scenario(sc, RunOptions(bus="direct"), frame_sinks=[frames], keep_trace=True)
    frames.close()
    log = tmp_path / "full.log"
    with CandumpWriter(log, "vcan0", 1_700_000_000_000_000) as w:
        w.write(frames.frames)
    data = log.read_bytes()
    grow = tmp_path / "candump.log"
    grow.write_bytes(b"")
    follower = LogFollower(grow, hold_us=0)
    pipe = Pipeline(0x10, 0x20, expect=sc.expect)
    rng = np.random.default_rng(3)
    cuts = np.sort(rng.integers(0, len(data), 40))
    pos, seen, per_poll = 0, 0, []
    for cut in [*cuts.tolist(), len(data)]:
        with open(grow, "ab") as fh:
            fh.write(data[pos:cut])
        pos = cut
        got = follower.drain()
        per_poll.append(len(got))
        seen += len(got)
        pipe.feed(got)
    last = follower.drain(final=True)
    seen += len(last)
    pipe.feed(last)
    assert seen == len(frames.frames)  # every frame once
    assert max(per_poll) < len(frames.frames) / 4  # a poll returns the new frames, not the whole log
    res = pipe.finish(sc.name, "vcan0")
    assert res.summary["steps"] == ref.summary["steps"]
    assert res.summary["identified"] == ref.summary["identified"]
    assert json.dumps(res.summary["bus_stats"]) == json.dumps(ref.summary["bus_stats"])
