"""The PDO layout of a run: which COB-ID carries which signals. Read off the bus traffic
itself (bench/run/decode/decoder.py `layout_from_sdo`: the EDS defaults plus every SDO transfer to
0x1800/0x1A00), so a log decodes without any file beside it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from canopen.objectdictionary import datatypes

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


@dataclass
class PdoLayout:
    node: str  # 'plant' | 'drive'
    pdo: str  # 'TPDO1' ...
    cob_id: int
    trans_type: int
    signals: list[tuple[str, str]]  # (qualified name "Object.sub", format char)

    def numpy_dtype(self) -> np.dtype:
        return np.dtype([(name, "<" + f) for name, f in self.signals])


@dataclass
class BusLayout:
    plant_id: int
    drive_id: int
    sync_cob_id: int
    pdos: list[PdoLayout] = field(default_factory=list)
