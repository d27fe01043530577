"""pyserial's `socket://` port without the nap in its close: the master's port to a slot of the CAN box.

pyserial's socket handler sleeps 0.3 s in close() ("in case of quick reconnects, give the server some time"): a
fixed 0.3 s at the end of every run through the box (issue 56, item 3). The box's port is a QEMU chardev that
listens again as soon as its client has gone, and the next run connects only after its own slot's set-up, so the
nap buys nothing here. Registered through pyserial's own extension point (serial.protocol_handler_packages, the
URL scheme `boxsocket://HOST:PORT`) by `use()`; everything else is pyserial's."""

from __future__ import annotations

import socket

import serial
from serial.urlhandler import protocol_socket

SCHEME = "boxsocket"


def use(channel: str) -> str:
    """The `socket://` channel as this handler's URL, the handler registered (once per process)."""
    if __package__ not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(__package__)
    return SCHEME + channel[len("socket") :] if channel.startswith("socket://") else channel


class Serial(protocol_socket.Serial):
    def from_url(self, url: str) -> tuple[str, int]:
        return super().from_url("socket" + url[len(SCHEME) :])  # type: ignore[no-any-return]

    def close(self) -> None:
        if self.is_open and self._socket:
            try:
                self._socket.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            finally:
                self._socket.close()
            self._socket = None
        self.is_open = False
