"""A run, end to end: scenario -> SDO configuration -> PDO loop -> frames -> decode once ->
trace chunks -> sinks. `run_scenario` is the public entry point (bench/run/pipeline.py).

The names below are imported on first use, so that `bench.signals` (what the view worker
needs) does not pull in canopen and the C library."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bench.run.options import RunOptions
    from bench.run.pipeline import Pipeline, RunResult, run_scenario

__all__ = ["Pipeline", "RunOptions", "RunResult", "run_scenario"]


def __getattr__(name: str) -> Any:
    if name in ("Pipeline", "RunResult", "run_scenario"):
        from bench.run import pipeline

        return getattr(pipeline, name)
    if name == "RunOptions":
        from bench.run.options import RunOptions

        return RunOptions
    raise AttributeError(name)
