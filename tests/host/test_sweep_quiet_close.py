"""A sweep's embedded cluster closes without a worker's heartbeat error on the user's terminal (issue 52: the CI run
under load saw `distributed.worker - ERROR - Failed to communicate with scheduler during heartbeat` and two
tracebacks after a sweep's Ctrl-C). The race, made to happen every time: a scheduler that answers heartbeats 6 s late
(as a loaded one does, later), a LocalCluster closed while a beat is in flight. Without bench/sweep/heartbeat.py's
QuietClose the error shows (so this test can fail); with it, nothing does."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = """
import asyncio, logging, sys, time
import dask
from dask.distributed import Client, LocalCluster
from distributed.scheduler import Scheduler

orig_init = Scheduler.__init__

def init(self, *a, **kw):
    orig_init(self, *a, **kw)
    answer = self.handlers["heartbeat_worker"]

    async def late(**k):
        await asyncio.sleep(6.0)
        return answer(**k)

    self.handlers["heartbeat_worker"] = late

Scheduler.__init__ = init

def work(x):
    time.sleep(0.5)
    return x

if __name__ == "__main__":
    dask.config.set({"distributed.worker.daemon": False, "distributed.worker.profile.enabled": False})
    extra = {}
    if sys.argv[1] == "quiet":
        from bench.sweep.heartbeat import QuietClose
        extra["plugins"] = (QuietClose(),)
    cl = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      silence_logs=logging.ERROR, dashboard_address=None, **extra)
    c = Client(cl)
    futs = [c.submit(work, i, pure=False) for i in range(20)]
    time.sleep(3)
    for f in futs:
        f.cancel()
    c.close()
    cl.close()
    print("closed", file=sys.stderr)
"""


@pytest.mark.parametrize("mode", ["plain", "quiet"])
def test_a_closing_worker_with_a_beat_in_flight(tmp_path: Path, mode: str) -> None:
    script = tmp_path / "close.py"
    script.write_text(SCRIPT)
    res = subprocess.run([sys.executable, str(script), mode], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and "closed" in res.stderr, res.stderr[-2000:]
    said = "Failed to communicate with scheduler during heartbeat" in res.stderr
    if mode == "plain":
        assert said, "the race was not provoked: the test would prove nothing (dask changed?)"
    else:
        assert not said and "Traceback" not in res.stderr, res.stderr[-2000:]
