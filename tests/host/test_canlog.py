"""bench/run/record/canlog.py and bench/direct/hil_log.c: the candump log written and read in C must
round-trip through python-can's own readers/writers and can-utils' log2asc."""

from __future__ import annotations

import ctypes
import gzip
import re
import shutil
import subprocess
import time
from pathlib import Path

import can
import numpy as np
import pytest

from bench.run.bus.frames import FRAME_DTYPE, join
from bench.run.record import canlog, messages
from bench.run.record.canlog import LOG_FORMATS, CandumpWriter, export, read_frames

LINE_RE = re.compile(rb"^\(\d{10}\.\d{6}\) vcan0 [0-9A-F]{3}#(?:[0-9A-F]{2}){0,8}$")


def random_frames(n: int, seed: int = 1) -> np.ndarray:
    """Random 11-bit data frames, simulated time from 0 (several frames may share a µs)."""
    rng = np.random.default_rng(seed)
    f = np.zeros(n, dtype=FRAME_DTYPE)
    f["t_us"] = np.cumsum(rng.integers(0, 60, n))
    f["cob_id"] = rng.integers(0, 0x800, n)
    f["cob_id"][:2] = (0, 0x7FF)
    f["dlc"] = rng.integers(0, 9, n)
    f["dlc"][:3] = (0, 8, 0)
    data = rng.integers(0, 256, (n, 8), dtype=np.uint8)
    data[np.arange(8)[None, :] >= f["dlc"][:, None]] = 0
    f["data"] = data
    f["seq"] = np.arange(n)
    f["sender"] = rng.integers(0, 2, n)
    return f


def t0_now() -> int:
    return int(time.time() * 1e6)


def same(a: np.ndarray, b: np.ndarray) -> None:
    """Equal in all fields but seq and sender."""
    assert len(a) == len(b)
    for k in ("t_us", "cob_id", "dlc", "data"):
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def from_messages(msgs: list[can.Message]) -> np.ndarray:
    """Independent conversion of python-can's messages (the reference) to FRAME_DTYPE."""
    out = np.zeros(len(msgs), dtype=FRAME_DTYPE)
    for i, m in enumerate(msgs):
        assert not m.is_extended_id and not m.is_remote_frame and not m.is_error_frame
        out[i]["t_us"] = round(m.timestamp * 1e6)
        out[i]["cob_id"] = m.arbitration_id
        out[i]["dlc"] = m.dlc
        assert m.dlc == len(m.data)
        out[i]["data"][: m.dlc] = np.frombuffer(bytes(m.data), dtype=np.uint8)
    return out


def absolute(frames: np.ndarray, t0: int) -> np.ndarray:
    out = frames.copy()
    out["t_us"] += np.uint64(t0)
    return out


def relative(frames: np.ndarray) -> np.ndarray:
    out = frames.copy()
    out["t_us"] -= out["t_us"][0]
    return out


@pytest.fixture
def written(tmp_path: Path) -> tuple[Path, np.ndarray]:
    """3000 random frames written by CandumpWriter in uneven chunks; (path, frames with absolute t_us)."""
    frames = random_frames(3000)
    t0 = t0_now()
    path = tmp_path / "run.log"
    with CandumpWriter(path, "vcan0", t0) as w:
        for a, b in ((0, 1), (1, 1), (1, 100), (100, 2999), (2999, 3000)):
            w.write(frames[a:b])
        assert w.frames == 3000
    return path, absolute(frames, t0)


def test_formats() -> None:
    assert LOG_FORMATS == ("log", "asc", "blf")


def test_writer_lines_are_candump_format(written: tuple[Path, np.ndarray]) -> None:
    path, frames = written
    lines = path.read_bytes().split(b"\n")
    assert lines[-1] == b"" and len(lines) == len(frames) + 1
    for line in lines[:-1]:
        assert LINE_RE.match(line), line
    f = frames[0]
    sec, us = divmod(int(f["t_us"]), 1_000_000)
    assert lines[0] == f"({sec:010d}.{us:06d}) vcan0 {int(f['cob_id']):03X}#".encode()  # dlc 0: '#' alone
    f = frames[1]
    assert lines[1].endswith(b" 7FF#" + bytes(f["data"]).hex().upper().encode())


def test_python_can_reads_our_log(written: tuple[Path, np.ndarray]) -> None:
    path, frames = written
    msgs = list(can.io.CanutilsLogReader(path))
    assert all(m.channel == "vcan0" and not m.is_fd for m in msgs)
    same(from_messages(msgs), frames)


@pytest.mark.parametrize("chunk", [1 << 20, 7, 1, 2999, 3000])
def test_read_frames_round_trip(written: tuple[Path, np.ndarray], chunk: int) -> None:
    path, frames = written
    it = read_frames(path, chunk_frames=chunk)
    chunks = list(it)
    assert all(len(c) == chunk for c in chunks[:-1]) and 0 < len(chunks[-1]) <= chunk
    got = np.concatenate(chunks)
    same(got, frames)
    np.testing.assert_array_equal(got["seq"], np.arange(len(frames)))
    assert (got["sender"] == 255).all()
    assert it.skipped == 0 and it.frames == len(frames)


def test_read_frames_small_blocks(written: tuple[Path, np.ndarray], monkeypatch: pytest.MonkeyPatch) -> None:
    """Lines split across the file's read blocks: none lost, none doubled."""
    path, frames = written
    for block in (64, 97, 200):
        monkeypatch.setattr(canlog, "_READ_BLOCK", block)
        for chunk in (5, 1 << 20):
            it = read_frames(path, chunk_frames=chunk)
            same(np.concatenate(list(it)), frames)
            assert it.skipped == 0


def test_partial_last_line(tmp_path: Path, written: tuple[Path, np.ndarray]) -> None:
    path, frames = written
    text = path.read_bytes()
    # a complete last line without its '\n' is still a frame
    p = tmp_path / "no_newline.log"
    p.write_bytes(text[:-1])
    it = read_frames(p, chunk_frames=7)
    same(np.concatenate(list(it)), frames)
    assert it.skipped == 0 and it.unparsable == 0
    assert it.truncated_line == len(frames) and not it.truncated_dropped  # said: its '\n' is missing
    # a line cut in the middle (a recorder killed mid-write): dropped, said as the truncated line (its
    # number), neither a skipped frame nor an unparsable line
    last = text.rstrip(b"\n").rsplit(b"\n", 1)[1]
    p.write_bytes(text + last[:12])
    it = read_frames(p)
    same(np.concatenate(list(it)), frames)
    assert (it.skipped, it.unparsable, it.first_unparsable_line) == (0, 0, None)
    assert it.truncated_line == len(frames) + 1 and it.truncated_dropped
    # a complete log is not truncated
    it = read_frames(path)
    list(it)
    assert it.truncated_line is None


def test_parse_stops_before_partial_line() -> None:
    """hil_log_parse itself: *consumed ends at the last complete line, the rest parses once fed again."""
    lib = canlog._hil()
    buf = b"(1700000000.000001) can0 123#11\n(1700000000.000002) can0 124#2233\n(1700000000.0000"
    out = np.zeros(4, dtype=FRAME_DTYPE)
    consumed, skipped = ctypes.c_uint64(), ctypes.c_uint64()
    n = lib.hil_log_parse(buf, len(buf), out.ctypes.data, 4, ctypes.byref(consumed), ctypes.byref(skipped))
    assert (n, consumed.value, skipped.value) == (2, buf.rindex(b"(1700000000.0000"), 0)
    assert out["t_us"][:2].tolist() == [1700000000000001, 1700000000000002]
    assert out["dlc"][:2].tolist() == [1, 2] and out["data"][1][:3].tolist() == [0x22, 0x33, 0]
    assert (out["sender"][:2] == 255).all() and (out["seq"][:2] == 0).all()
    rest = buf[consumed.value :] + b"03) can0 7FF#\n"
    n = lib.hil_log_parse(rest, len(rest), out.ctypes.data, 4, ctypes.byref(consumed), ctypes.byref(skipped))
    assert (n, consumed.value) == (1, len(rest))
    assert (out["cob_id"][0], out["dlc"][0], out["t_us"][0]) == (0x7FF, 0, 1700000000000003)
    # out full: stops after cap frames, the caller goes on from *consumed
    n = lib.hil_log_parse(buf, len(buf), out.ctypes.data, 1, ctypes.byref(consumed), ctypes.byref(skipped))
    assert (n, consumed.value) == (1, buf.index(b"\n") + 1)


def test_format_capacity() -> None:
    """hil_log_format returns 0 when cap cannot hold all lines; 46 + len(channel) a line is enough."""
    lib = canlog._hil()
    f = random_frames(50)
    f["dlc"] = 8
    f["t_us"] = np.uint64(2**64 - 1)  # the longest time stamp: 14 digits of seconds
    assert lib.hil_log_line_max(b"vcan0") == 51
    assert lib.hil_log_line_max(b"") == 0 and lib.hil_log_line_max(b"a b") == 0
    buf = ctypes.create_string_buffer(50 * 51)
    n = lib.hil_log_format(f.ctypes.data, 50, 0, b"vcan0", buf, 50 * 51)
    assert n == 50 * 51
    assert lib.hil_log_format(f.ctypes.data, 50, 0, b"vcan0", buf, 50 * 51 - 1) == 0
    short = f.copy()
    short["t_us"] = 1700000000_000000
    short["dlc"] = 0
    n = lib.hil_log_format(short.ctypes.data, 50, 0, b"vcan0", buf, 50 * 51)
    assert n == 50 * len("(1700000000.000000) vcan0 123#\n")
    assert lib.hil_log_format(short.ctypes.data, 50, 0, b"vcan0", buf, n) == n  # exact fit
    assert lib.hil_log_format(short.ctypes.data, 50, 0, b"vcan0", buf, n - 1) == 0


def test_python_can_writer_log_parses_the_same(tmp_path: Path) -> None:
    """A log written by python-can's CanutilsLogWriter (with its ' R' / ' T' suffix) reads the
    same through read_frames as through python-can's reader."""
    frames = absolute(random_frames(1000, seed=2), t0_now())
    path = tmp_path / "pycan.log"
    with can.Logger(str(path)) as logger:
        for i, m in enumerate(messages.to_messages(frames)):
            m.is_rx = i % 3 != 0
            logger.on_message_received(m)
    assert b" T\n" in path.read_bytes() and b" R\n" in path.read_bytes()
    ref = from_messages(list(can.LogReader(str(path))))
    same(ref, frames)
    for chunk in (1 << 20, 7):
        it = read_frames(path, chunk_frames=chunk)
        same(np.concatenate(list(it)), ref)
        assert it.skipped == 0


@pytest.mark.parametrize("ext", ["asc", "blf"])
def test_export_python_can_formats(written: tuple[Path, np.ndarray], ext: str) -> None:
    path, frames = written
    dst = path.with_suffix("." + ext)
    seen: list[int] = []
    assert export(path, dst, progress=seen.append) == len(frames)
    assert seen and seen[-1] == len(frames) and seen == sorted(seen)
    msgs = list(can.LogReader(str(dst)))
    got = from_messages(msgs)
    if ext == "asc":  # .asc keeps µs relative to the first frame (its absolute start only in ms)
        same(got, relative(frames))
    else:  # .blf keeps absolute time stamps (ns)
        same(got, frames)
    # read_frames reads them back through python-can, in chunks too
    for chunk in (1 << 20, 7):
        it = read_frames(dst, chunk_frames=chunk)
        arr = np.concatenate(list(it))
        same(arr, got)
        np.testing.assert_array_equal(arr["seq"], np.arange(len(frames)))
        assert it.skipped == 0


def test_export_to_log(written: tuple[Path, np.ndarray], tmp_path: Path) -> None:
    path, frames = written
    blf = tmp_path / "x.blf"
    export(path, blf)
    back = tmp_path / "back.log"
    assert export(blf, back) == len(frames)
    same(from_messages(list(can.LogReader(str(back)))), frames)


def log2asc() -> str:
    exe = shutil.which("log2asc")
    assert exe, "log2asc missing: install the Debian package can-utils (make setup)"
    return exe


def test_log2asc_reads_our_log(written: tuple[Path, np.ndarray], tmp_path: Path) -> None:
    """can-utils' log2asc converts our log with exactly one header. It needs the channel names as
    arguments (frames of other channels are dropped silently) and absolute time stamps: it takes a
    0 seconds field for "no header yet" and repeats the header for each frame of the first second."""
    path, frames = written
    out = tmp_path / "log2asc.asc"
    subprocess.run([log2asc(), "-I", str(path), "-O", str(out), "vcan0"], check=True, timeout=60)
    lines = out.read_text().splitlines()
    assert sum(line.startswith("date ") for line in lines) == 1
    assert sum(line.startswith("base hex") for line in lines) == 1
    # its output is an .asc python-can reads back: the same frames, µs relative to the first
    same(from_messages(list(can.LogReader(str(out)))), relative(frames))


MIXED = """\
(1700000000.000001) vcan0 123#1122

(1700000000.000002) vcan0 12345678#1122
(1700000000.000003) vcan0 20000080#0000000000000000
(1700000000.000004) vcan0 123#R
(1700000000.000005) vcan0 123#R5
(1700000000.000006) vcan0 123##1112233445566778899AABBCC
(1700000000.000007) vcan0 1FF##0AABB
(1700000000.000008) vcan0 124#
   (1700000000.000009)   can1   7FF#0102030405060708   R\r
"""
MIXED_VALID = [
    (1700000000_000001, 0x123, b"\x11\x22"),
    (1700000000_000006, 0x123, bytes.fromhex("112233445566778899AABBCC")),  # CAN FD, 12 bytes: a frame of ours
    (1700000000_000007, 0x1FF, b"\xaa\xbb"),
    (1700000000_000008, 0x124, b""),
    (1700000000_000009, 0x7FF, bytes(range(1, 9))),
]
MIXED_SKIPPED = 4  # extended, error, 2 remote


def check_valid(arr: np.ndarray, expect: list[tuple[int, int, bytes]]) -> None:
    assert [(int(f["t_us"]), int(f["cob_id"]), bytes(f["data"][: f["dlc"]])) for f in arr] == expect


def test_skipped_like_python_can(tmp_path: Path) -> None:
    """Frames that are not 11-bit data frames (classic of <= 8 bytes, CAN FD of <= 64) are skipped and counted, the
    same by the C parser (.log) and through python-can (the same file gzipped: .log.gz goes through can.LogReader)."""
    path = tmp_path / "mixed.log"
    path.write_text(MIXED)
    gz = tmp_path / "mixed.log.gz"
    gz.write_bytes(gzip.compress(MIXED.encode()))
    for p in (path, gz):
        it = read_frames(p, chunk_frames=3)
        check_valid(join(list(it)), MIXED_VALID)
        assert it.skipped == MIXED_SKIPPED, p


MALFORMED = [
    b"garbage",
    b"(",
    b"()",
    b"(1700000000.000001)",
    b"(1700000000.000001) vcan0",
    b"(x.1) vcan0 123#11",
    b"(.000001) vcan0 123#11",
    b"(1700000000.000001 vcan0 123#11",
    b"1700000000.000001 vcan0 123#11",
    b"(1700000000.000001)vcan0 123#11",
    b"(1700000000.000001) vcan0 123#1",
    b"(1700000000.000001) vcan0 123#1G",
    b"(1700000000.000001) vcan0 800#11",
    b"(1700000000.000001) vcan0 1234#11",
    b"(1700000000.000001) vcan0 #11",
    b"(1700000000.000001) vcan0 123",
    b"(1700000000.000001) vcan0 123#112233445566778899",
    b"(1700000000.000001) vcan0 123## ",
    b"(1700000000.000001) vcan0 123#11 X",
    b"(1700000000.000001) vcan0 123#11 R T",
    b"(99999999999999999999.000001) vcan0 123#11",
    b"(1700000000.000001) vcan0 1 2#11",
    b"\x00\xff\x80(\x01",
]
MALFORMED_FRAMES = [b"(1700000000.000001) vcan0 1234#11"]  # a frame (extended ID), not ours
SILENT = [b"", b"   \r", b"# a comment", b"  ; another comment"]  # skipped without being counted


def test_garbage(tmp_path: Path) -> None:
    """Malformed lines and random bytes: no crash, each malformed line counted, the valid lines
    between them still read."""
    rng = np.random.default_rng(3)
    valid = [
        b"(1700000000.%06d) vcan0 %03X#%s" % (i, i * 7, bytes([i] * (i % 9)).hex().upper().encode())
        for i in range(len(MALFORMED) + 1)
    ]
    body = (
        b"".join(
            v + b"\n" + m + b"\n" + SILENT[i % len(SILENT)] + b"\n"
            for i, (v, m) in enumerate(zip(valid, MALFORMED, strict=False))
        )
        + valid[-1]
        + b"\n"
    )
    path = tmp_path / "bad.log"
    path.write_bytes(body)
    expect = [(1700000000_000000 + i, i * 7, bytes([i] * (i % 9))) for i in range(len(valid))]
    for chunk in (1 << 20, 2):
        it = read_frames(path, chunk_frames=chunk)
        check_valid(np.concatenate(list(it)), expect)
        # one of them is a frame (not ours), the rest no candump frame
        assert (it.skipped, it.extended) == (len(MALFORMED_FRAMES), 1)
        assert it.unparsable == len(MALFORMED) - len(MALFORMED_FRAMES)
        assert it.first_unparsable_line == 2  # valid, garbage, ...
    # random bytes (no '\n' in them) between valid lines: one skipped line each
    blobs = [
        rng.integers(0, 256, int(rng.integers(1, 300)), dtype=np.uint8).tobytes().replace(b"\n", b"x")
        for _ in range(50)
    ]
    blobs = [b if b.strip(b" \t\r\v\f") else b"x" for b in blobs]
    blobs = [b"x" + b if b.lstrip(b" \t\r\v\f")[:1] in (b"#", b";") else b for b in blobs]
    body = b"".join(valid[i % len(valid)] + b"\n" + b + b"\n" for i, b in enumerate(blobs))
    path.write_bytes(body)
    it = read_frames(path, chunk_frames=3)
    assert len(np.concatenate(list(it))) == len(blobs) and it.unparsable == len(blobs) and it.skipped == 0


def test_garbage_line_longer_than_a_block(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(canlog, "_READ_BLOCK", 128)
    path = tmp_path / "long.log"
    good = b"(1700000000.000001) vcan0 123#11\n"
    path.write_bytes(good + b"y" * 1000 + b"\n" + good + b"z" * 500)
    it = read_frames(path)
    assert len(np.concatenate(list(it))) == 2 and it.unparsable == 1 and it.skipped == 0
    assert it.first_unparsable_line == 2 and it.truncated_line == 4 and it.truncated_dropped


def test_random_buffers_never_crash() -> None:
    """hil_log_parse on random and mutated buffers: never reads past len (each buffer is a separate
    bytes object; run under ASan/valgrind to be strict), counts add up."""
    lib = canlog._hil()
    rng = np.random.default_rng(4)
    template = MIXED.encode() * 3
    out = np.zeros(64, dtype=FRAME_DTYPE)
    consumed, skipped = ctypes.c_uint64(), ctypes.c_uint64()
    for i in range(3000):
        if i % 2:
            buf = bytearray(template)
            pos = rng.integers(0, len(buf), int(rng.integers(1, 20)))
            for p in pos:
                buf[p] = int(rng.integers(0, 256))
            buf = bytes(buf[: int(rng.integers(0, len(buf) + 1))])
        else:
            buf = rng.choice(
                np.frombuffer(b"()#.0123456789ABCDEFRrT \t\n\r\x00xyz", dtype=np.uint8), int(rng.integers(0, 400))
            ).tobytes()
        cap = int(rng.integers(1, 65))
        n = lib.hil_log_parse(buf, len(buf), out.ctypes.data, cap, ctypes.byref(consumed), ctypes.byref(skipped))
        assert n <= cap and consumed.value <= len(buf)
        assert n + skipped.value <= buf[: consumed.value].count(b"\n")
        assert (out["dlc"][:n] <= 8).all() and (out["cob_id"][:n] <= 0x7FF).all()


def test_writer_rejects_bad_input(tmp_path: Path) -> None:
    with pytest.raises(ValueError):
        CandumpWriter(tmp_path / "x.log", "vcan 0", 0)
    with CandumpWriter(tmp_path / "x.log", "vcan0", 0) as w:
        with pytest.raises(TypeError):
            w.write(np.zeros(3, dtype=np.uint8))
        w.write(np.zeros(0, dtype=FRAME_DTYPE))
    assert w.frames == 0 and (tmp_path / "x.log").read_bytes() == b""
