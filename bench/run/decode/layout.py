"""The PDO layout of a run: which COB-ID carries which signals. Read off the bus traffic itself
(`layout_from_sdo`: the EDS defaults plus every SDO transfer to the PDO records), so a log decodes
without any file beside it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from canopen.objectdictionary import datatypes

if TYPE_CHECKING:
    from bench.run.decode.sdo_log import NodeState, SdoLog

# EDS data type -> numpy/struct format character of a mapped PDO entry.
FMT = {
    datatypes.REAL32: "f",
    datatypes.UNSIGNED8: "B",
    datatypes.UNSIGNED16: "H",
    datatypes.UNSIGNED32: "I",
    datatypes.INTEGER8: "b",
    datatypes.INTEGER16: "h",
    datatypes.INTEGER32: "i",
    datatypes.BOOLEAN: "?",
}
PDOS = 4  # the PDOs of each direction a node has (its EDS's 0x1400-0x1403, 0x1800-0x1803)
# (communication record, mapping record) of PDO 1 of each direction (CiA 301)
RECORDS = {"TPDO": (0x1800, 0x1A00), "RPDO": (0x1400, 0x1600)}
PDO_INVALID = 0x80000000  # bit 31 of a PDO's COB-ID entry: the PDO is not used


@dataclass
class PdoLayout:
    node: str  # 'plant' | 'drive'
    pdo: str  # 'TPDO1' ... (the node sends it) or 'RPDO1' ... (the node receives it from the master)
    cob_id: int
    trans_type: int
    signals: list[tuple[str, str]]  # (qualified name "Object.sub", format char)

    def numpy_dtype(self) -> np.dtype:
        return np.dtype([(name, "<" + f) for name, f in self.signals])

    @property
    def received(self) -> bool:
        """An RPDO of the node: the master sends it."""
        return self.pdo.startswith("RPDO")


@dataclass
class BusLayout:
    plant_id: int | None  # None: no plant node on the bus (the CiA 402 profile)
    drive_id: int
    sync_cob_id: int
    pdos: list[PdoLayout] = field(default_factory=list)


def layout_from_sdo(sdo: SdoLog, master_rpdos: bool = False) -> BusLayout:
    """The valid TPDOs of the nodes at this point of the bus traffic (EDS defaults + SDO seen). With
    `master_rpdos` (the CiA 402 profile, where the master sends the drive its RPDOs) also the drive's RPDOs
    the master set up: those whose COB-ID entry it wrote by SDO (or that were assumed so, NodeState.assume);
    the others are valid only by the EDS's defaults, for a producer that is not on this bus."""
    layout = BusLayout(sdo.plant_id, sdo.drive.node_id, sdo.sync_cob_id)
    for node in sdo.states:
        for n in range(PDOS):
            pdo = node_pdo(node, "TPDO", n)
            if pdo is not None:
                layout.pdos.append(pdo)
    if master_rpdos:
        com = RECORDS["RPDO"][0]
        for n in range(PDOS):
            pdo = node_pdo(sdo.drive, "RPDO", n) if (com + n, 1) in sdo.drive.written else None
            if pdo is not None:
                layout.pdos.append(pdo)
    return layout


def node_pdo(node: NodeState, kind: str, n: int) -> PdoLayout | None:
    """PDO n (0-based) of a node ('TPDO' or 'RPDO') as its entries stand, or None when it is not valid, maps
    nothing, or maps an entry the node's EDS does not have as a number."""
    com, mapping = RECORDS[kind]
    v = node.values
    cob = v.get((com + n, 1))
    count = int(v.get((mapping + n, 0)) or 0)
    if cob is None or int(cob) & PDO_INVALID or count == 0:
        return None
    sigs = []
    for i in range(1, count + 1):
        entry = int(v.get((mapping + n, i)) or 0)
        var = node.vars.get((entry >> 16, (entry >> 8) & 0xFF))
        if var is None or var.data_type not in FMT:
            return None
        sigs.append((node.qualname(var.index, var.subindex) or var.name, FMT[var.data_type]))
    return PdoLayout(node.name, f"{kind}{n + 1}", int(cob) & 0x7FF, int(v.get((com + n, 2)) or 0), sigs)
