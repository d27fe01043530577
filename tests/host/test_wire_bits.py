"""bench.tools.wire: CAN frames bit by bit, against published CRC check values, hand-stuffed frames and
bench/canbus.py's worst-case formula."""

from __future__ import annotations

import random

import pytest

from bench.canbus import FD_LENGTHS, classic_frame_bits, fd_frame_bits
from bench.tools.wire import (
    CRC15,
    CRC17,
    CRC21,
    WireBits,
    bytes_bits,
    classic_stream,
    crc,
    exact_bits,
    fd_stream,
    worst_bits,
)

CHECK = b"123456789"


def _bits(text: str) -> list[int]:
    """'0101 1' -> [0, 1, 0, 1, 1] (spaces for the reader only)."""
    return [int(c) for c in text if c in "01"]


def _long_division(bits: list[int], width: int, poly: int) -> int:
    """The CRC as the remainder of message * x^width divided by the generator (mod 2): another algorithm than
    the shift register under test."""
    generator = (1 << width) | poly
    value = int("".join(map(str, bits)) or "0", 2) << width
    for i in range(len(bits) + width - 1, width - 1, -1):
        if value >> i & 1:
            value ^= generator << (i - width)
    return value


@pytest.mark.parametrize(
    "spec, check",
    [(CRC15, 0x059E), (CRC17, 0x04F03), (CRC21, 0x0ED841)],  # CRC catalogue: CRC-15/CAN, CRC-17/CAN-FD, CRC-21/CAN-FD
)
def test_crc_check_values(spec: tuple[int, int], check: int) -> None:
    assert crc(bytes_bits(CHECK), *spec) == check
    assert _long_division(bytes_bits(CHECK), *spec) == check


def test_classic_all_zero_frame_stuffed_every_five_bits() -> None:
    # id 0, DLC 0: SOF, 11 id, RTR, IDE, r0, 4 DLC = 19 zeros; the CRC of an all-zero message is 0: 15 zeros.
    # 34 zeros: a stuff bit (1) after every 5 (the stuff bit starts the next run): 6 of them, after zero 30.
    stuffed = "000001 000001 000001 000001 000001 000001 0000"
    tail = "1 1 1 1111111 111"  # CRC delimiter, ACK slot, ACK delimiter, EOF, IFS
    frame = classic_stream(0x000, b"")
    assert frame.bits == _bits(stuffed + tail)
    assert frame.stuff == 6 and exact_bits(0x000, b"").total == 34 + 6 + 13
    assert exact_bits(0x000, b"").total < classic_frame_bits(0)


def test_classic_alternating_frame_has_no_stuff_bits() -> None:
    body = "0 01010101010 000 1000" + " 10101010" * 8  # SOF, id 0x2AA, RTR IDE r0, DLC 8, data 0xAA x 8
    crc_seq = _long_division(_bits(body), *CRC15)
    assert crc_seq == 0b100001111010110  # its longest run is 4 (hand-checked): the CRC needs no stuff bit
    frame = classic_stream(0x2AA, b"\xaa" * 8)
    assert frame.bits == _bits(body + " 100001111010110" + " 1 1 1 1111111 111")
    assert frame.stuff == 0 and frame.wire().nominal == 98 + 13


def test_classic_stuff_bit_inside_the_crc() -> None:
    body = "0 10101010101 000 1000" + " 01010101" * 8  # id 0x555, data 0x55 x 8: no stuff bit up to the data
    assert _long_division(_bits(body), *CRC15) == 0b001101100000100
    # the last data bit is 1; CRC 0011011 00000 (five zeros: a stuff 1) 100
    frame = classic_stream(0x555, b"\x55" * 8)
    assert frame.bits == _bits(body + " 0011011 00000 1 100" + " 1 1 1 1111111 111")
    assert frame.stuff == 1


def test_fd_zero_frame_bit_by_bit() -> None:
    """id 0, 8 zero bytes, bit-rate switch: the dynamic stuff bits, the stuff count and the fixed stuff bits."""
    frame = fd_stream(0x000, bytes(8))
    arbitration = "000001 000001 0000 1 0 1"  # SOF + 11 id + RRS + IDE = 14 zeros (2 stuff bits); FDF res BRS
    # ESI 0, DLC 1 000; DLC's 3 zeros + 64 data zeros = 67 zeros: a stuff bit after each 5th (13), the last two
    # zeros follow; no stuff bit after the last data bit.
    data = "0 1" + " 00000 1" * 13 + " 00"
    count = "1 1001"  # fixed stuff bit (not the last data bit 0); 15 stuff bits mod 8 = 7: Gray 100, parity 1
    head = _bits(arbitration + data + count)
    assert frame.bits[: len(head)] == head
    assert frame.stuff == 15
    crc_part = frame.bits[len(head) : -13]
    # a fixed stuff bit, the complement of the bit before it, before the CRC's first bit and after every 4th
    assert len(crc_part) == 17 + 5
    for k in (0, 5, 10, 15, 20):
        assert crc_part[k] != (crc_part[k - 1] if k else head[-1])
    assert frame.bits[-13:] == [1] * 13
    wire = frame.wire()
    assert wire.nominal == 17 + 2 + 13  # SOF .. BRS with its 2 stuff bits, the tail
    assert wire.data == 5 + 64 + 13 + 1 + 4 + 17 + 5  # ESI DLC data, stuff, FSB, count, CRC, its fixed stuff


def test_fd_alternating_frame_has_no_dynamic_stuff_bits() -> None:
    frame = fd_stream(0x555, b"\x55" * 8)
    head = _bits("0 10101010101 0 0 1 0 1 0 1000" + " 01010101" * 8 + " 0 0000 1")  # ... count 0: 000 + parity 0
    assert frame.bits[: len(head)] == head and frame.stuff == 0
    assert frame.wire().nominal == 17 + 13 and frame.wire().data == 5 + 64 + 1 + 4 + 1 + 17 + 4


def test_fd_without_bit_rate_switch_is_all_nominal() -> None:
    # BRS dominant: ... FDF 1, res 0, BRS 0, ESI 0, DLC 1 000, data 0 ...: runs of 3 and 4, no stuff bit
    wire = exact_bits(0x555, b"\x55" * 8, fd=True, brs=False)
    assert wire == WireBits(17 + 5 + 64 + 1 + 4 + 1 + 17 + 4 + 13, 0, 0)


def test_fd_crc21_above_16_bytes() -> None:
    frame = fd_stream(0x555, b"\x55" * 20)  # no dynamic stuff bits, 21-bit CRC, 7 fixed stuff bits
    assert frame.wire().data == 5 + 160 + 1 + 4 + 21 + 6


def test_worst_case_equals_the_formula() -> None:
    for n in range(9):
        assert worst_bits(n).total == classic_frame_bits(n)
    for n in FD_LENGTHS:
        w = worst_bits(n, fd=True)
        assert (w.nominal, w.data) == fd_frame_bits(n)
    assert worst_bits(8, extended=True).total == 54 + 64 + (54 + 64 - 1) // 4 + 13  # 29-bit: 20 more stuffable


def test_exact_never_exceeds_the_worst_case() -> None:
    rng = random.Random(54)
    for _ in range(2000):
        fd, extended = rng.random() < 0.5, rng.random() < 0.3
        n = rng.choice(FD_LENGTHS) if fd else rng.randint(0, 8)
        data = bytes(rng.getrandbits(8) for _ in range(n))
        can_id = rng.getrandbits(29 if extended else 11)
        exact, worst = exact_bits(can_id, data, fd, extended), worst_bits(n, fd, extended)
        assert exact.total <= worst.total and exact.stuff <= worst.stuff
        assert exact.time_s(1e6, 5e6) <= worst.time_s(1e6, 5e6) + 1e-12


def test_refusals() -> None:
    with pytest.raises(ValueError, match="0..8"):
        classic_stream(0x100, bytes(9))
    with pytest.raises(ValueError, match="64"):
        fd_stream(0x100, bytes(65))
    with pytest.raises(ValueError, match="11-bit"):
        exact_bits(0x800, b"")
