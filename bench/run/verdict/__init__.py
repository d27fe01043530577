"""From decoded periods to a verdict: streaming step statistics, the injected faults and the nodes' reactions, the
status, the summary and its exit code."""
