"""The direct bus's SDO transfers in one C call (bench/run/bus/direct_sdo.py) are python canopen's transfers:
the same sequence of reads, writes and refusals, done once by canopen's own client and once by the fast path
on two fresh in-process buses, puts the same frames on the bus log byte for byte, returns the same values and
raises the same abort codes; segmented objects (a string) still go through canopen's code. A server that is not
on the bus: the same request, canopen's abort frame after it (0x05040000, timed out), SdoCommunicationError."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import canopen
import numpy as np
import pytest
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench.paths import EDS_DIR
from bench.run.bus.direct import DirectBus, Hil
from bench.run.bus.direct_sdo import DirectSdo

PLANT_ID, DRIVE_ID = 0x10, 0x20
ABSENT_ID = 0x30  # no node answers there
VALUE_TOO_HIGH = 0x06090031
READ_ONLY = 0x06010002
NO_OBJECT = 0x06020000


def _session(fast: bool, script: Callable[..., list[Any]]) -> tuple[Any, Any]:
    hil = Hil(PLANT_ID, DRIVE_ID)
    net = canopen.Network()
    bus = DirectBus(hil)
    net.bus = bus
    net.connect()
    bus.attach(net.listeners)
    plant = canopen.RemoteNode(PLANT_ID, str(EDS_DIR / "plant.eds"))
    drive = canopen.RemoteNode(DRIVE_ID, str(EDS_DIR / "drive.eds"))
    absent = canopen.RemoteNode(ABSENT_ID, str(EDS_DIR / "drive.eds"))
    absent.sdo.RESPONSE_TIMEOUT = 0.02  # canopen's own client waits this long for the answer that never comes
    for n in (plant, drive, absent):
        net.add_node(n)
        if fast:
            DirectSdo(n.sdo, hil).install()
    hil.start_recorder(65536)
    try:
        results = script(plant, drive, absent)
        frames = hil.take()
    finally:
        bus.close_soon()
        net.disconnect()
    return results, frames


def _outcome(f: Callable[[], Any]) -> Any:
    try:
        return ("ok", f())
    except SdoAbortedError as exc:
        return ("abort", exc.code)
    except SdoCommunicationError as exc:
        return ("no answer", str(exc))


def _script(plant: canopen.RemoteNode, drive: canopen.RemoteNode, absent: canopen.RemoteNode) -> list[Any]:
    ctl = drive.sdo["Controller"]
    out: list[Any] = []
    out.append(_outcome(lambda: plant.sdo["Motor preset"].raw))  # a string: segmented, canopen's own code
    out.append(_outcome(lambda: plant.sdo["Sensors"]["rng_seed"].raw))
    for value in (7, 123456):
        out.append(_outcome(lambda value=value: setattr(plant.sdo["Sensors"]["rng_seed"], "raw", value)))
        out.append(_outcome(lambda: plant.sdo["Sensors"]["rng_seed"].raw))
    out.append(_outcome(lambda: setattr(ctl["Ts_s"], "raw", 50e-6)))  # REAL32
    out.append(_outcome(lambda: ctl["Ts_s"].raw))
    out.append(_outcome(lambda: setattr(ctl["Ts_s"], "raw", 1e9)))  # out of the EDS's range: the node refuses
    out.append(_outcome(lambda: setattr(drive.sdo["Statusword"], "raw", 0)))  # read only
    out.append(_outcome(lambda: drive.sdo.upload(0x5FFF, 0)))  # no such object
    out.append(_outcome(lambda: drive.sdo["Producer heartbeat time"].raw))  # UNSIGNED16
    out.append(_outcome(lambda: drive.sdo["Statusword"].raw))
    out.append(_outcome(lambda: absent.sdo["Statusword"].raw))
    out.append(_outcome(lambda: setattr(absent.sdo["Controlword"], "raw", 6)))
    return out


@pytest.fixture(scope="module")
def both() -> tuple[tuple[Any, Any], tuple[Any, Any]]:
    return _session(False, _script), _session(True, _script)


def test_the_fast_path_puts_canopens_frames_on_the_bus(both: Any) -> None:
    (_, slow), (_, fast) = both
    assert len(slow) > 20
    keep = ["cob_id", "dlc", "data", "sender", "t_us"]
    np.testing.assert_array_equal(fast[keep], slow[keep])


def test_the_fast_path_returns_canopens_values_and_aborts(both: Any) -> None:
    (slow, _), (fast, _) = both
    assert fast == slow
    codes = {r[1] for r in fast if r[0] == "abort"}
    assert {READ_ONLY, NO_OBJECT} <= codes and len(codes) == 3, codes  # and the range refusal
    assert fast[0] == ("ok", slow[0][1]) and isinstance(fast[0][1], str)  # the string came through canopen
    assert fast[3] == ("ok", 7) and fast[5] == ("ok", 123456)


def test_a_server_that_does_not_answer_gets_canopens_abort(both: Any) -> None:
    (slow, slow_frames), (fast, fast_frames) = both
    assert fast[-2:] == slow[-2:] == [("no answer", "No SDO response received")] * 2
    for frames in (slow_frames, fast_frames):
        to_absent = frames[frames["cob_id"] == 0x600 + ABSENT_ID]
        assert len(to_absent) == 4  # upload request, abort; download request, abort
        for abort in to_absent[1::2]:
            assert bytes(abort["data"][: abort["dlc"]]) == bytes([0x80, 0, 0, 0, 0x00, 0x00, 0x04, 0x05])


@pytest.mark.parametrize("ids", [(PLANT_ID, DRIVE_ID), (0x11, 0x2A)])
def test_the_in_process_nodes_pdo_maps_are_the_eds_defaults(ids: tuple[int, int]) -> None:
    """Direct mode reads the PDO maps it wires from the EDS (configure.py wire_pdos): every map of both nodes
    after a reset, read by SDO, is the map the EDS gives, at the default node-IDs and others."""
    from bench.eds import load as load_od

    hil = Hil(*ids)
    net = canopen.Network()
    bus = DirectBus(hil)
    net.bus = bus
    bus.attach(net.listeners)
    nodes = [canopen.RemoteNode(i, load_od(name, i)) for name, i in zip(("plant", "drive"), ids, strict=True)]
    try:
        for n in nodes:
            net.add_node(n)
            n.nmt.send_command(0x81)
        seen = 0
        for n in nodes:
            for maps in (n.tpdo, n.rpdo):
                for num in list(maps.map):
                    m = maps[num]
                    m.read()
                    by_sdo = (m.cob_id, m.enabled, m.trans_type, [(v.index, v.subindex, v.length) for v in m.map])
                    m.read(from_od=True)
                    by_eds = (m.cob_id, m.enabled, m.trans_type, [(v.index, v.subindex, v.length) for v in m.map])
                    assert by_sdo == by_eds, (n.id, num)
                    seen += 1
        assert seen == 16
    finally:
        net.disconnect()
