"""Detect real SocketCAN on the host and bring up vcan interfaces.

The bench never fakes a bus: either the host kernel has AF_CAN (and a vcan
interface exists or can be created), or the CAN parts run inside the virtme-ng
micro-VM of :mod:`bench.run.bus.vm`.
"""

from __future__ import annotations

import errno
import json
import math
import os
import socket
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any


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


# ------------------------------------------------------------------ CAN controllers (link type `can`)
DEFAULT_BITRATE = 1_000_000  # the loop's frames at Ts = 100 us need most of a 1 Mbit/s bus (summary: bus_load)
RESTART_MS = 100  # a controller that went bus-off restarts by itself after this long (ip ... restart-ms)


class LinkError(RuntimeError):
    """A CAN link the bench cannot use as it is; the message says what it needs."""


def link_info(name: str) -> dict[str, Any] | None:
    """What the kernel reports of a network interface (`ip -details -statistics -json link show`): its kind
    (can, vcan, slcan...), whether it is up, and for a CAN controller its state, bit rate and error counters.
    None when there is no such interface or iproute2 cannot tell."""
    try:
        proc = subprocess.run(
            ["ip", "-details", "-statistics", "-json", "link", "show", name], capture_output=True, text=True
        )
    except OSError:
        return None
    if proc.returncode != 0:
        return None
    return link_info_json(proc.stdout)


def link_info_json(text: str) -> dict[str, Any] | None:
    """link_info from the JSON `ip -details -statistics -json link show NAME` printed (here, or in the CAN box)."""
    try:
        link = json.loads(text)[0]
    except (ValueError, IndexError):
        return None
    info = link.get("linkinfo", {})
    data = info.get("info_data", {})
    xstats = info.get("info_xstats", {})
    stats = link.get("stats64", {})
    out: dict[str, Any] = {
        "kind": info.get("info_kind", "can" if link.get("link_type") == "can" else link.get("link_type")),
        "up": "UP" in link.get("flags", []),
        "operstate": link.get("operstate"),
        "mtu": link.get("mtu"),  # 16: classic CAN frames only; 72: CAN FD too
        "rx_frames": stats.get("rx", {}).get("packets"),
        "tx_frames": stats.get("tx", {}).get("packets"),
        "rx_errors": stats.get("rx", {}).get("errors"),
        "tx_errors": stats.get("tx", {}).get("errors"),
        "rx_dropped": stats.get("rx", {}).get("dropped"),
        "tx_dropped": stats.get("tx", {}).get("dropped"),
    }
    if out["kind"] == "can":
        berr = data.get("berr_counter", {})
        out.update(
            {
                "state": data.get("state"),
                "bitrate": data.get("bittiming", {}).get("bitrate"),
                "restart_ms": data.get("restart_ms"),
                "berr_tx": berr.get("tx"),
                "berr_rx": berr.get("rx"),
                **{k: xstats.get(k) for k in ("restarts", "bus_error", "error_warning", "error_passive", "bus_off")},
                "arbitration_lost": xstats.get("arbitration_lost"),
            }
        )
    return out


def prepare_can_link(name: str, bitrate: int | None) -> str:
    """Bring a CAN controller up at its bit rate, as `ip link set NAME type can bitrate B restart-ms 100` and
    `ip link set NAME up` do (root or CAP_NET_ADMIN). A link already up is left as it is, unless it runs at
    another bit rate than asked. Virtual links (vcan, vxcan, slcan) have no bit rate: nothing to do.
    Returns what was done; raises LinkError saying what is needed."""
    info = link_info(name)
    if info is None:
        raise LinkError(f"{name}: no such network interface")
    if info["kind"] != "can":
        return f"{name}: {info['kind']} link, no bit rate"
    have = info.get("bitrate")
    if info["up"]:
        if bitrate is not None and have and have != bitrate:
            raise LinkError(
                f"{name} is up at {have} bit/s, not the --bitrate {bitrate} asked; every node on a bus runs at "
                f"one rate: drop --bitrate, or set it: ip link set {name} down && ip link set {name} type can "
                f"bitrate {bitrate} restart-ms {RESTART_MS} && ip link set {name} up"
            )
        return f"{name}: up at {have} bit/s, {info.get('state')}"
    rate = bitrate or have or DEFAULT_BITRATE
    cmds = [
        ["ip", "link", "set", name, "type", "can", "bitrate", str(rate), "restart-ms", str(RESTART_MS)],
        ["ip", "link", "set", name, "up"],
    ]
    for cmd in cmds:
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            why = proc.stderr.strip() or f"exit {proc.returncode}"
            rights = "" if os.geteuid() == 0 else " (as root or with CAP_NET_ADMIN)"
            raise LinkError(
                f"{name} is down and cannot be brought up by this user: `{' '.join(cmd)}` said: {why}. "
                f"Bring it up{rights}: sudo {' '.join(cmds[0])} && sudo {' '.join(cmds[1])}; or run the bench "
                "as root"
            )
    return f"{name}: brought up at {rate} bit/s" + ("" if bitrate else " (default)" if not have else "")


FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def classic_frame_bits(n_bytes: int) -> int:
    if not 0 <= n_bytes <= 8:
        raise ValueError(f"classic CAN carries 0..8 data bytes, not {n_bytes}")
    return 47 + 8 * n_bytes + (34 + 8 * n_bytes - 1) // 4


def fd_frame_bits(n_bytes: int) -> tuple[int, int]:
    """(bits at the nominal rate, bits at the data rate) of a CAN FD frame, worst case."""
    length = next((n for n in FD_LENGTHS if n >= n_bytes), None)
    if length is None:
        raise ValueError(f"CAN FD carries at most 64 data bytes, not {n_bytes}")
    nominal_bits = 17 + 4 + 13
    crc = 17 if length <= 16 else 21
    data_bits = 1 + 4 + 8 * length + (5 + 8 * length - 1) // 4 + 4 + crc + math.ceil((4 + crc) / 4)
    return nominal_bits, data_bits
