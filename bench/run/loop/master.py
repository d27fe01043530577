"""The master's canopen objects of a run: a Network and the two RemoteNodes, subscribed as the bench needs.

Over a bus they are made for each run. In direct mode they are kept between the runs of a process (a sweep runs
thousands of points in one worker): python canopen builds a RemoteNode's PDO maps by probing 512 numbers of its
object dictionary for each of its four map sets, about half a millisecond a node, for nodes that are the same
run after run. What a run changes in them is written again by the next run before it is used: the nodes are
reset (NMT), every PDO map the run wires is read from the EDS before it is changed (Configurator.wire_pdos),
and the bus and its SDO fast path are the run's own (Session.open). A run takes the kept master for the time
it runs (`take`, `give_back`); a second one at the same time (not possible in direct mode, whose nodes are
libhil's statics, but cheap to allow) gets new objects.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import canopen

from bench.eds import load as load_od


@dataclass
class Master:
    net: canopen.Network
    plant: canopen.RemoteNode
    drive: canopen.RemoteNode
    key: tuple[int | None, int | None] = (None, None)


def new_master(plant_id: int | None, drive_id: int | None) -> Master:
    """A Network with both nodes added and subscribed as a run needs (no bus yet: Session.open gives it one)."""
    net = canopen.Network()
    # The OD objects read once per process (bench/eds.py), shared with the decoder's SDO follower.
    plant = canopen.RemoteNode(plant_id, load_od("plant", plant_id))
    drive = canopen.RemoteNode(drive_id, load_od("drive", drive_id))
    for n in (plant, drive):
        net.add_node(n)
        # An SDO frame is always 8 bytes (CiA 301); canopen's client takes any frame on the identifier for
        # the answer and fails on a short one (struct.error): a foreign frame there is dropped instead.
        net.unsubscribe(n.sdo.tx_cobid, n.sdo.on_response)
        net.subscribe(n.sdo.tx_cobid, _sdo_answers_only(n.sdo))
        # canopen's EMCY consumer keeps every EMCY in an unbounded list, at a cost per frame: the decoder
        # lists the EMCYs from the record and the liveness judge takes 0x8130 itself, so a node that
        # floods EMCYs (one per foreign SYNC) must not slow the master's notifier thread with it
        net.unsubscribe(0x80 + n.id, n.emcy.on_emcy)
    return Master(net, plant, drive, (plant_id, drive_id))


_kept: dict[tuple[int | None, int | None], Master] = {}
_lock = threading.Lock()


def take(plant_id: int | None, drive_id: int | None) -> Master:
    """The master kept for these node-IDs (direct mode), or a new one."""
    with _lock:
        kept = _kept.pop((plant_id, drive_id), None)
    return kept if kept is not None else new_master(plant_id, drive_id)


def give_back(master: Master) -> None:
    """After a run (its bus shut down): kept for the next run of this process."""
    with _lock:
        _kept[master.key] = master


def _sdo_answers_only(sdo):  # type: ignore[no-untyped-def]
    def on_response(can_id: int, data: bytearray, ts: float) -> None:
        if len(data) == 8:
            sdo.on_response(can_id, data, ts)

    return on_response
