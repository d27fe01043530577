"""A serial CAN adapter (SLCAN, the Lawicel ASCII protocol) joined to a SocketCAN bus, as the drive node's
transport when the drive is the Cortex-M4F image (`bench run --drive mcu`, docs/PORTING.md).

The kernel does the per-frame work, never Python (inside the VM Python is ~50x slower): `slcand` attaches
the tty to the `slcan` line discipline as a CAN interface (slcan0), and two can-gw rules route every frame
between it and the bus both ways (`cangw -e`: echoed on the destination, so the recorder on the bus sees
the image's frames as its own interface would). can-gw routes a frame once (one hop): nothing loops.
Written by hand because python-can's slcan interface would put Python in the per-frame path.
"""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

from bench.run.bus.nodes import end_process

SLCAN_SPEED = "8"  # slcand -s8: 1 Mbit/s as the adapter announces it (the image's SLCAN ignores the rate)
UART_BAUD = "115200"  # the emulated 16550's highest rate; QEMU does not pace the line by it


class BridgeError(RuntimeError):
    """The SLCAN bridge could not be set up; the message says which step and what it printed."""


def _run(cmd: list[str]) -> None:
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise BridgeError(f"`{' '.join(cmd)}` failed: {(res.stderr or res.stdout).strip()}")


class SlcanBridge:
    """slcand on `tty` as `name`, routed to and from `bus`; stopped (rules removed, slcand ended) by stop().
    Has the `name`/`proc`/`alive()` of a node process: the run's liveness watch names it if slcand dies."""

    def __init__(self, tty: str, bus: str, name: str = "slcan0", log: Path | None = None) -> None:
        self.tty, self.bus, self.ifname, self.log = tty, bus, name, log
        self.name = "slcand"
        self.proc: subprocess.Popen[bytes] | None = None
        self._rules: list[list[str]] = []
        self._log_fh = None

    def start(self, timeout_s: float = 10.0) -> SlcanBridge:
        _run(["modprobe", "-a", "slcan", "can-gw"])
        out = subprocess.DEVNULL
        if self.log is not None:
            self._log_fh = open(self.log, "wb")  # noqa: SIM115 - closed in stop()
            out = self._log_fh  # type: ignore[assignment]
        argv = ["slcand", "-o", "-c", "-F", f"-s{SLCAN_SPEED}", "-S", UART_BAUD, self.tty, self.ifname]
        self.proc = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        deadline = time.monotonic() + timeout_s
        while not Path(f"/sys/class/net/{self.ifname}").exists():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise BridgeError(f"slcand did not attach {self.tty} as {self.ifname} within {timeout_s:.0f} s")
            time.sleep(0.05)
        _run(["ip", "link", "set", self.ifname, "txqueuelen", "1000", "up"])
        for src, dst in ((self.bus, self.ifname), (self.ifname, self.bus)):
            rule = ["-s", src, "-d", dst, "-e"]
            _run(["cangw", "-A", *rule])
            self._rules.append(rule)
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self, timeout_s: float = 5.0) -> int | None:
        for rule in self._rules:
            subprocess.run(["cangw", "-D", *rule], capture_output=True)
        self._rules = []
        if self.proc is None:
            return None
        return end_process(self.proc, self._log_fh, timeout_s)  # slcand closes the channel ('C'), detaches the tty
