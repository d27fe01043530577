"""A scenario's [[faults]]: checked like its events (the bad key, what is allowed, nothing starts),
then written as the injector's rule text (protocols/faults/fault_rules.h), the one format both
transports read::

    [[faults]]
    kind = "drop"                # drop | delay | duplicate | corrupt | reorder           (frames)
    frame = "drive.TPDO1"        #   silence_heartbeat | freeze | kill | reset             (nodes)
    at_period = 200              # first period of the window (default 0)
    periods = 1                  # window length (default 1; with `probability` alone: the whole run)
    probability = 0.01           # each matching frame in the window (default 1), seeded:
    seed = 7                     #   default scenario.seed; same seed, same frames hit, on every bus
    count = 1                    # at most this many frames hit (default: no limit)
    delay_periods = 1            # delay: whole periods (released right after the SYNC that starts it)
    delay_us = 300               # delay: microseconds (real time only)
    bit = 12                     # corrupt: flip this bit (0 = LSB of byte 0) ...
    dlc = 4                      #   ... or send with this DLC
    node = "drive"               # node faults: plant | drive

Frames are named by the node that sends them and the EDS object that defines their COB-ID:
SYNC, plant.TPDO1 .. plant.TPDO4, drive.TPDO1 .. drive.TPDO4, plant.heartbeat, drive.heartbeat,
plant.EMCY, drive.EMCY (or `cob_id = 0x190` with `from = "plant"|"drive"`). The COB-IDs are read
from the EDS files at run time for the run's node-IDs (bench/eds.py), never written here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

FRAME_KINDS = ("drop", "delay", "duplicate", "corrupt", "reorder")
NODE_KINDS = ("silence_heartbeat", "freeze", "kill", "reset")
FAULT_KINDS = FRAME_KINDS + NODE_KINDS
NODES = ("plant", "drive")
SIDE = {"plant": "a", "drive": "b"}  # the injector's sides: a = plant, master, recorder; b = drive
PER_KIND = {
    "drop": set(),
    "delay": {"delay_periods", "delay_us"},
    "duplicate": set(),
    "corrupt": {"bit", "dlc"},
    "reorder": set(),
    "silence_heartbeat": {"node"},
    "freeze": {"node"},
    "kill": {"node"},
    "reset": {"node"},
}
FRAME_KEYS = {"frame", "cob_id", "from", "probability", "seed", "count"}


class FaultError(ValueError):
    """A bad [[faults]] entry: the message names the file, the entry, the key and what is allowed."""


@dataclass(frozen=True)
class Fault:
    index: int  # in the scenario's [[faults]]
    kind: str
    at_period: int
    periods: int
    frame: str | None = None  # a frame name (frame faults), or None with cob_id
    cob_id: int | None = None
    sender: str | None = None  # plant | drive: who sends the frames (frame faults)
    node: str | None = None  # node faults
    probability: float = 1.0
    seed: int = 1
    count: int = 0
    delay_periods: int = 0
    delay_us: int = 0
    bit: int | None = None
    dlc: int | None = None

    def describe(self) -> str:
        what = self.node if self.node else (self.frame or f"0x{self.cob_id:03X} from the {self.sender}")
        span = f"period {self.at_period}" if self.periods == 1 else f"periods {self.at_period}..{self.end - 1}"
        extra = ""
        if self.kind == "delay":
            extra = f" by {self.delay_us} us" if self.delay_us else f" by {self.delay_periods} period(s)"
        elif self.kind == "corrupt":
            extra = f" (DLC {self.dlc})" if self.dlc is not None else f" (bit {self.bit} flipped)"
        if self.probability < 1:
            extra += f", each with probability {self.probability:g} (seed {self.seed})"
        if self.count:
            extra += f", at most {self.count}"
        return f"{self.kind} {what}{extra} at {span}"

    @property
    def end(self) -> int:
        return self.at_period + self.periods


def _int(w: str, key: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise FaultError(f"{w}.{key} = {v!r}: expected an integer in {lo} .. {hi}")
    return v


def frame_names() -> tuple[str, ...]:
    pdos = tuple(f"{n}.TPDO{i}" for n in NODES for i in range(1, 5))
    return ("SYNC", *pdos, "plant.heartbeat", "drive.heartbeat", "plant.EMCY", "drive.EMCY")


def max_rules() -> int:
    """The injector's fixed rule table: MaxRules of [FaultInjector] in protocols/eds/common.ini, from which
    protocols/gen_od.py generates the C's FI_MAX_RULES (protocols/generated/eds_common.h)."""
    from bench.eds import fault_injector_size

    return fault_injector_size("MaxRules")


def parse_faults(
    raw: Any, where: str, periods: int, timing: str, seed: int, event_periods: tuple[int, ...] = ()
) -> list[Fault]:
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise FaultError(f"{where}: faults must be an array of tables ([[faults]])")
    if len(raw) > max_rules():
        raise FaultError(f"{where}: {len(raw)} [[faults]] entries; the injector holds at most {max_rules()}")
    out = []
    for i, ent in enumerate(raw):
        w = f"{where}: faults[{i}]"
        if not isinstance(ent, dict):
            raise FaultError(f"{w}: must be a table")
        kind = ent.get("kind")
        if kind not in FAULT_KINDS:
            raise FaultError(f"{w}.kind = {kind!r}: expected one of {', '.join(FAULT_KINDS)}")
        allowed = {"kind", "at_period", "periods"} | PER_KIND[kind] | (FRAME_KEYS if kind in FRAME_KINDS else set())
        for key in ent:
            if key not in allowed:
                raise FaultError(
                    f"{w}: key {key!r} does not apply to kind {kind!r}; allowed: {', '.join(sorted(allowed))}"
                )
        at = _int(w, "at_period", ent.get("at_period", 0), 0, periods - 1)
        whole = "probability" in ent and "at_period" not in ent and "periods" not in ent
        span = _int(w, "periods", ent.get("periods", periods - at if whole else 1), 1, periods - at)
        f: dict[str, Any] = {"index": i, "kind": kind, "at_period": at, "periods": span}
        if kind in FRAME_KINDS:
            f.update(_frame_keys(w, ent, seed))
        else:
            node = ent.get("node")
            if node not in NODES:
                raise FaultError(f"{w}.node = {node!r}: expected one of {', '.join(NODES)}")
            if kind == "freeze" and node == "plant":
                raise FaultError(
                    f"{w}: freeze node = 'plant': the plant produces the SYNCs that count the periods, so a frozen "
                    "plant would never be thawed; freeze the drive, or kill the plant"
                )
            f["node"] = node
            if kind == "freeze":
                # the drive thaws at the SYNC of period at + periods: that period must come, and no event (written
                # by SDO to the frozen drive, at the hold before its period) may fall inside
                if at + span > periods - 1:
                    raise FaultError(
                        f"{w}: freeze from period {at} for {span} periods ends at {at + span}, after the run's last "
                        f"period {periods - 1}: the drive would still be frozen when the bench reads its statuses"
                    )
                inside = [e for e in event_periods if at < e <= at + span]
                if inside:
                    raise FaultError(
                        f"{w}: freeze from period {at} for {span} periods covers the event at period {inside[0]}: its "
                        "settings go to the drive by SDO, which a frozen drive cannot answer; move one of them"
                    )
        if kind == "delay":
            dp, du = ent.get("delay_periods"), ent.get("delay_us")
            if (dp is None) == (du is None):
                raise FaultError(f"{w}: a delay needs exactly one of delay_periods (whole periods) or delay_us")
            if du is not None:
                f["delay_us"] = _int(w, "delay_us", du, 1, 10_000_000)
                if timing != "realtime":
                    raise FaultError(
                        f"{w}.delay_us: microseconds mean something only in real time (scenario.timing = "
                        "'realtime'); in lockstep use delay_periods"
                    )
            else:
                f["delay_periods"] = _int(w, "delay_periods", dp, 1, 1_000_000)
        if kind == "corrupt":
            bit, dlc = ent.get("bit"), ent.get("dlc")
            if (bit is None) == (dlc is None):
                raise FaultError(f"{w}: corrupt needs exactly one of bit (0 .. 63, flipped) or dlc (0 .. 8)")
            if bit is not None:
                f["bit"] = _int(w, "bit", bit, 0, 63)
            else:
                f["dlc"] = _int(w, "dlc", dlc, 0, 8)
        out.append(Fault(**f))
    return out


def _frame_keys(w: str, ent: dict[str, Any], seed: int) -> dict[str, Any]:
    f: dict[str, Any] = {}
    name, cob = ent.get("frame"), ent.get("cob_id")
    if (name is None) == (cob is None):
        raise FaultError(f"{w}: name the frames with frame = one of {', '.join(frame_names())} (or cob_id and from)")
    if name is not None:
        if name not in frame_names():
            raise FaultError(f"{w}.frame = {name!r}: expected one of {', '.join(frame_names())}")
        f["frame"] = name
        f["sender"] = "plant" if name == "SYNC" else name.split(".")[0]
        if "from" in ent:
            raise FaultError(f"{w}: from is implied by frame = {name!r}; give it only with cob_id")
    else:
        f["cob_id"] = _int(w, "cob_id", cob, 0, 0x7FF)
        sender = ent.get("from")
        if sender not in NODES:
            raise FaultError(f"{w}.from = {sender!r}: with cob_id, say who sends the frames: plant or drive")
        f["sender"] = sender
    p = ent.get("probability", 1.0)
    if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0 < p <= 1:
        raise FaultError(f"{w}.probability = {p!r}: expected a number in (0, 1]")
    f["probability"] = float(p)
    f["seed"] = _int(w, "seed", ent.get("seed", seed), 0, 0xFFFFFFFF)
    f["count"] = _int(w, "count", ent.get("count", 0), 0, 0xFFFFFFFF)
    return f


def cob_ids(plant_id: int, drive_id: int) -> dict[str, int]:
    """Each frame name's COB-ID for these node-IDs, from the EDS files (their defaults, which the
    session wires the loop with)."""
    from bench.eds import load as load_od

    out = {"SYNC": int(load_od("plant", plant_id)[0x1005].default) & 0x7FF}
    for node, nid in (("plant", plant_id), ("drive", drive_id)):
        od = load_od(node, nid)
        for i in range(1, 5):
            out[f"{node}.TPDO{i}"] = int(od[0x1800 + i - 1][1].default) & 0x7FF
        out[f"{node}.heartbeat"] = 0x700 + nid  # CiA 301: NMT error control is 0x700 + node-ID
        out[f"{node}.EMCY"] = int(od[0x1014].default) & 0x7FF
    return out


# What a lockstep period waits on, by the EDS objects mapped: the drive steps on the sample (the plant's
# TPDO that carries Measurement.sample_index) and the plant waits for the drive's Voltage command. A lost
# SYNC or current frame (TPDO1) does not stall it: the drive still steps (late or on the held currents).
_AWAITED = {"plant": ("Measurement", "sample_index"), "drive": ("Voltage command", None)}


def loop_frames(plant_id: int | None = None, drive_id: int | None = None) -> dict[int, str]:
    """The frames a lockstep period cannot do without, COB-ID -> name, from the EDS files' default TPDO
    mappings: the plant's TPDO that maps the sample index (it triggers the drive's step) and the drive's
    TPDO that maps the voltage command (the plant produces the next SYNC when it has come)."""
    from bench.eds import default_node_id
    from bench.eds import load as load_od

    plant_id = default_node_id("plant") if plant_id is None else plant_id
    drive_id = default_node_id("drive") if drive_id is None else drive_id
    ids = cob_ids(plant_id, drive_id)
    out: dict[int, str] = {}
    for node, nid in (("plant", plant_id), ("drive", drive_id)):
        od = load_od(node, nid)
        record, member = _AWAITED[node]
        for i in range(4):
            mapping = od[0x1A00 + i]
            for k in range(1, int(mapping[0].default or 0) + 1):
                entry = int(mapping[k].default)
                obj = od[entry >> 16]
                if obj.name == record and (member is None or obj[(entry >> 8) & 0xFF].name == member):
                    out[ids[f"{node}.TPDO{i + 1}"]] = f"{node}.TPDO{i + 1}"
    return out


def refuse_lockstep_stalls(
    faults: list[Fault],
    where: str,
    timing: str,
    expect: tuple[str, ...],
    command_timeout_us: Callable[[int], float],
    compact: bool = False,
) -> None:
    """In lockstep with [drive] command_timeout_us = 0 (plant.eds 0x2003:04, its default) the plant waits for
    every command: a fault that takes a frame of the loop away (dropped, or delayed to a later period that
    cannot come) or freezes the drive stalls the loop; the run would wait 10 s of simulated time, then say
    frames_lost. Refused before anything starts, unless the scenario expects frames_lost.
    `command_timeout_us(period)`: the value in effect at that period (the scenario's, its events'); `compact`: the
    scenario's compact measurement frame ([frames]): the plant's TPDO1 carries the sample, not its TPDO2."""
    if timing != "lockstep" or "frames_lost" in expect:
        return
    from bench.eds import default_node_id

    loop = loop_frames()
    names = cob_ids(default_node_id("plant"), default_node_id("drive"))
    if compact:
        loop = {c: n for c, n in loop.items() if not n.startswith("plant.")} | {names["plant.TPDO1"]: "plant.TPDO1"}
    for f in faults:
        if command_timeout_us(f.at_period) > 0:
            continue
        if f.kind in ("drop", "delay") or (f.kind == "corrupt" and f.dlc is not None and f.dlc < 8):
            cob = names[f.frame] if f.frame else f.cob_id
            if cob not in loop:
                continue
            # a loop frame is 8 bytes (its EDS mapping); a shorter one is not processed (CiA 301): as dropped
            how = f"{f.kind} to DLC {f.dlc}" if f.kind == "corrupt" else f.kind
            what = f"a {how} of {f.frame or loop[cob]} (a frame of the loop)"
        elif f.kind == "freeze":
            what = "a frozen drive (it sends no command)"
        else:
            continue
        raise FaultError(
            f"{where}: faults[{f.index}] ({f.kind}, at_period {f.at_period}): {what} stalls a lockstep loop whose "
            "plant waits for every command ([drive] command_timeout_us = 0, plant.eds 0x2003:04): the run would "
            "stop after 10 s of simulated time with frames_lost. Set [drive] command_timeout_us > 0 (e.g. 20000) "
            'so the plant goes on without the missing command, or expect = "frames_lost" if the stall is the '
            "point"
        )


def rules_text(faults: list[Fault], plant_id: int, drive_id: int, measurement_mark: bool = False) -> str:
    """The injector's rules (protocols/faults/fault_rules.h), one line per fault, in order; `measurement_mark`: the
    plant's compact measurement frame (its TPDO1) starts the periods, not a SYNC ([frames] period_mark)."""
    ids = cob_ids(plant_id, drive_id)
    lines = [f"period_cob=0x{ids['plant.TPDO1']:03X}  # [frames] period_mark"] if measurement_mark and faults else []
    for f in faults:
        if f.kind in FRAME_KINDS:
            cob = ids[f.frame] if f.frame else f.cob_id
            assert f.sender is not None
            parts = [f"kind={f.kind}", f"from={SIDE[f.sender]}", f"cob=0x{cob:03X}"]
            parts.append(f"prob={f.probability!r}")
            parts += [f"seed={f.seed}", f"count={f.count}"]
            if f.kind == "delay":
                parts.append(f"delay_us={f.delay_us}" if f.delay_us else f"delay_periods={f.delay_periods}")
            if f.kind == "corrupt":
                parts.append(f"dlc={f.dlc}" if f.dlc is not None else f"bit={f.bit}")
        elif f.kind == "silence_heartbeat":
            assert f.node is not None
            parts = ["kind=drop", f"from={SIDE[f.node]}", f"cob=0x{ids[f.node + '.heartbeat']:03X}"]
        else:
            assert f.node is not None
            parts = [f"kind={f.kind}", f"from={SIDE[f.node]}"]
            if f.kind == "reset":
                parts.append(f"node_id=0x{plant_id if f.node == 'plant' else drive_id:02X}")
        parts += [f"at={f.at_period}", f"periods={f.periods}"]
        lines.append(" ".join(parts) + f"  # faults[{f.index}]")
    return "\n".join(lines) + ("\n" if lines else "")
