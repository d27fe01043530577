"""`bench perf`: moved to bench/tools/perf/ (this shim keeps `from bench.perf import ...` working)."""

from .tools.perf import add_arguments, main  # noqa: F401
