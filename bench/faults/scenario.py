"""The scenario every fault check runs (You 2019 deadbeat, locked rotor, the Fig. 8 step) and its variants:
with a fault injected, with the plant's command timeout set. `bench faults --set` changes them all (`law`)."""

from __future__ import annotations

import copy
from typing import Any

from bench.scenario import apply_overrides

STEP_AT = 20  # the iq step 0 -> 1 A of You 2019 Fig. 8
# `bench faults --set KEY=VALUE ...`: the scenario changes every check's runs share, e.g. another current law
# (controller.controller=NAME, a user's law with --law DIR) and its parameters. The protocol reactions judged
# (held periods, EMCYs, safe state, heartbeats) are the drive's and the plant's, whatever the law; how fast the
# loop recovers is judged against the law's own fault-free step (settling_bound, recovered).
Law = tuple[str, ...]
# drive trace for the checks: its measurement counters and its safe state (drive.eds 0x2204, 0x2209)
TRACE = {
    "pdo3": ["Drive status.lost_measurements", "Drive status.late_measurements"],
    "pdo4": ["Safe state.reason", "Safe state.non_finite_rejected"],
}


def base(name: str, periods: int = 120, law: Law = (), **over: Any) -> dict[str, Any]:
    """You 2019 (seed 000) deadbeat, locked rotor, the Fig. 8 step at period 20. No command timeout
    (0x2003:04 = 0): in lockstep the plant waits for every command as long as the drive is alive, so
    that no load on the machine can turn a slow answer into a held command (the checks whose fault
    removes a command from the loop set one: `with_command_timeout`)."""
    raw: dict[str, Any] = {
        "scenario": {"name": name, "periods": periods, "expect": ["ok"]},
        "motor": {"preset": "you2019", "mech_mode": "locked"},
        "drive": {"preset": "ideal", "command_timeout_us": 0},
        "controller": {"controller": "deadbeat_you2019", "Vmax_V": 139.0},
        "events": [{"at_period": STEP_AT, "references": {"iq_ref_A": 1.0}}],
        "trace": copy.deepcopy(TRACE),
    }
    for k, v in over.items():
        raw.setdefault(k, {}).update(v) if isinstance(v, dict) else raw.__setitem__(k, v)
    return apply_overrides(raw, list(law), "--set") if law else raw


# The plant's command timeout for the checks that drop or hold back the loop's command: lockstep has
# no other way to go on without it. Over a bus every period's answer must come within it, so it is far
# beyond the drive's answer (~0.1 ms; a loaded machine or VM stalls a process for 100s of ms) and well
# below the master's stall detection (10 s of no period: RunOptions.stall_s).
COMMAND_TIMEOUT_US = 2_000_000


def with_command_timeout(raw: dict[str, Any], timeout_us: int = COMMAND_TIMEOUT_US) -> dict[str, Any]:
    raw["drive"]["command_timeout_us"] = timeout_us
    return raw


def with_fault(raw: dict[str, Any], expect: list[str], *faults: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(raw)
    out["scenario"]["name"] += "-fault"
    out["scenario"]["expect"] = expect
    out["faults"] = list(faults)
    return out
