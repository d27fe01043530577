"""What the law interface lost, as data: a law folder written against an earlier version of the bench that no longer
compiles because it names something removed gets a message that says what changed, in which version, and what to
write instead, beside the compiler's error (bench/law.py). The law interface is firmware_shim/core/current_law.h
(current_law_t, current_law_out_t) and drive_config.h (drive_config_t, what every law is given); a removal is one
more row of REMOVED (and a line of CHANGELOG.md and of docs/YOUR_CONTROLLER.md's upgrade note)."""

from __future__ import annotations

import re
from dataclasses import dataclass

GUIDE = "docs/YOUR_CONTROLLER.md"


@dataclass(frozen=True)
class Removed:
    owner: str  # the C type whose member it was (current_law_t), or the header that declared it
    name: str  # the member or identifier
    version: str  # the bench's version that removed it
    instead: str  # what to write instead

    @property
    def what(self) -> str:
        return f"{self.owner}.{self.name}" if self.owner.endswith("_t") else f"{self.name} ({self.owner})"


_TRACE = (
    "a law's quantities are the status entries of its law.eds record (AccessType=ro, PDOMapping=1), written by its "
    "status() and traced by PDO (the record's Trace= key, a scenario's [trace]): delete the signals function, the "
    ".signals member and the recorder's ids (trace_recorder.h records the drive's own signals only)"
)
_RECORD = (
    "You 2019's pipeline settings moved into its own record (0x2500 Online tuning): a law of yours that read one "
    "gives its own law.eds record a parameter (AccessType=rw, a scenario key controller.<name>) and reads it from "
    "`record` (examples/laws/complex_vector_pi: bandwidth_Hz)"
)
_YOU2019_IDS = ("DET", "K1_HAT", "K2_HAT", "K1_BAR", "K2_BAR", "L_HAT", "K1_ACTIVE", "K2_ACTIVE", "IQ_HAT", "ID_HAT")
_PIPELINE = (
    "pi_bandwidth_Hz",
    "limited_memory",
    "deadtime_comp_enable",
    "deadtime_comp_V",
    "deadtime_comp_I_sat_A",
    "estimator_bandwidth_Hz",
    "decoupling_enable",
    "estimator_enable",
)
REMOVED = (
    Removed("current_law_t", "signals", "0.2.0", _TRACE),
    Removed("trace_recorder.h", "TRACE_SIG_COUNT", "0.2.0", _TRACE),  # current_law.h no longer includes it
    *(Removed("trace_recorder.h", f"TRACE_SIG_{sig}", "0.2.0", _TRACE) for sig in _YOU2019_IDS),
    *(Removed("drive_config_t", name, "0.2.0", _RECORD) for name in _PIPELINE),
)
# the upgrade note of each version that removed something (docs/YOUR_CONTROLLER.md's section)
NOTES = {"0.2.0": "Upgrading from 0.1"}

_Q = "['‘’`\"]"  # gcc quotes with ‘’ in a UTF-8 locale, ' otherwise; clang with '
_NAME = rf"{_Q}(?P<name>\w+){_Q}"
_TYPE = rf"{_Q}(?P<type>[^'‘’`\"]+){_Q}(?: {{aka {_Q}(?P<aka>[^'‘’`\"]+){_Q}}})?"
# the compilers' words for a member or an identifier that is not there (gcc 12, older gcc, clang)
DIAGNOSTICS = (
    re.compile(rf"{_TYPE} has no member named {_NAME}"),
    re.compile(rf"unknown field {_NAME} specified in initializer"),
    re.compile(rf"no member named {_NAME} in {_TYPE}"),
    re.compile(rf"field designator {_NAME} does not refer to any field in type {_TYPE}"),
    re.compile(rf"{_NAME} undeclared"),
    re.compile(rf"use of undeclared identifier {_NAME}"),
)


def _owned(row: Removed, found: re.Match[str]) -> bool:
    """The diagnostic is about the row's name, of the row's type where the compiler names the type."""
    if found.group("name") != row.name:
        return False
    named = " ".join(t for t in (found.groupdict().get("type"), found.groupdict().get("aka")) if t)
    if not row.owner.endswith("_t") or not named:
        return True
    struct = {"current_law_t": "current_law"}.get(row.owner, row.owner)
    return re.search(rf"\b({re.escape(row.owner)}|struct {re.escape(struct)})\b", named) is not None


def removed_in(lines: list[str]) -> list[Removed]:
    """The rows whose removal the compiler's output names, in the order it names them (each once)."""
    hits: list[Removed] = []
    for line in lines:
        for pattern in DIAGNOSTICS:
            for found in pattern.finditer(line):
                hits += [r for r in REMOVED if r not in hits and _owned(r, found)]
    return hits


def explain(lines: list[str]) -> str | None:
    """What to tell a user whose law names removed parts of the interface, or None."""
    rows = removed_in(lines)
    if not rows:
        return None
    groups: dict[tuple[str, str], list[str]] = {}  # one line per change, naming each of its parts the law used
    for r in rows:
        groups.setdefault((r.version, r.instead), []).append(r.what)
    said = [f"  {', '.join(names)}: removed in {version}: {instead}" for (version, instead), names in groups.items()]
    notes = sorted({f'{GUIDE}, "{NOTES[r.version]}"' for r in rows if r.version in NOTES})
    return (
        "it is written against an earlier version of the law interface:\n"
        + "\n".join(said)
        + (f"\n  (what changed and how to mend a law: {'; '.join(notes)}; CHANGELOG.md)" if notes else "")
    )
