"""The PDOs of a CiA 402 run: the reference the master looks for and maps when a drive lacks it, and the Layout
it used (kept in summary.json, assumed by the record's decoder).

The reference is the project's CiA 402 drive, read from protocols/eds/drive.eds: its RPDO4 {controlword, target
torque}, TPDO3 {statusword, mode display, torque actual, current actual} and TPDO4 {position, velocity actual},
with the COB-IDs, the SYNC and the rated values of its EDS.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from canopen import ObjectDictionary

from bench.eds import default_node_id
from bench.eds import load as load_od
from bench.run.decode.layout import PDO_INVALID, RECORDS

# drive.eds' PDOs the master uses: the one it sends (controlword and target torque), the statusword's, the motion's
REFERENCE_PDOS = ("RPDO4", "TPDO3", "TPDO4")
SYNC_TPDO = 1  # the master's TPDOs: synchronous, every SYNC
ASYNC_RPDO = 255  # the master's RPDO when it maps one itself: event-driven (its CAN_BCM task sends it)


@dataclass(frozen=True)
class Pdo:
    name: str  # "RPDO4", "TPDO3": PDO 4 received by the drive (records 0x1403/0x1603), PDO 3 sent (0x1802/0x1A02)
    cob_id: int
    trans_type: int
    entries: tuple[tuple[int, int, int], ...]  # (index, subindex, bits) in mapping order

    @property
    def number(self) -> int:
        return int(self.name[4:])

    @property
    def objects(self) -> tuple[int, ...]:
        return tuple(index for index, _, _ in self.entries)

    @property
    def size(self) -> int:
        """Data bytes of its frame."""
        return sum(bits for _, _, bits in self.entries) // 8

    def od_values(self) -> dict[tuple[int, int], float]:
        """The drive's communication and mapping entries of this PDO, as a master that set it up wrote them."""
        com, mapping = RECORDS[self.name[:4]]
        n = self.number - 1
        out: dict[tuple[int, int], float] = {
            (com + n, 1): self.cob_id,
            (com + n, 2): self.trans_type,
            (mapping + n, 0): len(self.entries),
        }
        for i, (index, sub, bits) in enumerate(self.entries, 1):
            out[(mapping + n, i)] = index << 16 | sub << 8 | bits
        return out


@dataclass
class Layout:
    """What the master used: the drive's SYNC settings, its PDOs, its rated values, the cycle."""

    drive_id: int
    sync_cob: int
    sync_overflow: int  # 0x1019: the counter the bench's SYNC carries (below 2: none)
    rpdo: Pdo
    tpdos: list[Pdo]
    rated_current_mA: int
    rated_torque_mNm: int
    cycle_s: float

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    def od_values(self) -> dict[tuple[int, int], float]:
        """The drive's entries as the master read and wrote them (bench/run/decode/sdo_log.py NodeState.assume)."""
        out: dict[tuple[int, int], float] = {
            (0x1005, 0): self.sync_cob,
            (0x1019, 0): self.sync_overflow,
            (0x6075, 0): self.rated_current_mA,
            (0x6076, 0): self.rated_torque_mNm,
        }
        for pdo in (self.rpdo, *self.tpdos):
            out.update(pdo.od_values())
        return out


def _default(od: ObjectDictionary, index: int, sub: int = 0) -> int:
    var = od.get_variable(index, sub)
    if var is None or var.default is None:
        raise KeyError(f"drive.eds has no default value of 0x{index:04X}:{sub:02X}")
    return int(var.default)


def reference_pdo(name: str, drive_id: int | None = None) -> Pdo:
    """One of drive.eds' PDOs as its EDS maps it, valid, with the transmission type the master gives it."""
    od = load_od("drive", default_node_id("drive") if drive_id is None else drive_id)
    com, mapping = RECORDS[name[:4]]
    n = int(name[4:]) - 1
    entries = []
    for sub in range(1, _default(od, mapping + n, 0) + 1):
        entry = _default(od, mapping + n, sub)
        entries.append((entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF))
    cob = _default(od, com + n, 1) & ~(PDO_INVALID | 0x40000000)  # without the valid and RTR bits
    return Pdo(name, cob, SYNC_TPDO if name.startswith("TPDO") else ASYNC_RPDO, tuple(entries))


def default_layout(drive_id: int | None = None, cycle_s: float = 0.001) -> Layout:
    """drive.eds' own PDOs (REFERENCE_PDOS) as the master sets them up, its SYNC and rated values (drive_id None:
    drive.eds' NodeID)."""
    if drive_id is None:
        drive_id = default_node_id("drive")
    od = load_od("drive", drive_id)
    rpdo, *tpdos = (reference_pdo(name, drive_id) for name in REFERENCE_PDOS)
    return Layout(
        drive_id,
        _default(od, 0x1005) & 0x7FF,
        _default(od, 0x1019),
        rpdo,
        tpdos,
        _default(od, 0x6075),
        _default(od, 0x6076),
        cycle_s,
    )
