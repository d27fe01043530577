"""A run's result, whoever ran it: HilRun (status, exit code, summary, steps, traces, folder; the expect_* checks),
Step (a reference step's figures), load_run (a `bench run --out` folder read back). The pytest plugin's hil_run and the
library's bench.api.run return a HilRun; this package imports nothing of pytest and numpy only to read traces."""

from __future__ import annotations

from bench.result.run import HilRun, RunFolderError, load_run
from bench.result.steps import Step

__all__ = ["HilRun", "RunFolderError", "Step", "load_run"]
