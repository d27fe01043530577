"""What the master said to the nodes, read back from the frames: every expedited SDO
transfer on the bus, decoded with the EDS into the nodes' object-dictionary state.

A run's log is self-describing this way, with the EDS: the PDO layout (EDS defaults and what the master
writes to 0x1800/0x1A00 - over a bus it reads them first, in direct mode it knows them from the EDS - and a
CiA 402 master its drive's 0x1400/0x1600), the plant's parameters (read by
SDO at configuration), every setting and reference step with the period it took effect, and the
statuses read at the end are all SDO transfers on the bus. `bench run` and `bench replay` of its
log derive the same summary from the same frames.

Hand-written because python `canopen` decodes SDO only as a client of a live node; it has
no passive decoder for recorded traffic. Only expedited transfers are decoded (every
numeric entry is one; segmented ones carry strings: skipped).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import canopen
import numpy as np
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes

from bench.eds import load as load_od

STRUCT = {
    datatypes.BOOLEAN: "?",
    datatypes.INTEGER8: "b",
    datatypes.INTEGER16: "h",
    datatypes.INTEGER32: "i",
    datatypes.UNSIGNED8: "B",
    datatypes.UNSIGNED16: "H",
    datatypes.UNSIGNED32: "I",
    datatypes.REAL32: "f",
    datatypes.INTEGER64: "q",
    datatypes.UNSIGNED64: "Q",
    datatypes.REAL64: "d",
}


@dataclass
class SdoWrite:
    period: int  # the period it took effect (SYNCs seen before the request)
    node: str  # 'plant' | 'drive'
    name: str  # 'Object.sub' as in the EDS
    value: float


Tables = tuple[dict[tuple[int, int], ODVariable], dict[tuple[int, int], float]]


def _tables(od: canopen.ObjectDictionary) -> Tables:
    """Every entry of an OD by (index, sub) and the numeric EDS defaults, built once per OD object and kept on it
    (bench.eds caches the project's ODs: a sweep's worker decodes run after run with them); read only."""
    got: Tables | None = getattr(od, "_bench_sdo_tables", None)
    if got is not None:
        return got
    variables: dict[tuple[int, int], ODVariable] = {}
    defaults: dict[tuple[int, int], float] = {}
    for obj in od.values():
        subs = (
            [obj]
            if isinstance(obj, ODVariable)
            else list(obj.subindices.values())
            if isinstance(obj, (ODRecord, ODArray))
            else []
        )
        for v in subs:
            variables[(v.index, v.subindex)] = v
            if v.data_type in STRUCT and v.default is not None and not isinstance(v.default, (bytes, str)):
                defaults[(v.index, v.subindex)] = v.default
    od._bench_sdo_tables = (variables, defaults)  # type: ignore[attr-defined]
    return variables, defaults


@dataclass
class NodeState:
    """One node's object dictionary as the bus shows it: EDS defaults, then every confirmed
    expedited download and upload, in bus order."""

    name: str
    node_id: int
    values: dict[tuple[int, int], float] = field(default_factory=dict)
    pending: tuple[int, int, int, int, bytes] | None = None  # (ccs, index, sub, command, data) of the open request
    eds: Path | None = None  # the node's EDS when it is not the project's (a drive the bench did not build)
    written: set[tuple[int, int]] = field(default_factory=set)  # entries a confirmed download set (or assumed)

    def __post_init__(self) -> None:
        self.od = (
            load_od(self.name, self.node_id) if self.eds is None else canopen.import_od(str(self.eds), self.node_id)
        )
        self.vars, defaults = _tables(self.od)
        self.values.update(defaults)

    def qualname(self, index: int, sub: int) -> str | None:
        v = self.vars.get((index, sub))
        if v is None:
            return None
        return f"{v.parent.name}.{v.name}" if isinstance(v.parent, (ODRecord, ODArray)) else v.name

    def assume(self, values: dict[tuple[int, int], float]) -> None:
        """Entries as a master set them before the record began (a log whose configuration traffic is not in
        it): as if downloaded by SDO; the transfers on the bus still change them."""
        self.values.update(values)
        self.written.update(values)

    def get(self, name: str, sub: str | None = None) -> float | None:
        obj = self.od[name]
        v = obj if sub is None else obj[sub]
        return self.values.get((v.index, v.subindex))

    def _decode(self, index: int, sub: int, data: bytes) -> float | None:
        v = self.vars.get((index, sub))
        if v is None or v.data_type not in STRUCT:
            return None
        fmt = "<" + STRUCT[v.data_type]
        if struct.calcsize(fmt) > len(data):
            return None
        return struct.unpack_from(fmt, data)[0]

    def request(self, d: bytes) -> None:
        """A client frame: an initiate request (download ccs 1, upload ccs 2) opens a transfer."""
        ccs = d[0] >> 5
        self.pending = (ccs, d[1] | d[2] << 8, d[3], d[0], d[4:8]) if ccs in (1, 2) else None

    def response(self, d: bytes) -> tuple[str, int, int, float] | None:
        """A server frame: ('w' | 'r', index, sub, value) of a completed expedited transfer."""
        p, self.pending = self.pending, None
        if p is None:
            return None
        ccs, index, sub, cmd, data = p
        if (d[1] | d[2] << 8, d[3]) != (index, sub):
            return None
        scs = d[0] >> 5
        if ccs == 1 and scs == 3 and cmd & 0x02:  # expedited download, confirmed
            kind, payload, flags = "w", data, cmd
        elif ccs == 2 and scs == 2 and d[0] & 0x02:  # expedited upload response
            kind, payload, flags = "r", bytes(d[4:8]), d[0]
        else:  # abort (scs 4), segmented transfer: nothing stored
            return None
        n = 4 - ((flags >> 2) & 3) if flags & 0x01 else 4
        value = self._decode(index, sub, bytes(payload[:n]) + bytes(4))
        if value is None:
            return None
        self.values[(index, sub)] = value
        if kind == "w":
            self.written.add((index, sub))
        return kind, index, sub, value


class SdoLog:
    """The SDO traffic of a run, followed frame by frame (only SDO frames reach Python)."""

    def __init__(self, plant_id: int | None, drive_id: int, drive_eds: Path | None = None) -> None:
        """plant_id None: no plant node on the bus (the CiA 402 profile: the bench is the master of a drive);
        drive_eds: the drive's EDS when it is not the project's drive.eds."""
        plant = None if plant_id is None else NodeState("plant", plant_id)
        self.drive = NodeState("drive", drive_id, eds=drive_eds)
        self._plant = plant
        self.states = (self.drive,) if plant is None else (plant, self.drive)  # the nodes on the bus, plant first
        self.nodes = {s.node_id: s for s in self.states}
        self.writes: list[SdoWrite] = []
        self.transfers = 0  # completed expedited transfers seen (0: a log without configuration traffic)
        self._req_ids = np.array([0x600 + i for i in self.nodes], dtype=np.uint16)
        self._resp_ids = np.array([0x580 + i for i in self.nodes], dtype=np.uint16)

    def mask(self, frames: np.ndarray) -> np.ndarray:
        cob = frames["cob_id"]
        m = (cob > 0x580) & (cob < 0x680)  # the SDO ranges first: the PDO stream is most of the frames
        idx = np.flatnonzero(m)
        if len(idx):
            c = cob[idx]
            m[idx] = np.isin(c, self._req_ids) | np.isin(c, self._resp_ids)
        return m

    def feed(self, frames: np.ndarray, periods: np.ndarray) -> None:
        """SDO frames (see `mask`) in bus order, with the number of SYNCs seen before each."""
        # plain Python values, not a numpy scalar per field (a few hundred frames a run, run after run in a sweep)
        data = np.ascontiguousarray(frames["data"][:, :8]).tobytes()  # SDO: classic frames, also in a CAN FD run
        cobs, dlcs = frames["cob_id"].tolist(), frames["dlc"].tolist()
        for i, (cob, dlc, period) in enumerate(zip(cobs, dlcs, periods.tolist(), strict=True)):
            if dlc != 8:
                continue
            d = data[8 * i : 8 * i + 8]
            if cob >= 0x600:
                self.nodes[cob - 0x600].request(d)
                continue
            node = self.nodes[cob - 0x580]
            done = node.response(d)
            if done is not None:
                self.transfers += 1
            if done is not None and done[0] == "w":
                name = node.qualname(done[1], done[2])
                if name is not None:
                    self.writes.append(SdoWrite(int(period), node.name, name, float(done[3])))

    # ------------------------------------------------------------------ what the state tells
    @property
    def plant(self) -> NodeState:
        if self._plant is None:
            raise AttributeError("no plant node on this bus (the CiA 402 profile)")
        return self._plant

    @property
    def plant_id(self) -> int | None:
        return None if self._plant is None else self._plant.node_id

    @property
    def sync_node(self) -> NodeState:
        """Whose SYNC settings the bus follows: the plant's (it produces SYNC), else the drive's (a CiA 402
        master produces SYNC as the drive's 0x1005 and 0x1019 say)."""
        return self.drive if self._plant is None else self._plant

    @property
    def sync_cob_id(self) -> int:
        v = self.sync_node.values.get((0x1005, 0))  # COB-ID SYNC message
        return int(v or 0x80) & 0x7FF

    @property
    def sync_overflow(self) -> float | None:
        """The SYNC counter's overflow value (0x1019; below 2: SYNC without a counter)."""
        return self.sync_node.values.get((0x1019, 0))

    def changes(self, name: str, node: str = "drive") -> list[tuple[int, float]]:
        """(period, value) of every confirmed write of `name` ('Object.sub'), in bus order."""
        return [(w.period, w.value) for w in self.writes if w.node == node and w.name == name]
