"""python-can (this process) talks to a C process over vcan0 and checks the content: on the host's vcan0, or
through the session's slot of the CAN box (python-can's slcan interface on the slot's tap, as a user's script
would: tests/can/can_site.py)."""

from __future__ import annotations

import struct
from pathlib import Path

import can
from can_site import Site


def test_python_can_to_c_echo(site: Site, tmp_path: Path) -> None:
    n = 50
    log = tmp_path / "echo.out"
    echo = site.popen(["can_pingpong", "echo", site.iface, str(n)], log)
    try:
        assert site.wait_for_output(log, "echo: ready", 60), site.read(log)  # it listens
        with site.bus() as bus:
            for seq in range(n):
                payload = struct.pack("<II", seq, (~seq) & 0xFFFFFFFF)
                bus.send(can.Message(arbitration_id=0x181, data=payload, is_extended_id=False))
                while True:
                    msg = bus.recv(timeout=5.0)
                    assert msg is not None, f"no echo for seq {seq}"
                    if msg.arbitration_id == 0x201:
                        break
                got_seq, check = struct.unpack("<II", msg.data)
                assert msg.dlc == 8
                assert got_seq == seq
                assert check == (seq * 2654435761) & 0xFFFFFFFF
        assert echo.wait(timeout=10) == 0, site.read(log)
    finally:
        if echo.poll() is None:
            echo.kill()
    assert f"answered {n} pings" in site.read(log)


def test_python_can_sees_frames_of_a_c_process(site: Site, tmp_path: Path) -> None:
    """A C process sends; python-can receives the exact frames (ids, DLC, bytes)."""
    log = tmp_path / "ping.out"
    with site.bus() as bus:
        pinger = site.popen(["can_pingpong", "ping", site.iface, "3"], log)
        try:
            for seq in range(3):
                msg = bus.recv(timeout=30.0)  # a bound: the first waits for the process's start in the box
                assert msg is not None
                assert msg.arbitration_id == 0x181 and msg.dlc == 8
                assert struct.unpack("<II", msg.data) == (seq, (~seq) & 0xFFFFFFFF)
                reply = struct.pack("<II", seq, (seq * 2654435761) & 0xFFFFFFFF)
                bus.send(can.Message(arbitration_id=0x201, data=reply, is_extended_id=False))
            rc = pinger.wait(timeout=10)
        finally:
            if pinger.poll() is None:
                pinger.kill()
    assert rc == 0, site.read(log)
    assert "3 answers verified, 0 bad" in site.read(log)
