"""The drive's current laws as drive.eds declares them: what each one reports and traces.

A law is a value name of Controller.controller (`[2200sub1] ValueNames=`). A law with parameters and
status has a manufacturer record whose EDS section names it in `CurrentLaws=`; these keys of that
section (ignored by `canopen` and protocols/gen_od.py) say what the bench does with it:

    Source=You 2019             the paper or book of the law (`Source.<law>=` for one law of a
                                record that several share); none or empty: the summary's "paper" is null
    Results=K1_bar_V_A,...      entries read by SDO at the end of a run and shown, in this order, as
                                the summary's "identified" values (`Results.<law>=`, empty: none);
                                none: every read-only (status) entry of the record in sub-index order
    Trace=det_A2,K1_hat_V_A,... up to four entries the drive's TPDO3 (first two) and TPDO4 (next two)
                                carry when the scenario has no [trace] (`Trace.<law>=`); an entry
                                of another object as "Object.entry"; none: the record's first four
                                numeric, mappable status entries

and on an entry's own section:

    ValidIf=identifications     the value does not apply (null in the summary) unless that entry
                                of the same record is non-zero at the end of the run
    NotApplicableNote=...       (on the entry a ValidIf names) the summary's "note" when it is zero

A law without a record (open loop) identifies nothing and traces the drive's own view (DRIVE_VIEW), as
the PI does by its keys (`Results.pi=`, `Trace.pi=Drive status.id_A,...` in You 2019's law.eds). The
papers' law folders and a user's are merged into drive.eds at build time: no Python edit for either.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import canopen
from canopen.objectdictionary import ODRecord, ODVariable, datatypes

from bench.eds import eds_path, load, raw_eds, section_of, value_names

LAW_ENTRY = ("Controller", "controller")
# The drive's own view, traced for a law without a record: its measured currents, the iq reference in
# effect, its speed estimate (two REAL32 per TPDO).
DRIVE_VIEW: dict[int, tuple[str, ...]] = {
    3: ("Drive status.id_A", "Drive status.iq_A"),
    4: ("Drive status.iq_ref_active_A", "Drive status.speed_rad_s"),
}
TRACE_PDOS = (3, 4)  # the drive's trace TPDOs, two entries each
NUMERIC = {
    datatypes.BOOLEAN,
    datatypes.INTEGER8,
    datatypes.INTEGER16,
    datatypes.INTEGER32,
    datatypes.UNSIGNED8,
    datatypes.UNSIGNED16,
    datatypes.UNSIGNED32,
    datatypes.REAL32,
}


@dataclass(frozen=True)
class LawInfo:
    """What the bench reads, shows and traces of one current law."""

    name: str  # the value name, e.g. "deadbeat_you2019"
    source: str | None  # "You 2019"; None: not given
    record: str | None  # its record's object name ("Online tuning"); None: a law without a record
    results: tuple[str, ...] = ()  # entries of the record, in summary order
    trace: dict[int, tuple[str, ...]] = field(default_factory=dict)  # TPDO -> "Object.entry" names
    valid_if: dict[str, str] = field(default_factory=dict)  # result entry -> the entry it depends on
    notes: dict[str, str] = field(default_factory=dict)  # condition entry -> the note when it is zero


def _od(path: Path | None) -> canopen.ObjectDictionary:
    return load("drive") if path is None else _import(str(path))


@cache
def _import(path: str) -> canopen.ObjectDictionary:
    return canopen.import_od(path)


def _path(path: Path | None) -> Path:
    return eds_path("drive") if path is None else path


def law_names(path: Path | None = None) -> tuple[str, ...]:
    """The laws in value order (value 0, 1, ... of Controller.controller)."""
    return value_names(_path(path), _od(path)[LAW_ENTRY[0]][LAW_ENTRY[1]])


def law_records(path: Path | None = None) -> tuple[str, ...]:
    """The laws' records by object name, in index order (their parameters are a scenario's [controller] keys)."""
    raw = raw_eds(str(_path(path)))
    od = _od(path)
    return tuple(
        od[i].name
        for i in sorted(od.indices)
        if isinstance(od[i], ODRecord) and raw.has_option(f"{i:04X}", "CurrentLaws")
    )


def _record_of(law: str, path: Path | None) -> ODRecord | None:
    raw = raw_eds(str(_path(path)))
    for obj in _od(path).values():
        sec = f"{obj.index:04X}"
        if isinstance(obj, ODRecord) and raw.has_option(sec, "CurrentLaws"):
            if law in (n.strip() for n in raw.get(sec, "CurrentLaws").split(",")):
                return obj
    return None


def law_record(law: str, path: Path | None = None) -> ODRecord | None:
    """The EDS record of law `law` (the section whose CurrentLaws= names it), None for a law without one."""
    return _record_of(law, path)


def _key(raw: object, sec: str, key: str, law: str) -> str | None:
    """`key.<law>=` of the section, else `key=`, else None."""
    for k in (f"{key}.{law}", key):
        if raw.has_option(sec, k):  # type: ignore[attr-defined]
            return str(raw.get(sec, k)).strip()  # type: ignore[attr-defined]
    return None


def _names(text: str) -> tuple[str, ...]:
    return tuple(n.strip() for n in text.split(",") if n.strip())


def _status(rec: ODRecord) -> list[ODVariable]:
    return [rec.subindices[s] for s in sorted(rec.subindices) if s > 0 and not rec.subindices[s].writable]


def _default_trace(rec: ODRecord) -> tuple[str, ...]:
    return tuple(v.name for v in _status(rec) if v.data_type in NUMERIC and v.pdo_mappable)[: 2 * len(TRACE_PDOS)]


def _pdos(rec: ODRecord, names: tuple[str, ...]) -> dict[int, tuple[str, ...]]:
    """TPDO3 the first two, TPDO4 the next two; a name without an object is the record's."""
    full = tuple(n if "." in n else f"{rec.name}.{n}" for n in names)
    return {p: full[2 * i : 2 * i + 2] for i, p in enumerate(TRACE_PDOS) if full[2 * i : 2 * i + 2]}


@cache
def _law_info(law: str, path: Path | None) -> LawInfo:
    if law not in law_names(path):
        raise KeyError(f"{law!r} is not a value of Controller.controller in {_path(path)}")
    rec = _record_of(law, path)
    if rec is None:
        return LawInfo(law, None, None, (), dict(DRIVE_VIEW))
    raw = raw_eds(str(_path(path)))
    sec = f"{rec.index:04X}"
    given = _key(raw, sec, "Results", law)
    results = _names(given) if given is not None else tuple(v.name for v in _status(rec))
    traced = _key(raw, sec, "Trace", law)
    trace = _names(traced) if traced is not None else _default_trace(rec)
    for n in (*results, *(t for t in trace if "." not in t)):
        if n not in rec.names:
            raise KeyError(f"[{sec}] {rec.name}: {n!r} is not an entry of the record")
    valid_if: dict[str, str] = {}
    notes: dict[str, str] = {}
    for var in rec.values():
        vsec = section_of(var)
        if raw.has_option(vsec, "ValidIf"):
            cond = raw.get(vsec, "ValidIf").strip()
            if cond not in rec.names:
                raise KeyError(f"[{vsec}] ValidIf={cond}: not an entry of {rec.name}")
            valid_if[var.name] = cond
        if raw.has_option(vsec, "NotApplicableNote"):
            notes[var.name] = raw.get(vsec, "NotApplicableNote").strip()
    valid_if = {k: v for k, v in valid_if.items() if k in results}  # what this law shows
    return LawInfo(law, _key(raw, sec, "Source", law) or None, rec.name, results, _pdos(rec, trace), valid_if, notes)


def law_info(law: str, path: Path | None = None) -> LawInfo:
    """The law's source, record, results (summary order), default trace and ValidIf conditions, from
    drive.eds (the merged one of the build) or the EDS at `path`. KeyError: not a law of that EDS."""
    return _law_info(law, path)


def result_reads(path: Path | None = None) -> tuple[tuple[str, str, tuple[str, ...]], ...]:
    """("drive", record, entries) read at the end of every run, in law order, each distinct one once:
    each law's results, then the read-only entries its ValidIf conditions name (a parameter's value is
    known from its writes or its EDS default)."""
    out: list[tuple[str, str, tuple[str, ...]]] = []
    for law in law_names(path):
        info = law_info(law, path)
        if info.record is None:
            continue
        rec = _od(path)[info.record]
        conds = [c for c in dict.fromkeys(info.valid_if.values()) if c not in info.results and not rec[c].writable]
        read = ("drive", info.record, (*info.results, *conds))
        if read[2] and read not in out:
            out.append(read)
    return tuple(out)
