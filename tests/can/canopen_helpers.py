"""Shared pieces of the CANopen conformance tests over vcan."""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import can
import canopen
from can_site import Site

from bench.paths import EDS_DIR
from bench.run.bus.nodes import NodeProcess
from bench.run.options import BOX_STALL_S


class Capture(can.Listener):
    """Every frame seen on the bus, with its arrival time."""

    def __init__(self) -> None:
        self.frames: list[tuple[float, int, bytes]] = []
        self.lock = threading.Lock()

    def on_message_received(self, msg: can.Message) -> None:
        with self.lock:
            self.frames.append((time.monotonic(), msg.arbitration_id, bytes(msg.data)))

    def clear(self) -> None:
        with self.lock:
            self.frames.clear()

    def with_id(self, cob_id: int) -> list[bytes]:
        with self.lock:
            return [d for _, c, d in self.frames if c == cob_id]

    def wait_for_data(self, cob_id: int, data: bytes, timeout: float = 5.0) -> list[bytes]:
        """The frames of cob_id up to and with the first one carrying `data` (all of them if none came within
        the timeout, a bound). A frame the node sent before the event waited for may still arrive after a
        clear() on a loaded machine (python-can's receive thread is late): look for the frame, not at the
        first one."""
        deadline = time.monotonic() + timeout
        while True:
            got = self.with_id(cob_id)
            if data in got:
                return got[: got.index(data) + 1]
            if time.monotonic() >= deadline:
                return got
            time.sleep(0.005)

    def wait_for(self, cob_id: int, count: int = 1, timeout: float = 5.0) -> list[bytes]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            got = self.with_id(cob_id)
            if len(got) >= count:
                return got
            time.sleep(0.005)
        return self.with_id(cob_id)


# How long a test waits for frames that do come (wait_for returns as soon as they are there: a bound, not a
# timing): the CAN box's stall allowance (bench/run/options.py BOX_STALL_S). On a loaded 2-core host the box's
# emulation starved a node's answers for seconds: 2 of 20 SYNC-triggered TPDOs came within the former 3 s bound
# (issue 52's CAN phase under two busy loops).
ANSWER_S = BOX_STALL_S


@dataclass
class Target:
    """One C node process under test and the canopen master talking to it."""

    kind: str  # 'plant' or 'drive' (which EDS)
    node_id: int
    net: canopen.Network
    node: canopen.RemoteNode
    capture: Capture
    proc: NodeProcess

    def raw_sdo(self, payload: bytes, timeout: float = 5.0) -> bytes | None:
        """Send one raw SDO request frame, return the server's answer (or None). The bound is for an answer that
        comes: through the CAN box under two busy loops one took more than 2 s (a check for no answer passes its
        own short timeout)."""
        before = len(self.capture.with_id(0x580 + self.node_id))
        self.net.send_message(0x600 + self.node_id, payload)
        got = self.capture.wait_for(0x580 + self.node_id, before + 1, timeout)
        return got[before] if len(got) > before else None

    def abort_code(self, answer: bytes | None) -> int | None:
        if answer is None or answer[0] != 0x80:
            return None
        return struct.unpack_from("<I", answer, 4)[0]


def _grew(capture: Capture, last: list[int], timeout: float) -> bool | None:
    """True when the capture got frames within `timeout` (Site.drain's recv for a listener's bus)."""
    time.sleep(timeout)
    with capture.lock:
        n = len(capture.frames)
    grew, last[0] = n > last[0], n
    return True if grew else None


@contextmanager
def node_target(binary: str, args: list[str], kind: str, node_id: int, site: Site) -> Iterator[Target]:
    """`binary` started on the site's bus (the host's vcan0, or the session's slot of the CAN box:
    tests/can/can_site.py) with python canopen as its master on the host."""
    net = canopen.Network()
    net.connect(**site.bus_kwargs())
    capture = Capture()
    net.notifier.add_listener(capture)
    node = canopen.RemoteNode(node_id, str(EDS_DIR / f"{kind}.eds"))
    # an SDO answer's bound: in the CAN box as the bench's own (options.py BOX_STALL_S: QEMU's emulation under a loaded
    # host starved a node for over 3 s in a CI run under load, and 8 conformance tests failed with "No SDO response")
    node.sdo.RESPONSE_TIMEOUT = BOX_STALL_S if site.in_box else 3.0
    net.add_node(node)
    proc = site.node(binary, [*args, "--iface", site.iface, "--node-id", str(node_id)])
    if site.in_box:  # what the tap's console kept from before this connection (Site.drain)
        last = [0]
        Site.drain(lambda timeout: _grew(capture, last, timeout))
        capture.clear()
    proc.start()
    try:
        boot = capture.wait_for(0x700 + node_id, 1, timeout=10.0)
        assert boot and boot[0] == b"\x00", f"no boot-up message from {binary} (got {boot})"
        yield Target(kind, node_id, net, node, capture, proc)
    finally:
        rc = proc.stop()
        net.disconnect()
        assert rc in (0, None, -15), f"{binary} exited with {rc}"
