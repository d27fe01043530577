"""The exact length of a CAN frame on a physical bus, bit by bit, from its real identifier and payload.

A frame is laid out field by field, stuffed, its CRC computed, and its bits counted at the nominal and at the
data rate. Written by hand: python-can, cantools and canmatrix read and write logs, messages and signals, not
the bits on the wire, and no well-kept Python package encodes a CAN frame with its stuff bits (crcmod and
friends compute byte-wise CRCs; the CAN CRCs run over bit streams that are not whole bytes).

Classic CAN (ISO 11898-1, base and extended format): SOF, identifier (11 bits; or 11, SRR, IDE, 18), RTR,
IDE / r1, r0, DLC, data, CRC-15 (polynomial 0x4599, register starting at 0, over the unstuffed bits SOF .. data).
Every bit SOF .. CRC is stuffed: after five equal bits a complementary bit, which counts as the first of the
next run (so one after the last CRC bit too). Then CRC delimiter, ACK slot, ACK delimiter, 7 EOF and 3 bits of
intermission (IFS): 13 bits, none stuffed.

CAN FD (ISO 11898-1:2015, the "ISO" CRC): SOF, identifier (11; or 11, SRR, IDE, 18), RRS (dominant), IDE (base
format), FDF (recessive), res, BRS, ESI, DLC, data padded with 0x00 up to the FD length (0..8, 12, 16, 20, 24,
32, 48, 64). Dynamic stuffing as above from SOF through the data field, but no dynamic stuff bit after the last
bit of the data field (of the DLC when there is no data): the fixed stuff bit that follows is its complement
anyway. Then the stuff count: a fixed stuff bit (the complement of the bit before it), the number of dynamic
stuff bits modulo 8 in 3-bit Gray code and an even-parity bit; then the CRC sequence, CRC-17 (0x1685B) up to 16
data bytes, else CRC-21 (0x102899), with a fixed stuff bit (the complement of the bit before it) before its first
bit and after every fourth bit (none after the last). The CRC register starts at 1 followed by zeros (ISO;
the original Bosch FD 1.0 started at 0) and runs over SOF .. data including the dynamic stuff bits, then the 4
stuff-count bits; the fixed stuff bits are outside it. The tail is classic CAN's 13 bits.
With the bit-rate switch (BRS recessive) the bits after BRS (a stuff bit right after BRS included) up to the last
CRC bit run at the data rate; SOF .. BRS and CRC delimiter .. IFS at the nominal rate (the switch is at BRS's
and the CRC delimiter's sample points: those two bits are counted whole at the nominal rate, as
bench/canbus.py's formula does).

Sources checked: the CRC catalogue's parameters and check values (CRC-15/CAN 0x059E, CRC-17/CAN-FD 0x04F03,
CRC-21/CAN-FD 0x0ED841 for "123456789"); Vector's CAN FD e-learning (dynamic stuff bits counted in the CRC; fixed
stuff bits in the CRC field); the ISO/Bosch FD frame layouts (Molinaro's CANFDFrameGenerator; CTU CAN FD's
"ISO" CRC start value).

``worst_bits`` is the worst case bench/canbus.py's formula assumes (a stuff bit after every 4 bits after the
first 5), derived here from the same field lengths; ``exact <= worst`` in bits, and in time whenever the data
rate is at least the nominal rate (a dynamic stuff bit right after BRS runs at the data rate).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from bench.canbus import FD_LENGTHS

CRC15 = (15, 0x4599)
CRC17 = (17, 0x1685B)
CRC21 = (21, 0x102899)
TAIL_BITS = 13  # CRC delimiter, ACK slot, ACK delimiter, 7 EOF, 3 IFS
GRAY_PARITY = tuple(((n ^ (n >> 1)) << 1) | (bin(n ^ (n >> 1)).count("1") & 1) for n in range(8))


def crc(bits: Iterable[int], width: int, poly: int, init: int = 0) -> int:
    """The CRC shift register of ISO 11898-1 over a bit stream, first bit first (no reflection, no final xor)."""
    top, mask, reg = 1 << (width - 1), (1 << width) - 1, init
    for b in bits:
        feedback = b ^ (1 if reg & top else 0)
        reg = (reg << 1) & mask
        if feedback:
            reg ^= poly
    return reg


def int_bits(value: int, n: int) -> list[int]:
    """`value` as n bits, most significant first."""
    return [(value >> (n - 1 - i)) & 1 for i in range(n)]


def bytes_bits(data: bytes) -> list[int]:
    return [b for byte in data for b in int_bits(byte, 8)]


def fd_length(n_bytes: int) -> int:
    """The CAN FD data length that carries n bytes (the payload is padded up to it)."""
    for length in FD_LENGTHS:
        if length >= n_bytes:
            return length
    raise ValueError(f"CAN FD carries at most 64 data bytes, not {n_bytes}")


@dataclass(frozen=True)
class WireBits:
    """A frame's bits on the wire: at the nominal rate, at the data rate, and its (dynamic) stuff bits."""

    nominal: int
    data: int
    stuff: int

    @property
    def total(self) -> int:
        return self.nominal + self.data

    def time_s(self, bitrate: float, data_bitrate: float | None = None) -> float:
        return self.nominal / bitrate + self.data / (data_bitrate or bitrate)


@dataclass
class FrameStream:
    """The bits of one frame as sent, with each bit's rate (True: the data rate) and its dynamic stuff bits."""

    bits: list[int] = field(default_factory=list)
    fast: list[bool] = field(default_factory=list)
    stuff: int = 0
    _run: int = 0
    _last: int = 1  # the idle bus is recessive

    def put(self, bit: int, fast: bool = False) -> None:
        self.bits.append(bit)
        self.fast.append(fast)
        self._run = self._run + 1 if bit == self._last else 1
        self._last = bit

    def put_stuffed(
        self, bits: Iterable[int], fast: bool = False, last_unstuffed: bool = False, stuff_fast: bool | None = None
    ) -> None:
        """Bits under dynamic stuffing; `last_unstuffed`: no stuff bit after the last of them (FD data end);
        `stuff_fast`: the stuff bits' rate when it is not the bits' own (the one after BRS)."""
        seq = list(bits)
        for i, b in enumerate(seq):
            self.put(b, fast)
            if self._run == 5 and not (last_unstuffed and i == len(seq) - 1):
                self.put(1 - b, fast if stuff_fast is None else stuff_fast)
                self.stuff += 1

    def wire(self) -> WireBits:
        data = sum(self.fast)
        return WireBits(len(self.bits) - data, data, self.stuff)


def _identifier(can_id: int, extended: bool) -> tuple[list[int], list[int]]:
    """(base part, extension part) of an identifier's bits; the extension is empty for an 11-bit one."""
    if extended:
        if not 0 <= can_id < 1 << 29:
            raise ValueError(f"a 29-bit identifier is 0 .. 0x1FFFFFFF, not 0x{can_id:X}")
        return int_bits(can_id >> 18, 11), int_bits(can_id & 0x3FFFF, 18)
    if not 0 <= can_id < 1 << 11:
        raise ValueError(f"an 11-bit identifier is 0 .. 0x7FF, not 0x{can_id:X}")
    return int_bits(can_id, 11), []


def classic_stream(
    can_id: int, data: bytes, extended: bool = False, remote: bool = False, dlc: int = -1
) -> FrameStream:
    """A classic CAN data (or remote) frame, bit by bit."""
    if len(data) > 8:
        raise ValueError(f"classic CAN carries 0..8 data bytes, not {len(data)}")
    base, ext = _identifier(can_id, extended)
    rtr = 1 if remote else 0
    arb = [0, *base, 1, 1, *ext, rtr, 0, 0] if extended else [0, *base, rtr, 0, 0]  # ... r1, r0 / RTR, IDE, r0
    body = [*arb, *int_bits(len(data) if dlc < 0 else dlc, 4), *([] if remote else bytes_bits(data))]
    out = FrameStream()
    out.put_stuffed([*body, *int_bits(crc(body, *CRC15), 15)])
    for _ in range(TAIL_BITS):
        out.put(1)
    return out


def fd_stream(can_id: int, data: bytes, extended: bool = False, brs: bool = True, esi: bool = False) -> FrameStream:
    """A CAN FD data frame (ISO CRC), bit by bit; the payload padded with 0x00 to its FD length."""
    length = fd_length(len(data))
    payload = bytes(data) + bytes(length - len(data))
    base, ext = _identifier(can_id, extended)
    arb = [0, *base, 1, 1, *ext, 0, 1, 0] if extended else [0, *base, 0, 0, 1, 0]  # ... RRS, (IDE,) FDF, res
    width, poly = CRC21 if length > 16 else CRC17
    out = FrameStream()
    out.put_stuffed(arb)
    out.put_stuffed([1 if brs else 0], stuff_fast=brs)  # BRS; a stuff bit after it runs at the data rate
    tail = [1 if esi else 0, *int_bits(FD_LENGTHS.index(length), 4), *bytes_bits(payload)]
    out.put_stuffed(tail, brs, last_unstuffed=True)
    count = int_bits(GRAY_PARITY[out.stuff % 8], 4)
    sequence = int_bits(crc([*out.bits, *count], width, poly, 1 << (width - 1)), width)
    out.put(1 - out.bits[-1], brs)
    for b in count:
        out.put(b, brs)
    for i, b in enumerate(sequence):
        if i % 4 == 0:
            out.put(1 - out.bits[-1], brs)  # fixed stuff bit: before the CRC's first bit and after every 4th
        out.put(b, brs)
    for _ in range(TAIL_BITS):
        out.put(1)
    return out


def exact_bits(can_id: int, data: bytes, fd: bool = False, extended: bool = False, brs: bool = True) -> WireBits:
    """A frame's exact bits on the wire (nominal rate, data rate, stuff bits)."""
    if fd:
        return fd_stream(can_id, data, extended, brs).wire()
    return classic_stream(can_id, data, extended).wire()


def worst_bits(n_bytes: int, fd: bool = False, extended: bool = False, brs: bool = True) -> WireBits:
    """The worst case over every identifier and payload of this length, as bench/canbus.py's formula counts it:
    n stuffable bits hold at most (n - 1) // 4 stuff bits."""
    if not fd:
        if not 0 <= n_bytes <= 8:
            raise ValueError(f"classic CAN carries 0..8 data bytes, not {n_bytes}")
        stuffable = (1 + 11 + 2 + 18 + 3 if extended else 1 + 11 + 3) + 4 + 8 * n_bytes + 15
        stuff = (stuffable - 1) // 4
        return WireBits(stuffable + stuff + TAIL_BITS, 0, stuff)
    length = fd_length(n_bytes)
    arb = 1 + 11 + 2 + 18 + 4 if extended else 1 + 11 + 5  # SOF .. BRS
    control = 1 + 4 + 8 * length  # ESI, DLC, data
    width = CRC21[0] if length > 16 else CRC17[0]
    fixed = 2 + (width - 1) // 4  # before the stuff count, before the CRC, after every 4th CRC bit
    stuff_arb, stuff_data = (arb - 1) // 4, (control - 1) // 4
    fast = control + stuff_data + 4 + width + fixed
    nominal = arb + stuff_arb + TAIL_BITS
    return (
        WireBits(nominal, fast, stuff_arb + stuff_data) if brs else WireBits(nominal + fast, 0, stuff_arb + stuff_data)
    )
