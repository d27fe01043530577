"""`python -m bench.tools.perf [--inside-vm --out FILE]`: `bench perf` without the CLI (the VM helper)."""

import argparse
import sys

from bench.tools.perf import add_arguments, main

_ap = argparse.ArgumentParser(prog="bench perf", description="bench perf")
add_arguments(_ap)
sys.exit(main(_ap.parse_args()))
