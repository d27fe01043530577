"""What was injected and how the nodes reacted, with their periods: summary.json "faults".

Sources, each read once: the injector's own log (every action, its period and rule), the EMCYs the
decoder found on the bus, and the plant's status bits in the trace (held: no command since the previous SYNC;
missed; trip: the BitNames of plant.eds's Measurement.status). EMCY codes are named by bench/emcy.py."""

from __future__ import annotations

from typing import Any

from bench.eds import bits
from bench.emcy import emcy_names
from bench.run.bus.gateway import KINDS
from bench.scenario.faults import Fault

MAX_LISTED = 200  # reactions listed one by one (all are counted)
STATUS = bits("plant", "Measurement", "status")  # the masks of Measurement.status's bits (plant.eds BitNames)


class StatusWatch:
    """The plant's status bits per period, as the trace chunks pass (only the periods that have one)."""

    BITS = {"tripped": STATUS["trip"], "missed": STATUS["missed"], "held": STATUS["held"]}  # summary's key: mask

    def __init__(self) -> None:
        self.periods: dict[str, list[int]] = {k: [] for k in self.BITS}
        self.counts: dict[str, int] = dict.fromkeys(self.BITS, 0)

    def add(self, period: Any, status: Any) -> None:
        import numpy as np

        st = np.nan_to_num(status, nan=0.0).astype(np.int64)
        for name, bit in self.BITS.items():
            hit = period[(st & bit) != 0]
            self.counts[name] += len(hit)
            room = 10_000 - len(self.periods[name])
            if room > 0:
                self.periods[name].extend(int(p) for p in hit[:room])


def build(
    faults: list[Fault], events: list[tuple[Any, ...]], lost: int, emcy: list[dict[str, Any]], status: StatusWatch
) -> dict[str, Any]:
    names = emcy_names()
    reactions: list[dict[str, Any]] = []
    for e in emcy:
        code = int(e["code"], 16)
        what = names.get(code, "unknown")
        if code == 0:
            what = "error reset (all errors cleared)"
        reactions.append(
            {"period": e["period"], "node": e["node"], "what": f"EMCY {e['code']} {what}", "data": e["data"]}
        )
    for name in ("held", "missed"):
        for p in status.periods[name]:
            reactions.append({"period": p, "node": "plant", "what": f"command {name}"})
    reactions.sort(key=lambda r: (r["period"], r["node"], r["what"]))
    per_fault = []
    for f in faults:
        acts = [ev for ev in events if ev[2] == f.index and KINDS[ev[3]] not in ("release", "thaw")]
        first = min((int(ev[0]) for ev in acts), default=None)
        after = [r for r in reactions if first is not None and r["period"] >= first]
        entry: dict[str, Any] = {
            "fault": f.index,
            "kind": f.kind,
            "description": f.describe(),
            "actions": len(acts),
            "first_period": first,
            "action_periods": sorted({int(ev[0]) for ev in acts})[:50],
            "released": sum(1 for ev in events if ev[2] == f.index and KINDS[ev[3]] == "release"),
            "first_reaction": after[0] if after else None,
            "reaction_periods": (after[0]["period"] - first) if after and first is not None else None,
        }
        if f.kind in ("drop", "delay", "duplicate", "corrupt", "reorder"):
            entry["held_periods"] = sum(1 for p in status.periods["held"] if first is not None and p >= first)
        per_fault.append(entry)
    return {
        "injected": per_fault,
        "actions": len(events),
        "actions_not_logged": lost,  # -1: the gateway's log is missing (it died): the actions are unknown
        "reactions": reactions[:MAX_LISTED],
        "reaction_counts": {
            "held_periods": status.counts["held"],
            "missed_periods": status.counts["missed"],
            "emcy": len(emcy),
        },
    }


def format_faults(rep: dict[str, Any]) -> str:
    """The report in a few lines for the terminal."""
    lines = []
    for f in rep["injected"]:
        r = f["first_reaction"]
        react = (
            f"first reaction {r['what']} ({r['node']}) at period {r['period']}, after {f['reaction_periods']} period(s)"
            if r
            else "no reaction seen"
        )
        hit = f"{f['actions']} action(s) from period {f['first_period']}" if f["actions"] else "never applied"
        lines.append(f"fault {f['fault']}: {f['description']}: {hit}; {react}")
    c = rep["reaction_counts"]
    lines.append(f"plant: {c['held_periods']} held period(s), {c['missed_periods']} missed; {c['emcy']} EMCY(s)")
    return "\n".join(lines)
