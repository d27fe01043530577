"""The golden frame vectors, checked from the Python side: python `canopen` as the
master (reading the same EDS) must send exactly the vector's request bytes and decode
the vector's responses to the values the EDS and the request imply.

A responder on a python-can virtual bus plays the slave's side of each vector, and
fails the test if the master sends anything other than the next '>' frame.
The C side of the same vectors is protocols/tests/test_co_vectors.c.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import can
import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError

from bench.paths import EDS_DIR
from bench.tools.vectors import Frame, Vector, load_vectors

VECTORS = load_vectors()


class Responder(threading.Thread):
    """Plays the slave side: checks each master frame against the vector, answers with the '<' frames."""

    def __init__(self, channel: str, vector: Vector) -> None:
        super().__init__(daemon=True)
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.steps = list(vector.steps)
        self.errors: list[str] = []
        self.sent_by_master: list[Frame] = []
        self.stop = threading.Event()

    def run(self) -> None:
        while not self.stop.is_set():
            msg = self.bus.recv(timeout=0.05)
            if msg is None:
                continue
            got = Frame(msg.arbitration_id, bytes(msg.data))
            self.sent_by_master.append(got)
            if not self.steps or self.steps[0][0] != ">":
                self.errors.append(f"unexpected master frame {got}")
                continue
            _, want = self.steps.pop(0)
            if got != want:
                self.errors.append(
                    f"master sent {got.cob_id:03X}#{got.data.hex().upper()}, "
                    f"vector says {want.cob_id:03X}#{want.data.hex().upper()}"
                )
            while self.steps and self.steps[0][0] == "<":
                _, reply = self.steps.pop(0)
                self.bus.send(can.Message(arbitration_id=reply.cob_id, data=reply.data, is_extended_id=False))

    def close(self) -> None:
        self.stop.set()
        self.join(timeout=2)
        self.bus.shutdown()


@contextmanager
def master_for(vector: Vector) -> Iterator[tuple[canopen.Network, canopen.RemoteNode, Responder]]:
    channel = f"vec-{vector.name}-{time.monotonic_ns()}"
    responder = Responder(channel, vector)
    responder.start()
    net = canopen.Network()
    net.connect(interface="virtual", channel=channel)
    node = canopen.RemoteNode(vector.node_id, str(EDS_DIR / f"{vector.node}.eds"))
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    try:
        yield net, node, responder
    finally:
        net.disconnect()
        responder.close()


def _abort(node: canopen.RemoteNode, call: Callable[[], object]) -> int:
    with pytest.raises(SdoAbortedError) as exc:
        call()
    return exc.value.code


def drive_vector(name: str, net: canopen.Network, node: canopen.RemoteNode) -> None:
    od = node.object_dictionary
    motor = node.sdo["Motor model"] if "Motor model" in od else None
    if name == "sdo_expedited_download_real32":
        motor["R_ohm"].raw = 1.5
    elif name == "sdo_expedited_upload_real32":
        motor["R_ohm"].raw = 1.5
        assert motor["R_ohm"].raw == 1.5
    elif name == "sdo_expedited_upload_u32_identity":
        assert node.sdo["Identity object"]["Product code"].raw == od["Identity object"]["Product code"].default
    elif name == "sdo_abort_object_does_not_exist":
        assert 0x3000 not in od  # deliberately absent from the EDS
        assert _abort(node, lambda: node.sdo.upload(0x3000, 0)) == 0x06020000
    elif name == "sdo_abort_subindex_does_not_exist":
        assert 0x20 not in od["Motor model"].subindices
        assert _abort(node, lambda: node.sdo.upload(od["Motor model"].index, 0x20)) == 0x06090011
    elif name == "sdo_abort_read_only":
        assert od["Device type"].access_type == "ro"
        assert _abort(node, lambda: node.sdo.download(od["Device type"].index, 0, b"\0\0\0\0")) == 0x06010002
    elif name == "sdo_abort_value_too_high":

        def write() -> None:
            motor["R_ohm"].raw = 2000.0

        assert _abort(node, write) == 0x06090031
    elif name == "sdo_abort_length_too_long":
        pp = od["Motor model"]["pole_pairs"]
        assert (
            _abort(node, lambda: node.sdo.download(pp.index, pp.subindex, struct.pack("<I", 5), force_segment=False))
            == 0x06070012
        )
    elif name == "sdo_segmented_upload_string":
        assert node.sdo["Manufacturer device name"].raw == od["Manufacturer device name"].default
    elif name == "sdo_abort_restricted_sync_cobid":

        def write() -> None:
            node.sdo["COB-ID SYNC message"].raw = node.sdo.rx_cobid  # 0x600 + node-ID

        assert _abort(node, write) == 0x06090030
    elif name == "nmt_start_and_rpdo_references":
        node.nmt.send_command(0x01)
        node.rpdo.read(from_od=True)
        refs = node.rpdo[3]
        refs["References.iq_ref_A"].raw = 1.0
        refs["References.id_ref_A"].raw = 0.0
        refs.transmit()
        assert node.sdo["References"]["iq_ref_A"].raw == 1.0
    elif name == "sync_consumer_tpdo":
        node.tpdo.read(from_od=True)
        node.tpdo.subscribe()
        node.sdo["COB-ID SYNC message"].raw = 0x80
        node.nmt.send_command(0x01)
        net.sync.transmit(1)
        node.tpdo[2].wait_for_reception(timeout=2.0)
        assert node.tpdo[1]["Measurement.i_a_A"].raw == 0.0
        assert node.tpdo[2]["Measurement.sync_counter"].raw == 0
    else:
        raise AssertionError(f"vector {name} has no Python driver")


# Vectors python canopen cannot produce (it never sends a bad toggle bit or an invalid
# command specifier): their request bytes are checked by the C replay only.
C_ONLY = {
    "sdo_abort_toggle_bit": "canopen never sends a wrong toggle bit",
    "sdo_abort_invalid_command_specifier": "canopen never sends command specifier 7",
}


@pytest.mark.parametrize("name", sorted(VECTORS))
def test_vector_from_python_canopen(name: str) -> None:
    if name in C_ONLY:
        vec = VECTORS[name]
        assert vec.steps and vec.steps[-1][0] == "<"
        abort = vec.steps[-1][1].data
        assert abort[0] == 0x80, "C-only vectors must end in an SDO abort"
        return
    vec = VECTORS[name]
    with master_for(vec) as (net, node, responder):
        drive_vector(name, net, node)
        time.sleep(0.1)
        assert not responder.errors, responder.errors
        remaining = [s for s in responder.steps]
        assert not remaining, f"vector steps not exchanged: {remaining}"
