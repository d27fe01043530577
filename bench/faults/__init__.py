"""`bench faults`: the fault checks, each a scenario with [[faults]] (bench/scenario/faults.py) run through the
loop and judged (checks.py, measure.py); what was injected and how the nodes reacted is the run's own report
(bench/run/verdict/faults.py)."""
