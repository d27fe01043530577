"""python-can (this process) talks to a C process over vcan0 and checks the content."""

from __future__ import annotations

import struct
import subprocess

import can

from bench.paths import binary


def test_python_can_to_c_echo(vcan0: str) -> None:
    n = 50
    echo = subprocess.Popen(
        [str(binary("can_pingpong")), "echo", vcan0, str(n)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert echo.stdout is not None and echo.stdout.readline().strip() == "echo: ready"  # it listens
        with can.Bus(interface="socketcan", channel=vcan0, receive_own_messages=False) as bus:
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
        out, _ = echo.communicate(timeout=10)
    finally:
        if echo.poll() is None:
            echo.kill()
    assert echo.returncode == 0
    assert f"answered {n} pings" in out


def test_python_can_sees_frames_of_a_c_process(vcan0: str) -> None:
    """A C process sends; python-can receives the exact frames (ids, DLC, bytes)."""
    with can.Bus(interface="socketcan", channel=vcan0) as bus:
        pinger = subprocess.Popen(
            [str(binary("can_pingpong")), "ping", vcan0, "3"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        try:
            for seq in range(3):
                msg = bus.recv(timeout=5.0)
                assert msg is not None
                assert msg.arbitration_id == 0x181 and msg.dlc == 8
                assert struct.unpack("<II", msg.data) == (seq, (~seq) & 0xFFFFFFFF)
                reply = struct.pack("<II", seq, (seq * 2654435761) & 0xFFFFFFFF)
                bus.send(can.Message(arbitration_id=0x201, data=reply, is_extended_id=False))
            out, _ = pinger.communicate(timeout=10)
        finally:
            if pinger.poll() is None:
                pinger.kill()
    assert pinger.returncode == 0, out
    assert "3 answers verified, 0 bad" in out
