"""Where a run's frames come from, as numpy chunks in bus order (never a Python object per frame):

- direct mode: the C recorder of the in-process bus (bench/direct/hil_direct.c), emptied
  after every chunk of periods;
- SocketCAN: can-utils' candump (C, 8 MiB socket buffer: no frame lost at the lockstep rate
  even where Python is slow) writing the candump log, followed as it grows;
- any other python-can interface: a listener on the master's own bus.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np

from bench.run.bus.direct import Hil
from bench.run.bus.frames import empty, join
from bench.run.bus.nodes import in_vm
from bench.run.record.canlog import parse_candump
from bench.run.record.messages import ours, to_frames


class DirectSource:
    """The in-process bus's recorder. `collect` runs on the loop's thread after each chunk (it waits
    while `max_waiting` chunks are not yet drained: bounded memory); `drain` on the decoding thread."""

    def __init__(
        self, hil: Hil, chunk_periods: int, max_waiting: int = 2, min_frames: int = 0, fd: bool = False
    ) -> None:
        self.hil = hil
        # Frames per period: SYNC, 2 measurement TPDOs, the command, up to 3 trace TPDOs, and margin. `fd`: the wide
        # record of a run whose PDOs are CAN FD frames (bench/run/bus/frames.py).
        hil.start_recorder(chunk_periods * 12 + 65_536, fd)
        self._chunks: list[np.ndarray] = []
        self._cond = threading.Condition()
        self._max = max_waiting
        self._released = False
        # Frames taken but not handed out yet: `drain` returns nothing before `min_frames` are in (or the
        # end). The decoder's cost per chunk is largely fixed, so a run of short segments (a sweep's point:
        # two) is decoded once at its end, not once a segment; the loop thread is never kept waiting for it.
        self._min = min_frames
        self._held: list[np.ndarray] = []
        self._held_n = 0

    def collect(self) -> None:
        frames = self.hil.take()
        with self._cond:
            self._chunks.append(frames)
            self._cond.wait_for(lambda: len(self._chunks) < self._max or self._released)

    def release(self) -> None:
        """Let a waiting loop thread go on (end of a segment, Ctrl-C)."""
        with self._cond:
            self._released = True
            self._cond.notify_all()

    def drain(self, final: bool = False) -> np.ndarray:
        with self._cond:
            chunks, self._chunks = self._chunks, []
            self._released = False
            self._cond.notify_all()
        if final:  # what the master's SDO traffic left after the last chunk (between chunks the next
            chunks.append(self.hil.take())  # collect takes it, in bus order, with that chunk's frames)
        self._held += [c for c in chunks if len(c)]
        self._held_n += sum(len(c) for c in chunks)
        if not self._held or (self._held_n < self._min and not final):
            return empty()
        chunks, self._held, self._held_n = self._held, [], 0
        return join(chunks)

    def stop(self) -> None:
        self.release()


class LogFollower:
    """Reads what was appended to a candump log since the last call: complete lines only,
    sorted by kernel time stamp (candump on a loaded machine may write a frame a little late).
    Frames within `hold_us` of the newest are kept for the next call, so that a late frame
    still finds its place; `drain(final=True)` returns everything."""

    def __init__(self, path: Path, hold_us: int = 200_000, max_bytes: int = 64 << 20) -> None:
        self.path = path
        self.max_bytes = max_bytes
        self.hold_us = hold_us
        self._pos = 0
        self._rest = b""
        self._held = empty()
        self.skipped = 0

    def drain(self, final: bool = False) -> np.ndarray:
        if not self.path.exists():
            return empty()
        with open(self.path, "rb") as fh:
            fh.seek(self._pos)
            block = fh.read(-1 if final else self.max_bytes)  # bounded per call while the run goes on
        self._pos += len(block)
        data = self._rest + block
        frames, used, skipped = parse_candump(data)
        self._rest = data[used:]
        self.skipped += skipped
        frames = join([self._held, frames]) if len(self._held) else frames
        if len(frames) == 0:
            return frames
        frames = frames[np.argsort(frames["t_us"], kind="stable")]
        if final:
            self._held = empty()
            return frames
        cut = int(np.searchsorted(frames["t_us"], int(frames["t_us"][-1]) - self.hold_us, side="right"))
        self._held = frames[cut:]
        return frames[:cut]


def sorted_chunks(chunks: Iterable[np.ndarray], hold_us: int = 200_000) -> Iterator[np.ndarray]:
    """Chunks in kernel time-stamp order (stable): the frames of the last `hold_us` of a chunk wait
    for the next one, so that a frame a recorder wrote a little late still finds its place."""
    held = empty()
    for chunk in chunks:
        frames = join([held, chunk]) if len(held) else chunk
        if len(frames) == 0:
            continue
        frames = frames[np.argsort(frames["t_us"], kind="stable")]
        cut = int(np.searchsorted(frames["t_us"], int(frames["t_us"][-1]) - hold_us, side="right"))
        held = frames[cut:]
        if cut:
            yield frames[:cut]
    if len(held):
        yield held


class CandumpSource:
    """candump records the bus into `path`. Inside the VM it writes the guest's own /tmp (a shared
    9p folder is far too slow for a line per frame) and a thread copies the file in blocks to
    `path` every half second, so that the host can follow it."""

    def __init__(self, iface: str, path: Path, follow: bool = True) -> None:
        exe = shutil.which("candump")
        if exe is None:
            raise RuntimeError("candump not found: apt-get install can-utils")
        self.path = path
        self.local = path
        self._tmpdir: str | None = None
        if in_vm():
            self._tmpdir = tempfile.mkdtemp(prefix="bench-rec-")
            self.local = Path(self._tmpdir) / path.name
        self._fh = open(self.local, "wb")  # noqa: SIM115 - closed in stop()
        # -L: log-file format (absolute kernel time stamps); -r: 8 MiB receive buffer; line-buffered
        # (stdbuf) so that the file can be followed while the run goes on.
        argv = [exe, "-L", "-r", str(8 << 20), iface]
        if shutil.which("stdbuf"):
            argv = ["stdbuf", "-oL", *argv]
        self.proc = subprocess.Popen(argv, stdout=self._fh, stderr=subprocess.PIPE)
        time.sleep(0.2)
        if self.proc.poll() is not None:
            err = self.proc.stderr.read().decode() if self.proc.stderr else ""
            raise RuntimeError(f"candump on {iface} failed: {err.strip()}")
        self._stop = threading.Event()
        self._copier: threading.Thread | None = None
        if self.local != path:
            self._copier = threading.Thread(target=self._copy_loop, daemon=True)
            self._copier.start()
        self.follower = LogFollower(self.local) if follow else None

    def _copy_loop(self) -> None:
        pos = 0
        with open(self.path, "wb") as dst:
            while True:
                stopping = self._stop.wait(0.5)
                with open(self.local, "rb") as src:
                    src.seek(pos)
                    block = src.read()
                if block:
                    dst.write(block)
                    dst.flush()
                    pos += len(block)
                if stopping:
                    return

    def drain(self, final: bool = False) -> np.ndarray:
        return self.follower.drain(final) if self.follower is not None else empty()

    def stop(self) -> None:
        time.sleep(0.2)
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self._fh.close()
        if self._copier is not None:
            self._stop.set()
            self._copier.join(timeout=60)

    def cleanup(self) -> None:
        if self._tmpdir:
            shutil.rmtree(self._tmpdir, ignore_errors=True)


CATCH_UP_S = 120.0  # a box run's end: a bound on candump's catching up with the bus (a flood in a TCG guest)
COPY_S = 0.1  # how often the copier looks at candump's log in the box (tail -s)


class BoxCandumpSource:
    """candump records the run's bus inside the CAN box (bench/run/bus/box) into the guest's own memory, and
    `tail` copies the log to the lease's stage (shared with the host) every half second in large blocks: candump
    writing the 9p share itself, a 4 KiB block at a time, fell behind a fast lockstep loop (80 % of a
    20,000-period run still in its socket at the end). The host follows the copy as it grows (the live view); a
    box that dies mid-run leaves what was copied. At the end the bench waits until candump has written all it
    received (its log stops growing) and the copy has caught up."""

    def __init__(self, lease: Any, iface: str, path_name: str = "candump.log") -> None:
        self.lease = lease
        self.path = lease.stage / path_name
        self.guest = Path(f"/run/box/{lease.ns}-candump.log")
        err = lease.stage / "candump.err"
        # candump only receives: it may run on any of the box's vCPUs (the slot's own is for its senders, whose frames
        # must leave in order: Lease.in_ns). On the nodes' vCPU every frame woke it there and took that vCPU from the
        # nodes: the lockstep loop's period (candump's stamps, 4 runs of 200 periods) had a median of 0.88 ms, 0.42 ms
        # with candump free to run on the other one (issue 56, item 4).
        from bench.run.bus.box.life import BOX_CPUS

        cpus = f"0-{BOX_CPUS - 1}"
        self.proc = lease.popen(
            ["taskset", "-c", cpus, "candump", "-L", "-r", str(8 << 20), iface], self.guest, err=err
        )
        self.copier = lease.popen(
            [
                "tail",
                "---disable-inotify",
                "-s",
                str(COPY_S),
                "--pid",
                str(self.proc.pid),
                "-c",
                "+1",
                "-f",
                str(self.guest),
            ],
            self.path,
            err=lease.stage / "copier.err",
            in_slot=False,
        )
        self._iface, self._err = iface, err
        self.follower = LogFollower(self.path)

    def await_ready(self) -> None:
        """Until candump listens, asked of the guest in one request: its process is candump (what ran before it has
        exec'd), it sleeps (state S: in select, after its socket was bound) and holds a socket (its CAN socket), or it
        ended. Up to 3 s, 10 ms naps. The run asks it once its nodes were started, before their NMT reset: the
        two starts overlap. (A fixed 0.2 s nap before: the log missed the bench's NMT reset commands.)"""
        p, iface, err = self.proc, self._iface, self._err
        state = p.state_text()
        _, out = self.lease.ctl.sh(
            f"c=$(command -v candump); r=late; l=; st=; for ((k = 0; k < 300; k++)); do [ -s {p.exit_file} ] && break; "
            f'if [ -n "$c" ] && [ /proc/{p.pid}/exe -ef "$c" ]; then {state} 2>/dev/null; '
            f'if [ "$st" = S ]; then for f in /proc/{p.pid}/fd/*; do [ -S $f ] && r=ready && break 2; done; fi; fi; '
            f"read -r -t 0.01 -u 4 _; done; echo $r {p.exit_text()}",
            timeout_s=60,
        )
        words = out.split()
        if p.ended_with(words[-1] if words else "") is not None:
            why = err.read_text(errors="replace").strip() if err.exists() else ""
            raise RuntimeError(f"candump on {iface} in the CAN box failed: {why or p.returncode}")
        if words[-2:-1] != ["ready"]:  # asleep in select with its socket: it has bound it
            print(
                f"bench: warning: candump on {iface} in the CAN box did not show that it listens within 3 s; the log "
                "may miss the run's first frames",
                file=sys.stderr,
                flush=True,
            )

    def drain(self, final: bool = False) -> np.ndarray:
        return self.follower.drain(final)

    def stop(self) -> None:
        from bench.run.bus.box.boxproc import await_file
        from bench.run.bus.box.control import BoxGone

        g, p, cp = self.guest, self.proc, self.copier
        # One request (each costs the guest ~10 ms under TCG, each exec in it ~90 ms). candump has written all the
        # run sent once it sleeps (state S: blocked in select, its socket empty) with its output unchanged for 0.1 s
        # (read from /proc every 20 ms, no exec; the nodes have ended: Session.close), or, when its output goes on
        # growing (a flood of foreign traffic), once its log holds a frame stamped after the run's end (the guest's
        # clock; looked at every 0.3 s) - SIGINT before that drops what still waits in its socket (a loaded guest's
        # candump may be seconds behind a flood: the end of the loop was lost). Then SIGINT and its exit; the copier
        # (tail -f --pid) copies the rest and ends by itself once candump has ended: its exit awaited, the whole log
        # is on the stage (the share is mounted `sync` in the guest); both exit statuses; the log unlinked.
        state = p.state_text()
        pos = f"x=-; while read -r a v; do [ $a = pos: ] && x=$v && break; done </proc/{p.pid}/fdinfo/1"
        stamped = (
            rf"[[ $(tail -c 300 {g}) =~ .*\(([0-9]+)\.([0-9]{{6}})\)\  ]] && "
            f"[ $((10#${{BASH_REMATCH[1]}}${{BASH_REMATCH[2]}})) -ge $e ] && break"
        )
        script = (
            f"e=${{EPOCHREALTIME/./}}; w=-; q=0; l=; st=; x=-; for ((k = 1; ; k++)); do read -r -t 0.02 -u 4 _; "
            f"[ $((${{EPOCHREALTIME/./}} - e)) -gt {int(CATCH_UP_S * 1e6)} ] && break; "
            f"[ -s {p.exit_file} ] && break; {pos} 2>/dev/null; {state} 2>/dev/null; "
            f'if [ "$x" = "$w" ]; then q=$((q + 1)); [ $q -ge 5 ] && [ "$st" = S ] && break; else w=$x; q=0; fi; '
            f"if [ $((k % 15)) = 0 ]; then {stamped}; fi; done; "
            f"kill -2 {p.pid} 2>/dev/null; {await_file(f'-s {p.exit_file}', 1000)}; "
            f"{await_file(f'-s {cp.exit_file}', 6000)}; echo {p.exit_text()} {cp.exit_text()}; rm -f {g}"
        )
        try:
            _, out = self.lease.ctl.sh(script, timeout_s=CATCH_UP_S + 120)
            rc_dump, rc_copy = out.split()[-2:]
            p.ended_with(rc_dump)
            cp.ended_with(rc_copy)
        except (BoxGone, ValueError, IndexError):
            pass
        finally:
            p.kill()  # no request when it ended (its status known)
            cp.kill()

    def cleanup(self) -> None:
        for name in ("candump.err", "copier.err"):
            err = self.path.with_name(name)
            if err.exists() and err.stat().st_size == 0:
                err.unlink()


class ListenerSource(can.Listener):
    """Frames seen by the master's own bus (interfaces other than SocketCAN)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._msgs: list[can.Message] = []

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            self._msgs.append(msg)

    def drain(self, final: bool = False) -> np.ndarray:
        with self._lock:
            msgs, self._msgs = self._msgs, []
        return frames_from_messages(msgs)

    def stop(self) -> None:
        pass


def frames_from_messages(msgs: list[can.Message]) -> np.ndarray:
    """python-can messages (11-bit data frames, classic or CAN FD) as frames, by time stamp."""
    keep = sorted((m for m in msgs if ours(m)), key=lambda m: m.timestamp)
    return to_frames(keep) if keep else empty()
