"""`bench sweep`: robustness studies over scenario keys, on dask.distributed.

space.py    the points: grids, ranges, Monte Carlo samples
point.py    one point, run in memory in direct mode, reduced to a row
engine.py   where points run: a LocalCluster, an existing Dask cluster, or serially
heartbeat.py  the embedded cluster's workers close without a heartbeat error (a worker plugin)
table.py    rows streamed to Parquet as they complete; --resume
bisect.py   boundary search (k-section on the workers)
report.py   heat-map, boundary line, distributions
outputs.py  sweep.json, plots, what is printed
command.py  the command line
"""

from bench.sweep.command import add_arguments, main

__all__ = ["add_arguments", "main"]
