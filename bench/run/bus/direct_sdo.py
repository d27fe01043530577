"""SDO transfers of the direct bus in one C call each: python canopen's client, with its expedited transfers
(everything of four bytes or less: all the bench configures) handed whole to libhil's `hil_sdo`.

Why by hand: python canopen carries every transfer through its generic machinery (a CAN message object, the
network's send lock, the notifier's listeners, a response queue, a stream object), about 40 us a transfer
here, most of a sweep point's configuration. On the in-process bus the nodes answer while the request is
sent, so the transfer is one function call. It stays CANopen: the request frame is the one canopen sends
(CiA 301 expedited initiate download / upload), it goes through the node's SDO server and is recorded on the
bus log like any other frame, an abort raises canopen's SdoAbortedError with the server's code, a wrong
answer SdoCommunicationError. Segmented transfers (strings, domains) stay with canopen's own code.
"""

from __future__ import annotations

import ctypes
import struct
import types
from typing import TYPE_CHECKING

from can import CanOperationError
from canopen.sdo.constants import (
    ABORT_TIMED_OUT,
    EXPEDITED,
    REQUEST_DOWNLOAD,
    REQUEST_UPLOAD,
    RESPONSE_ABORTED,
    RESPONSE_DOWNLOAD,
    RESPONSE_UPLOAD,
    SDO_STRUCT,
    SIZE_SPECIFIED,
)
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

if TYPE_CHECKING:
    from canopen.sdo import SdoClient

    from bench.run.bus.direct import Hil


class DirectSdo:
    """Expedited SDO transfers of one node's client (canopen SdoClient) through `Hil.sdo`; `install` puts
    them in place of the client's `upload` / `download`, which canopen's variables, records and PDO maps call."""

    def __init__(self, client: SdoClient, hil: Hil) -> None:
        self.client = client
        self.hil = hil
        # canopen's own transfers (segmented ones), from the class: a client that had a DirectSdo before (a kept
        # master, bench/run/loop/master.py) must not call the earlier one, bound to an earlier bus
        self._upload = types.MethodType(type(client).upload, client)
        self._download = types.MethodType(type(client).download, client)
        self._req = ctypes.create_string_buffer(8)
        self._resp = ctypes.create_string_buffer(8)

    def install(self) -> None:
        self.client.upload = self.upload  # type: ignore[method-assign]
        self.client.download = self.download  # type: ignore[method-assign]

    def _size(self, index: int, subindex: int) -> int | None:
        """The object's size in bytes when the OD knows it and it fits an expedited transfer, else None;
        kept per OD (bench/eds.py caches one per process, shared by every run's client)."""
        od = self.client.od
        sizes: dict[tuple[int, int], int | None] | None = getattr(od, "_expedited_sizes", None)
        if sizes is None:
            sizes = {}
            od._expedited_sizes = sizes  # type: ignore[attr-defined]
        key = (index, subindex)
        if key not in sizes:
            var = od.get_variable(index, subindex)
            sizes[key] = None if var is None or not var.fixed_size or len(var) > 32 else len(var) // 8
        return sizes[key]

    def _transfer(self, command: int, index: int, subindex: int, data: bytes) -> bytes:
        req = bytearray(8)
        SDO_STRUCT.pack_into(req, 0, command, index, subindex)
        req[4 : 4 + len(data)] = data
        got = self.hil.sdo(self.client.rx_cobid, bytes(req), self.client.tx_cobid, self._resp)
        if got < 0:
            raise CanOperationError("the in-process bus's queue is full: the request was not sent")
        if got == 0:
            # a node that does not answer on the in-process bus never will (simulated time stands still):
            # the transfer ends as canopen ends it after its timeout, with its abort frame
            self.client.abort(ABORT_TIMED_OUT)
            raise SdoCommunicationError("No SDO response received")
        resp = self._resp.raw
        if resp[0] == RESPONSE_ABORTED:
            raise SdoAbortedError(struct.unpack_from("<L", resp, 4)[0])
        _, res_index, res_sub = SDO_STRUCT.unpack_from(resp)
        if (res_index, res_sub) != (index, subindex):
            raise SdoCommunicationError(
                f"Node returned a value for 0x{res_index:04X}:{res_sub:02X} instead, "
                "maybe there is another SDO client communicating on the same SDO channel?"
            )
        return resp

    def upload(self, index: int, subindex: int) -> bytes:
        size = self._size(index, subindex)
        if size is None:
            return self._upload(index, subindex)
        resp = self._transfer(REQUEST_UPLOAD, index, subindex, b"")
        command = resp[0]
        if command & 0xE0 != RESPONSE_UPLOAD:
            raise SdoCommunicationError(f"Unexpected response 0x{command:02X}")
        if not command & EXPEDITED:  # the server chose a segmented upload: not for four bytes or less
            raise SdoCommunicationError(f"Segmented answer 0x{command:02X} to an upload of {size} bytes")
        n = 4 - ((command >> 2) & 0x3) if command & SIZE_SPECIFIED else 4
        return resp[4 : 4 + min(n, size)]

    def download(self, index: int, subindex: int, data: bytes, force_segment: bool = False) -> None:
        if force_segment or not 0 < len(data) <= 4 or self._size(index, subindex) is None:
            self._download(index, subindex, data, force_segment)
            return
        command = REQUEST_DOWNLOAD | EXPEDITED | SIZE_SPECIFIED | ((4 - len(data)) << 2)
        resp = self._transfer(command, index, subindex, bytes(data))
        if resp[0] != RESPONSE_DOWNLOAD:
            raise SdoCommunicationError(f"Unexpected response 0x{resp[0]:02X}")
