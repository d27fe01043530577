"""bench/tools/busy.py: the busy loops the soak, `bench perf` and the lockstep-under-load test start are running
inside the block and gone after it, whatever ends the block."""

from __future__ import annotations

import os
import time

import pytest

from bench.tools.busy import busy_loops


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except OSError:
        return False


def test_the_loops_run_in_the_block_and_are_killed_when_it_raises() -> None:
    with pytest.raises(RuntimeError), busy_loops(2) as pids:
        assert len(pids) == 2 and all(_alive(p) for p in pids)
        assert all(os.getsid(p) == p for p in pids)  # each in its own session
        raise RuntimeError("the block ends badly")
    time.sleep(0.05)
    assert not any(_alive(p) for p in pids)
