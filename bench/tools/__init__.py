"""Tools around the bench, not in a run's data path: `perf` (every performance figure in one run)."""
