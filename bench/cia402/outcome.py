"""What a CiA 402 master run ends with, shared by the command (bench/cia402/command.py) and the session
(bench/cia402/session.py): its summary's text and file, and the signals that end it (a first Ctrl-C or
SIGTERM raises Interrupted, the second is ignored while the drive is disabled)."""

from __future__ import annotations

import json
import signal
from pathlib import Path
from types import FrameType
from typing import Any

from bench.cia402 import NO_LOCKSTEP


class Interrupted(Exception):
    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def summary_text(summary: dict[str, Any]) -> str:
    lines = [
        f"bench run (cia402): {summary['verdict']} — {summary['reason']}",
        f"  {NO_LOCKSTEP}; cycle {summary['cycle_ms']:g} ms, bus load {summary['bus_load'] * 100:.0f} %",
        f"  states: {' -> '.join(summary['states_passed']) or 'none seen'}; final {summary['final_state']}",
        f"  cycles {summary['cycles']}, without statusword TPDO {summary['cycles_without_statusword']}",
        f"  drive watches the bench's heartbeat: {'yes' if summary['watches_bench'] else 'NO'}",
    ]
    for t in summary["tracking"]:
        mean = t["mean_actual_permille"]
        lines.append(
            f"  target {t['target_permille']:+.0f} per mille from cycle {t['start_cycle']}: mean actual "
            + ("n/a" if mean is None else f"{mean:+.1f}")
            + ("" if t["relative_error"] is None else f" ({t['relative_error'] * 100:+.1f} %)")
        )
    if summary["ignored_scenario_keys"]:
        lines.append(f"  ignored scenario keys: {', '.join(summary['ignored_scenario_keys'])}")
    lines.append(f"  results: {summary['folder']}")
    return "\n".join(lines)


def write_summary(path: Path, summary: dict[str, Any]) -> None:
    path.write_text(json.dumps(summary, indent=2, default=str) + "\n")


def ignore_signals() -> None:
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)


def raise_on_signals() -> None:
    def handler(signum: int, frame: FrameType | None) -> None:
        ignore_signals()  # a second Ctrl-C must not cut the cleanup short
        raise Interrupted(signum)

    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, handler)
