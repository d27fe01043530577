"""The plant's object 0x2008 "Flux map" refuses a download with the SDO abort code its EDS text names (issue 52):
a truncated table (fewer bytes than its header's sizes take, or not even the header) with CiA 301's 0x06070013
"length of service parameter too low", bytes beyond them with 0x06070012, a table whose bytes are all there but
whose values are not a map with 0x06090030; a refused download keeps the live map. The codes are read from the
EDS's Description of 0x2008 (the bench's EDS set, what a user's CANopen tool shows), the answers from the plant of
the in-process bus, over canopen's segmented SDO client."""

from __future__ import annotations

import re
import struct
from collections.abc import Iterator

import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError

from bench.eds import raw_eds
from bench.motor.example import example_map
from bench.paths import EDS_DIR
from bench.run.bus.direct import DirectBus, Hil

PLANT_ID, DRIVE_ID = 0x10, 0x20
FLUX_MAP = 0x2008


def _promised() -> tuple[str, dict[str, int]]:
    """0x2008's Description and the abort code it names for each kind of refusal."""
    text = raw_eds(str(EDS_DIR / "plant.eds")).get(f"{FLUX_MAP:04X}", "Description")
    found = {
        what: re.search(pattern, text)
        for what, pattern in {
            "truncated": r"a truncated table[^;]*?abort (0x[0-9A-Fa-f]{8})",
            "too long": r"more abort (0x[0-9A-Fa-f]{8})",
            "not a map": r"cannot be inverted abort (0x[0-9A-Fa-f]{8})",
        }.items()
    }
    missing = [what for what, m in found.items() if m is None]
    assert not missing, f"plant.eds [2008] names no abort code for: {', '.join(missing)}: {text}"
    return text, {what: int(m.group(1), 16) for what, m in found.items() if m is not None}


@pytest.fixture
def plant() -> Iterator[canopen.RemoteNode]:
    """The plant of a fresh in-process bus, PRE-OPERATIONAL before its first SYNC (0x2008 writable)."""
    hil = Hil(PLANT_ID, DRIVE_ID)
    net = canopen.Network()
    bus = DirectBus(hil)
    net.bus = bus
    net.connect()
    bus.attach(net.listeners)
    node = canopen.RemoteNode(PLANT_ID, str(EDS_DIR / "plant.eds"))
    net.add_node(node)
    try:
        yield node
    finally:
        bus.close_soon()
        net.disconnect()


def _answer(plant: canopen.RemoteNode, data: bytes) -> int:
    """0 for an accepted download, else the plant's abort code."""
    try:
        plant.sdo.download(FLUX_MAP, 0, data)
    except SdoAbortedError as exc:
        return int(exc.code)
    return 0


def test_a_truncated_flux_map_is_refused_with_the_code_the_eds_names(plant: canopen.RemoteNode) -> None:
    text, code = _promised()
    good = example_map().blob()
    assert _answer(plant, good) == 0
    live = plant.sdo.upload(FLUX_MAP, 0)
    assert live == good

    cut_grid = bytearray(good)
    struct.pack_into("<d", cut_grid, 16 + 8, -1e3)  # id_A[1] below id_A[0]: every byte there, not a map
    answers = {
        "the last value cut off": (_answer(plant, good[:-8]), code["truncated"]),
        "cut inside a value": (_answer(plant, good[:-3]), code["truncated"]),
        "cut inside the header": (_answer(plant, good[:10]), code["truncated"]),
        "one value too many": (_answer(plant, good + bytes(8)), code["too long"]),
        "a grid not increasing": (_answer(plant, bytes(cut_grid)), code["not a map"]),
    }
    wrong = {case: f"0x{got:08X} (plant.eds: 0x{want:08X})" for case, (got, want) in answers.items() if got != want}
    assert not wrong, wrong
    assert code["truncated"] == 0x06070013  # CiA 301: the length of the service parameter too low
    assert plant.sdo.upload(FLUX_MAP, 0) == live, "a refused download replaced the live map"
    # every code the text promises for a written map is one the plant gives (0x08000022: the state, tested elsewhere)
    named = {int(c, 16) for c in re.findall(r"0x0[0-9A-Fa-f]{7}", text)} - {0x08000022}
    assert named == {want for _, want in answers.values()}, text
