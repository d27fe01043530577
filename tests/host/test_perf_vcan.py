"""`bench perf`'s vcan section, host side: the recorder check of a lockstep run's candump log
(read with bench.run.record.canlog, decoded by the run pipeline) on a log made in direct mode, where
no frame is lost; and the frame counter's count of frames out of time order in a log."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from bench.paths import REPO
from bench.run.bus.frames import FRAME_DTYPE
from bench.tools.perf.vcan import _FrameCount, recorder_check


def test_recorder_check_of_a_complete_log(tmp_path: Path) -> None:
    from bench.run import RunOptions, run_scenario
    from bench.run.record.canlog import CandumpWriter
    from bench.scenario import load

    periods = 600
    sc = load(REPO / "scenarios" / "you2019_step.toml", [f"scenario.periods={periods}"])
    with CandumpWriter(tmp_path / "candump.log", "vcan0", int(time.time() * 1e6)) as w:
        res = run_scenario(sc, RunOptions(bus="direct"), frame_sinks=[w])
    assert res.status == "ok"
    (tmp_path / "perf_capture.json").write_text(json.dumps({"periods": periods, "run_wall_s": 0.1}))
    rec = recorder_check(tmp_path)
    assert rec["periods_expected"] == rec["syncs_recorded"] == periods
    assert rec["lost_frames"] == 0 and rec["frames_out_of_time_order_in_log"] == 0
    assert (
        rec["loop_frames_recorded"]
        == rec["loop_frames_expected"]
        == periods * rec["frames_per_period"]["pdos_plus_sync"]
    )
    assert rec["continuity"] == rec["continuity_in_log_order"]
    assert all(v == 0 for v in rec["continuity"].values())
    assert rec["frames_total"] > rec["loop_frames_recorded"]  # the SDO configuration is in the log too


def test_frame_count_counts_frames_behind_an_earlier_later_stamp() -> None:
    c = _FrameCount()
    for stamps in ([1, 2, 5, 3, 4], [4, 6, 7]):  # 3 and 4 after 5; 4 after 5 across chunks
        f = np.zeros(len(stamps), dtype=FRAME_DTYPE)
        f["t_us"] = stamps
        f["cob_id"] = 0x80
        c.write(f)
    assert c.late == 3
    assert c.by_cob[0x80] == 8
