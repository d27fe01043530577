"""A run, end to end: scenario -> SDO configuration -> PDO loop -> frames -> decode once ->
trace chunks -> sinks. `run_scenario` is the public entry point (bench/run/pipeline.py)."""

from .pipeline import Pipeline, RunResult, run_scenario
from .session import RunOptions

__all__ = ["Pipeline", "RunOptions", "RunResult", "run_scenario"]
