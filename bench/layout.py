"""The PDO layout of a run: which COB-ID carries which signals, read from the nodes
(canopen's PDO API over SDO) and saved beside the recording so any log can be decoded
later (`bench replay`)."""

from __future__ import annotations

import json
import struct
from dataclasses import asdict, dataclass, field
from pathlib import Path

import canopen
import numpy as np
from canopen.objectdictionary import datatypes

FMT = {datatypes.REAL32: "f", datatypes.UNSIGNED8: "B", datatypes.UNSIGNED16: "H", datatypes.UNSIGNED32: "I",
       datatypes.INTEGER8: "b", datatypes.INTEGER16: "h", datatypes.INTEGER32: "i", datatypes.BOOLEAN: "?"}


@dataclass
class PdoLayout:
    node: str           # 'plant' | 'drive'
    pdo: str            # 'TPDO1' ...
    cob_id: int
    trans_type: int
    signals: list[tuple[str, str]]  # (qualified name "Object.sub", struct format char)

    @property
    def fmt(self) -> str:
        return "<" + "".join(f for _, f in self.signals)

    def decode(self, data: bytes) -> tuple[float, ...]:
        return struct.unpack_from(self.fmt, data)

    def numpy_dtype(self) -> np.dtype:
        return np.dtype([(name, "<" + f) for name, f in self.signals])


@dataclass
class BusLayout:
    plant_id: int
    drive_id: int
    sync_cob_id: int
    pdos: list[PdoLayout] = field(default_factory=list)

    def by_cob(self) -> dict[int, PdoLayout]:
        return {p.cob_id: p for p in self.pdos}

    def find(self, node: str, signal: str) -> PdoLayout | None:
        return next((p for p in self.pdos if p.node == node and any(s == signal for s, _ in p.signals)), None)

    def save(self, path: Path) -> None:
        path.write_text(json.dumps(asdict(self), indent=2))

    @classmethod
    def load(cls, path: Path) -> "BusLayout":
        d = json.loads(path.read_text())
        pdos = [PdoLayout(p["node"], p["pdo"], p["cob_id"], p["trans_type"], [tuple(s) for s in p["signals"]])
                for p in d["pdos"]]
        return cls(d["plant_id"], d["drive_id"], d["sync_cob_id"], pdos)  # type: ignore[arg-type]


def read_layout(plant: canopen.RemoteNode, drive: canopen.RemoteNode) -> BusLayout:
    """Read the valid TPDOs of both nodes by SDO."""
    sync = plant.sdo["COB-ID SYNC message"].raw & 0x7FF
    layout = BusLayout(plant.id, drive.id, sync)
    for name, node in (("plant", plant), ("drive", drive)):
        node.tpdo.read()
        for num, m in node.tpdo.map.items():
            if not m.enabled or not m.map:
                continue
            sigs = [(f"{v.od.parent.name}.{v.od.name}" if v.od.parent else v.od.name, FMT[v.od.data_type])
                    for v in m.map]
            layout.pdos.append(PdoLayout(name, f"TPDO{num}", m.cob_id, m.trans_type, sigs))
    return layout
