"""Detect real SocketCAN on the host and bring up vcan interfaces.

The bench never fakes a bus: either the host kernel has AF_CAN (and a vcan
interface exists or can be created), or the CAN parts run inside the virtme-ng
micro-VM of :mod:`bench.tools.vm`.
"""

from __future__ import annotations

import errno
import os
import socket
import subprocess
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class HostCan:
    af_can: bool
    errno_: int | None
    detail: str


def probe_af_can() -> HostCan:
    """Try to open a raw CAN socket on the host."""
    if not hasattr(socket, "AF_CAN"):
        return HostCan(False, None, "this Python has no socket.AF_CAN")
    try:
        socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except OSError as exc:
        name = errno.errorcode.get(exc.errno or 0, "?")
        return HostCan(False, exc.errno, f"socket(AF_CAN) fails: errno {exc.errno} ({name})")
    return HostCan(True, None, "socket(AF_CAN) works")


def interface_state(name: str) -> str | None:
    """'up', 'down' or None when the network interface does not exist."""
    base = Path("/sys/class/net") / name
    if not base.exists():
        return None
    try:
        flags = int((base / "flags").read_text().strip(), 16)
    except OSError:
        return "unknown"
    return "up" if flags & 0x1 else "down"


def can_interfaces() -> list[tuple[str, str]]:
    """(name, 'up'/'down') of every CAN network interface (ARPHRD_CAN = 280) of this machine."""
    out = []
    for d in sorted(Path("/sys/class/net").iterdir()) if Path("/sys/class/net").exists() else []:
        try:
            if (d / "type").read_text().strip() == "280":
                out.append((d.name, interface_state(d.name) or "unknown"))
        except OSError:
            continue
    return out


def ensure_vcan(name: str = "vcan0") -> str:
    """Make sure the vcan interface `name` exists and is up (needs root the first time)."""
    state = interface_state(name)
    if state == "up":
        return f"{name} already up"
    cmds = []
    if state is None:
        cmds += [["modprobe", "-a", "vcan", "can_raw"], ["ip", "link", "add", "dev", name, "type", "vcan"]]
    cmds += [["ip", "link", "set", name, "txqueuelen", "4000"], ["ip", "link", "set", "up", name]]
    for cmd in cmds:
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0 and cmd[0] != "modprobe":
            raise RuntimeError(f"`{' '.join(cmd)}` failed: {proc.stderr.strip()} (run as root)")
    return f"{name} created and up"


def host_has_vcan(name: str = "vcan0") -> bool:
    """True when CAN work can run on the host itself (AF_CAN and a usable vcan)."""
    if not probe_af_can().af_can:
        return False
    if interface_state(name) == "up":
        return True
    if os.geteuid() != 0:
        return False
    try:
        ensure_vcan(name)
    except RuntimeError:
        return False
    return True
