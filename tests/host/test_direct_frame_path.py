"""Direct mode's two frame paths (bench/direct/hil_direct.c): with no fault rule each frame goes from its bus slot
to the other node in place; with a rule, through the fault injector. A rule that never acts must leave every frame
of the run - its time, order, sender and bytes - and every trace value as the run without it."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.faults.scenario import base, with_command_timeout, with_fault
from bench.run import RunOptions, run_scenario
from bench.scenario import parse


class Frames:
    """A frame sink keeping every frame of the run."""

    def __init__(self) -> None:
        self.chunks: list[np.ndarray] = []

    def write(self, frames: np.ndarray) -> None:
        self.chunks.append(np.array(frames, copy=True))

    def close(self) -> None:
        pass

    def all(self) -> np.ndarray:
        return np.concatenate(self.chunks)


def _run(raw: dict[str, Any]) -> tuple[Any, np.ndarray]:
    frames = Frames()
    res = run_scenario(parse(raw, "<frame path>"), RunOptions(bus="direct"), frame_sinks=[frames], keep_trace=True)
    return res, frames.all()


def test_a_rule_that_never_acts_changes_no_frame_and_no_value() -> None:
    raw = with_command_timeout(base("frame-path", periods=400))
    plain, plain_frames = _run(raw)
    # a drop of the command with a probability no draw of 400 periods reaches: the injector's path, no action
    ruled, ruled_frames = _run(
        with_fault(raw, ["frames_lost"], {"kind": "drop", "frame": "drive.TPDO1", "probability": 1e-12, "seed": 5})
    )
    assert ruled.summary["faults"]["injected"][0]["actions"] == 0
    assert plain.summary["status"] == ruled.summary["status"] == "ok"
    assert len(plain_frames) > 4 * 400
    assert plain_frames.dtype == ruled_frames.dtype
    assert np.array_equal(plain_frames, ruled_frames)  # time stamps, bus order, senders, bytes
    assert plain.trace is not None and ruled.trace is not None
    for col in plain.trace:
        assert np.array_equal(plain.trace[col], ruled.trace[col], equal_nan=True), col
