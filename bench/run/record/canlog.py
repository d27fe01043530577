"""A run's CAN log on disk: candump `-L` logs (`.log`) written and read in C, every other
format python-can knows (.asc, .blf, .trc, .csv, ...) through python-can itself.

Why the candump path is hand-written: python-can's writers and readers make one Python object
per frame (a `can.Message`, its strings): measured ~10 µs a frame to write (5 µs building the
Message, 5 µs CanutilsLogWriter) and ~13 µs to read, i.e. ~90 µs a control period of ~8 frames:
18 s to write the log of 2e5 periods, as long to read it back. Here frames stay in
FRAME_DTYPE numpy arrays and build/libhil.so (bench/direct/hil_log.c) formats / parses whole
chunks (~0.1 µs a frame); the output is the can-utils format byte for byte, and the tests
round-trip it through python-can's CanutilsLogReader and can-utils' log2asc. .asc and .blf
are written by python-can's own writers (`export`): slow, but exactly what those tools expect.

Time stamps in a .log are `t0_us` plus the frames' own time. A direct run's frames carry simulated
time and its log starts at SIMULATED_T0_US, not at the wall clock: two identical runs write
byte-identical logs. Not 0: log2asc takes a 0 seconds
field as "no header written yet" and repeats its header for every frame of the first second.
"""

from __future__ import annotations

import ctypes
import itertools
from collections.abc import Callable, Iterator
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

import can
import numpy as np

from bench.paths import BUILD
from bench.run.bus.frames import FRAME_DTYPE, FRAME_FD_DTYPE, frame_dtype, is_fd
from bench.run.record.messages import ours, to_frames, to_messages

LOG_FORMATS = ("log", "asc", "blf")

_WRITE_BATCH = 1 << 16  # frames formatted per C call (buffer = batch * line_max bytes)
_READ_BLOCK = 4 << 20  # bytes read from a .log per block; also the longest line accepted
_lib: ctypes.CDLL | None = None


SIMULATED_T0_US = 1_000_000  # a direct run's log starts at 1 s of simulated time (see the docstring)


class _LogCounts(ctypes.Structure):
    """hil_log_counts_t of bench/direct/hil_log.c."""

    _fields_ = [
        ("lines", ctypes.c_uint64),
        ("skipped", ctypes.c_uint64),
        ("extended", ctypes.c_uint64),
        ("unparsable", ctypes.c_uint64),
        ("first_unparsable", ctypes.c_uint64),
    ]


def _hil() -> ctypes.CDLL:
    global _lib
    if _lib is None:
        path = BUILD / "libhil.so"
        if not path.exists():
            raise FileNotFoundError(f"{path} is missing: run `make all`")
        lib = ctypes.CDLL(str(path))
        lib.hil_log_line_max.argtypes = [ctypes.c_char_p]
        lib.hil_log_line_max.restype = ctypes.c_uint64
        lib.hil_log_format.argtypes = [
            ctypes.c_void_p,
            ctypes.c_uint32,
            ctypes.c_uint64,
            ctypes.c_char_p,
            ctypes.c_void_p,
            ctypes.c_uint64,
        ]
        lib.hil_log_format.restype = ctypes.c_uint64
        lib.hil_log_parse.argtypes = [
            ctypes.c_void_p,
            ctypes.c_uint64,
            ctypes.c_void_p,
            ctypes.c_uint32,
            ctypes.POINTER(ctypes.c_uint64),
            ctypes.POINTER(ctypes.c_uint64),
        ]
        lib.hil_log_parse.restype = ctypes.c_uint32
        lib.hil_log_parse_counted.argtypes = [
            ctypes.c_void_p,
            ctypes.c_uint64,
            ctypes.c_void_p,
            ctypes.c_uint32,
            ctypes.POINTER(ctypes.c_uint64),
            ctypes.POINTER(_LogCounts),
        ]
        lib.hil_log_parse_counted.restype = ctypes.c_uint32
        lib.hil_log_line_max_fd.argtypes = lib.hil_log_line_max.argtypes
        lib.hil_log_line_max_fd.restype = ctypes.c_uint64
        lib.hil_log_format_fd.argtypes = lib.hil_log_format.argtypes
        lib.hil_log_format_fd.restype = ctypes.c_uint64
        lib.hil_log_parse_fd.argtypes = lib.hil_log_parse.argtypes
        lib.hil_log_parse_fd.restype = ctypes.c_uint32
        lib.hil_log_parse_counted_fd.argtypes = lib.hil_log_parse_counted.argtypes
        lib.hil_log_parse_counted_fd.restype = ctypes.c_uint32
        _lib = lib
    return _lib


class CandumpWriter:
    """Frames -> a candump -L log, chunk by chunk (hil_log_format into one reused buffer).

    Time stamp of a frame = t0_us + frame["t_us"] (a direct run's frames: SIMULATED_T0_US, see above).
    Hand-written because python-can's CanutilsLogWriter needs a can.Message per frame (~10 µs,
    ~90 µs a control period)."""

    def __init__(self, path: Path, channel: str, t0_us: int = SIMULATED_T0_US) -> None:
        self._lib = _hil()
        self._channel = channel.encode("ascii")
        line_max = int(self._lib.hil_log_line_max(self._channel))
        if line_max == 0:
            raise ValueError(f"channel {channel!r}: 1..64 printable characters without white space")
        if t0_us < 0:
            raise ValueError("t0_us must be >= 0")
        self.path = Path(path)
        self.channel = channel
        self.t0_us = int(t0_us)
        self.frames = 0  # frames written so far
        self._buf = np.empty(_WRITE_BATCH * line_max, dtype=np.uint8)
        self._fh: BinaryIO | None = open(self.path, "wb")  # noqa: SIM115 - closed in close()

    def write(self, frames: np.ndarray) -> None:
        if self._fh is None:
            raise ValueError(f"{self.path}: writer is closed")
        if frames.dtype not in (FRAME_DTYPE, FRAME_FD_DTYPE):
            raise TypeError(f"frames must have FRAME_DTYPE or FRAME_FD_DTYPE, not {frames.dtype}")
        fd = is_fd(frames)
        fmt = self._lib.hil_log_format_fd if fd else self._lib.hil_log_format
        if fd and len(self._buf) < _WRITE_BATCH * int(self._lib.hil_log_line_max_fd(self._channel)):
            self._buf = np.empty(_WRITE_BATCH * int(self._lib.hil_log_line_max_fd(self._channel)), dtype=np.uint8)
        arr = np.ascontiguousarray(frames.reshape(-1))
        buf_addr, cap = self._buf.ctypes.data, self._buf.nbytes
        for start in range(0, len(arr), _WRITE_BATCH):
            part = arr[start : start + _WRITE_BATCH]
            n = int(fmt(part.ctypes.data, len(part), self.t0_us, self._channel, buf_addr, cap))
            if n == 0:
                raise RuntimeError("hil_log_format: buffer too small (line_max out of step with hil_log.c?)")
            self._fh.write(memoryview(self._buf)[:n])
            self.frames += len(part)

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> CandumpWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class LogFrames(Iterator[np.ndarray]):
    """The frames of a log as frame-record chunks (at most chunk_frames each, seq numbered across
    chunks from 0, sender 255): FRAME_DTYPE, and FRAME_FD_DTYPE from the first CAN FD frame on
    (bench/run/bus/frames.py `join` puts them together). After (or during) iteration: `frames` = frames
    yielded, `skipped` = frames that are not an 11-bit data frame (extended, error, remote), of them
    `extended` = extended-ID data frames; in a .log also `unparsable` = lines that are no candump frame
    (garbage, a line longer than a block), the first at line `first_unparsable_line`, and `truncated_line` =
    the last line's number when the file ends without its end of line (a recorder cut mid-write): that line is
    not counted as unparsable; its frame is kept when it still parses (only the '\n' was lost), else dropped
    (`truncated_dropped`).

    t_us is what the format keeps: absolute µs for .log and .blf, µs from the first frame for
    .asc (python-can's ASCReader default; the absolute start of an .asc is only in ms)."""

    def __init__(self, path: Path, chunk_frames: int = 1 << 20) -> None:
        if chunk_frames < 1:
            raise ValueError("chunk_frames must be >= 1")
        self.path = Path(path)
        self.chunk_frames = int(chunk_frames)
        self.frames = 0
        self.skipped = 0
        self.extended = 0
        self.unparsable = 0
        self.first_unparsable_line: int | None = None
        self.truncated_line: int | None = None
        self.truncated_dropped = False
        self.lines = 0  # lines read so far (.log)
        source = self._candump() if self.path.suffix.lower() == ".log" else self._python_can()
        self._chunks = self._numbered(source)

    def __next__(self) -> np.ndarray:
        return next(self._chunks)

    def __iter__(self) -> LogFrames:
        return self

    def _numbered(self, chunks: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
        for chunk in chunks:
            chunk["seq"] = np.arange(len(chunk), dtype=np.uint32)
            chunk["seq"] += np.uint32(self.frames & 0xFFFFFFFF)  # bus order, wraps like the recorder's
            self.frames += len(chunk)
            yield chunk

    def report(self) -> dict[str, int | bool | None]:
        """What was left out of the log, for summary.json's "log"."""
        return {
            "frames_skipped": self.skipped,
            "extended_frames": self.extended,
            "unparsable_lines": self.unparsable,
            "first_unparsable_line": self.first_unparsable_line,
            "truncated_line": self.truncated_line,
            "truncated_line_dropped": self.truncated_dropped,
        }

    def _count(self, c: _LogCounts, cut_line: bool) -> None:
        """Adds one hil_log_parse_counted call's counts; `cut_line`: the call's only line is the
        file's unterminated last line (truncated, not unparsable)."""
        if cut_line and c.lines:
            self.truncated_line = self.lines + 1
            self.truncated_dropped = bool(c.unparsable)
        elif c.unparsable:
            if self.first_unparsable_line is None:
                self.first_unparsable_line = self.lines + int(c.first_unparsable)
            self.unparsable += int(c.unparsable)
        self.lines += int(c.lines)
        self.skipped += int(c.skipped)
        self.extended += int(c.extended)

    def _long_line(self) -> None:
        """A "line" longer than a block: garbage, dropped up to its '\n'."""
        self.lines += 1
        self.unparsable += 1
        if self.first_unparsable_line is None:
            self.first_unparsable_line = self.lines

    def _long_line_was_cut(self) -> None:
        self.unparsable -= 1
        if self.first_unparsable_line == self.lines:
            self.first_unparsable_line = None
        self.truncated_line, self.truncated_dropped = self.lines, True

    def _candump(self) -> Iterator[np.ndarray]:
        """hil_log_parse_counted over fixed blocks of the file: memory stays one block + one chunk.
        Hand-written because python-can's CanutilsLogReader makes a can.Message per line (~13 µs)."""
        lib = _hil()
        buf = np.empty(_READ_BLOCK + 1, dtype=np.uint8)  # +1: the '\n' added to an unterminated last line
        base = buf.ctypes.data
        have = pos = 0
        eof = discarding = cut = False
        consumed, counts = ctypes.c_uint64(), _LogCounts()
        fd = False  # CAN FD lines seen: the wide record from then on (the chunks before stay classic)
        fresh = 0  # buf[fresh:have] not yet searched for a CAN FD line
        out = np.empty(self.chunk_frames, dtype=FRAME_DTYPE)
        filled = 0
        with open(self.path, "rb", buffering=0) as fh:
            while True:
                if not fd and fresh < have and _has_fd_line(buf[max(pos, fresh - 1) : have]):
                    fd = True
                    if filled:
                        yield out[:filled].copy()
                    out, filled = np.empty(self.chunk_frames, dtype=FRAME_FD_DTYPE), 0
                fresh = have
                parse = lib.hil_log_parse_counted_fd if fd else lib.hil_log_parse_counted
                n = int(
                    parse(
                        base + pos,
                        have - pos,
                        out.ctypes.data + filled * out.dtype.itemsize,
                        self.chunk_frames - filled,
                        ctypes.byref(consumed),
                        ctypes.byref(counts),
                    )
                )
                filled += n
                pos += consumed.value
                self._count(counts, cut)
                if filled == self.chunk_frames:  # out full: more lines may wait in buf
                    yield out
                    out = np.empty(self.chunk_frames, dtype=out.dtype)
                    filled = 0
                    continue
                # only a partial line (or nothing) is left: keep it, read more after it
                rest = have - pos
                if rest and pos:
                    ctypes.memmove(base, base + pos, rest)
                have, pos, fresh = rest, 0, rest
                if eof:
                    break
                if have == _READ_BLOCK:
                    self._long_line()
                    have, discarding, fresh = 0, True, 0
                got = fh.readinto(memoryview(buf)[have:_READ_BLOCK])
                if not got:
                    eof = True
                    if discarding:  # the long line was the last, unterminated: the cut line
                        self._long_line_was_cut()
                        have = 0
                    elif have:  # unterminated last line, alone in buf: complete it, parse it alone
                        buf[have] = 0x0A
                        have += 1
                        cut = True
                    continue
                if discarding:
                    nl = np.flatnonzero(buf[have : have + got] == 0x0A)
                    if len(nl) == 0:
                        continue
                    start = have + int(nl[0]) + 1
                    ctypes.memmove(base, base + start, have + got - start)
                    have, discarding, fresh = have + got - start, False, 0
                else:
                    have += got
        if filled:
            yield out[:filled].copy()

    def _python_can(self) -> Iterator[np.ndarray]:
        """Any other format through python-can's reader (one can.Message per frame, ~10+ µs: slow,
        but the reference reader of .asc/.blf), converted chunk by chunk."""
        with can.LogReader(str(self.path)) as reader:
            it = iter(reader)
            while True:
                msgs = list(itertools.islice(it, self.chunk_frames))
                if not msgs:
                    break
                keep = [m for m in msgs if ours(m)]
                self.skipped += len(msgs) - len(keep)
                self.extended += sum(
                    1 for m in msgs if m.is_extended_id and not (m.is_error_frame or m.is_remote_frame)
                )
                if keep:
                    yield to_frames(keep)


def _has_fd_line(block: np.ndarray) -> bool:
    """Whether candump text holds a CAN FD line ("III##F...")."""
    return bool(len(block) > 1 and ((block[:-1] == 0x23) & (block[1:] == 0x23)).any())


def parse_candump(data: bytes) -> tuple[np.ndarray, int, int]:
    """The complete lines of candump log text: (frames, bytes used, lines skipped). What follows
    the last newline is left for the caller to pass again with more data (following a growing log)."""
    lib = _hil()
    fd = b"##" in data  # CAN FD lines: the wide record
    out = np.empty(max(1, data.count(b"\n")), dtype=frame_dtype(fd))
    consumed, skipped = ctypes.c_uint64(), ctypes.c_uint64()
    parse = lib.hil_log_parse_fd if fd else lib.hil_log_parse
    n = int(parse(data, len(data), out.ctypes.data, len(out), ctypes.byref(consumed), ctypes.byref(skipped)))
    return out[:n], int(consumed.value), int(skipped.value)


def read_frames(path: Path, chunk_frames: int = 1 << 20) -> LogFrames:
    """The frames of any log (.log by hil_log_parse, others by can.LogReader) as FRAME_DTYPE chunks;
    the returned iterator's `.skipped` counts what was left out (see LogFrames)."""
    return LogFrames(path, chunk_frames)


def export(src: Path, dst: Path, progress: Callable[[int], None] | None = None) -> int:
    """Converts any log read_frames reads into dst, in the format of dst's extension, chunk by
    chunk: python-can's own writer (can.Logger) for .asc, .blf and the rest (the slow but standard
    path, one can.Message per frame), CandumpWriter for .log (same format as python-can's, channel "vcan0",
    time stamps as read). progress(frames written so far) after each chunk. Returns frames written."""
    dst = Path(dst)
    total = 0
    if dst.suffix.lower() == ".log":
        with CandumpWriter(dst, "vcan0", 0) as w:
            for chunk in read_frames(src):
                w.write(chunk)
                total += len(chunk)
                if progress is not None:
                    progress(total)
        return total
    logger = can.Logger(str(dst))
    try:
        for chunk in read_frames(src, chunk_frames=1 << 16):
            for msg in to_messages(chunk):
                logger.on_message_received(msg)
            total += len(chunk)
            if progress is not None:
                progress(total)
    finally:
        logger.stop()
    return total
