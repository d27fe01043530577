"""CAN FD frames in a run's log (issue 54 item 1): the wide record (bench/run/bus/frames.py FRAME_FD_DTYPE) written
by the C formatter as candump's "##" lines, read back by the C parser and by python-can's own readers, and exported
to .asc / .blf by python-can's writers with their length and bit-rate switch; a log whose CAN FD lines start after
classic ones reads in chunks of both records, which `join` puts together."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest

from bench.run.bus.frames import BRS, FDF, FRAME_DTYPE, FRAME_FD_DTYPE, fd_len, join, widen
from bench.run.record import canlog
from bench.run.record.canlog import CandumpWriter, export, parse_candump, read_frames

LENGTHS = (0, 1, 8, 12, 16, 20, 24, 32, 48, 64)


def fd_frames(n: int = 40, seed: int = 5) -> np.ndarray:
    """Classic and CAN FD frames of every CAN FD length, with and without the bit-rate switch, random payloads."""
    rng = np.random.default_rng(seed)
    f = np.zeros(n, dtype=FRAME_FD_DTYPE)
    f["t_us"] = np.arange(n) * 55 + 123
    f["seq"] = np.arange(n)
    f["cob_id"] = rng.integers(0, 0x800, n)
    f["sender"] = 255
    for i in range(n):
        length = LENGTHS[i % len(LENGTHS)]
        fd = length > 8 or i % 3 == 0
        f["dlc"][i] = length
        f["data"][i, :length] = rng.integers(0, 256, length)
        f["flags"][i] = (FDF | (BRS if i % 2 else 0)) if fd else 0
    return f


def same(a: np.ndarray, b: np.ndarray) -> None:
    for name in ("cob_id", "dlc", "data", "flags"):
        assert (a[name] == b[name]).all(), name


def test_fd_len_is_the_iso_table() -> None:
    assert [fd_len(n) for n in (0, 8, 9, 12, 13, 16, 17, 21, 25, 33, 49, 64)] == [
        0,
        8,
        12,
        12,
        16,
        16,
        20,
        24,
        32,
        48,
        64,
        64,
    ]
    with pytest.raises(ValueError):
        fd_len(65)


def test_candump_fd_lines_round_trip_through_the_c_parser_and_python_can(tmp_path: Path) -> None:
    frames = fd_frames()
    log = tmp_path / "fd.log"
    with CandumpWriter(log, "vcan0", 1_000_000) as w:
        w.write(frames)
    text = log.read_text()
    assert "##1" in text and "##0" in text  # candump's flags digit: 1 = bit-rate switch
    back = join(list(read_frames(log, chunk_frames=7)))
    assert back.dtype == FRAME_FD_DTYPE
    same(frames, back)
    assert (back["t_us"] == frames["t_us"] + 1_000_000).all()
    # python-can's reader, the reference: the same lengths, FD flags and payloads
    with can.LogReader(str(log)) as reader:
        msgs = list(reader)
    assert [len(m.data) for m in msgs] == frames["dlc"].tolist()
    assert [m.is_fd for m in msgs] == [bool(x & FDF) for x in frames["flags"]]
    assert [m.bitrate_switch for m in msgs] == [bool(x & BRS) for x in frames["flags"]]
    assert [bytes(m.data) for m in msgs] == [bytes(f["data"][: f["dlc"]]) for f in frames]


@pytest.mark.parametrize("fmt", ["asc", "blf"])
def test_fd_export_keeps_length_and_bit_rate_switch(tmp_path: Path, fmt: str) -> None:
    frames = fd_frames()
    if fmt == "asc":  # python-can's ASCReader drops a CAN FD frame of 0 bytes that its ASCWriter writes (the loop's
        frames = frames[(frames["dlc"] > 0) | (frames["flags"] == 0)]  # CAN FD PDOs have data: none of them)
    log = tmp_path / "fd.log"
    with CandumpWriter(log, "vcan0", 1_000_000) as w:
        w.write(frames)
    dst = tmp_path / f"fd.{fmt}"
    assert export(log, dst) == len(frames)
    back = join(list(read_frames(dst)))
    assert back.dtype == FRAME_FD_DTYPE
    same(frames, back)


def test_a_log_that_turns_fd_later_reads_in_both_records(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A run's configuration (classic SDO) fills the first blocks; the first CAN FD line comes later: the chunks
    before it stay classic, those after are wide, and `join` widens the classic ones. (The reader's block made
    small, so that the classic lines fill several blocks before the first CAN FD line.)"""
    monkeypatch.setattr(canlog, "_READ_BLOCK", 64 << 10)
    classic = np.zeros(5000, dtype=FRAME_DTYPE)
    classic["cob_id"] = 0x610
    classic["dlc"] = 8
    classic["t_us"] = np.arange(5000)
    fd = fd_frames(30)
    fd["t_us"] += 10_000
    log = tmp_path / "late.log"
    with CandumpWriter(log, "vcan0", 1_000_000) as w:
        w.write(classic)
        w.write(fd)
    chunks = list(read_frames(log, chunk_frames=1000))
    assert chunks[0].dtype == FRAME_DTYPE and chunks[-1].dtype == FRAME_FD_DTYPE
    back = join(chunks)
    assert len(back) == 5030
    same(widen(classic), back[:5000])
    same(fd, back[5000:])
    # a follower's block (parse_candump) picks the record by what it holds
    data = log.read_bytes()
    first, _, _ = parse_candump(data[:1000])
    assert first.dtype == FRAME_DTYPE
    all_of, used, skipped = parse_candump(data)
    assert all_of.dtype == FRAME_FD_DTYPE and used == len(data) and skipped == 0 and len(all_of) == 5030
