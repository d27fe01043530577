"""The master's port to a CAN box slot (bench/run/bus/box/protocol_boxsocket.py): pyserial's socket:// handler as
python-can's slcan interface opens it, without the 0.3 s nap pyserial's close takes."""

from __future__ import annotations

import socket
import threading

import can
import pytest
import serial
from serial.urlhandler import protocol_socket

from bench.run.bus.box.protocol_boxsocket import use


def test_the_channel_becomes_the_handlers_url_and_others_are_kept() -> None:
    assert use("socket://127.0.0.1:4000") == "boxsocket://127.0.0.1:4000"
    assert use("/dev/ttyACM0") == "/dev/ttyACM0"
    assert "bench.run.bus.box" in serial.protocol_handler_packages


def test_slcan_over_the_port_sends_and_closes_without_the_nap(monkeypatch: pytest.MonkeyPatch) -> None:
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    got: list[bytes] = []

    def serve() -> None:
        conn, _ = server.accept()
        with conn:
            while chunk := conn.recv(4096):
                got.append(chunk)

    t = threading.Thread(target=serve, daemon=True)
    t.start()

    def no_nap(s: float) -> None:
        raise AssertionError(f"the port's close slept {s} s")

    bus = can.Bus(interface="slcan", channel=use(f"socket://127.0.0.1:{port}"), sleep_after_open=0)
    try:
        bus.send(can.Message(arbitration_id=0x601, data=bytes(8), is_extended_id=False))
        monkeypatch.setattr(protocol_socket.time, "sleep", no_nap)  # pyserial's own handler would call it
        bus.shutdown()
    finally:
        server.close()
    t.join(timeout=5)
    assert b"t6018" + b"00" * 8 in b"".join(got)  # the SLCAN frame reached the other end
