"""`bench reproduce`: every quantitative claim of the three papers, run on the bench, in one report.

    bench reproduce --paper all --bus vcan0 --out reports/latest

For each claim: what the paper states (figure/table), what the bench measured, the
tolerance, the verdict (reproduced / differs) and why it differs where it does, with a
plot of the run and a link to its Rerun recording. Writes report.md, report.html and
report.json (one record per claim, for tools). Over vcan by default: on a host without
SocketCAN the claims run inside the VM (one boot) and the report is built on the host.

Each run is decoded once, by its own pipeline while it runs; its folder keeps the CAN log, the summary and the
decoded trace, from which its recording and figure are made (views.py). command.py: the arguments, the claims'
runs, main; report.py: the reports and `publish`.
"""

from __future__ import annotations

from bench.reproduce.command import add_arguments, collect, main, run_claim_function
from bench.reproduce.report import PAPERS, publish, write_reports
from bench.reproduce.views import make_views

__all__ = ["PAPERS", "add_arguments", "collect", "main", "make_views", "publish", "run_claim_function", "write_reports"]
