"""Faults on purpose: a scenario's [[faults]] (spec.py), the injector they drive (protocols/faults,
in-process in direct mode, the fault_gateway process over SocketCAN), and what was injected and
how the nodes reacted (report.py)."""

from bench.scenario.faults import FAULT_KINDS, Fault, FaultError, parse_faults, rules_text

__all__ = ["FAULT_KINDS", "Fault", "FaultError", "parse_faults", "rules_text"]
