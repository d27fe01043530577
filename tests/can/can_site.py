"""Where a CAN test's own processes and bus live: the host's vcan0 when its kernel has CAN, else one slot of the
CAN box (bench/run/bus/box, docs/VM.md) held for the whole session, so that every line of the test's Python runs
on the host as a user's python-can script would. A test starts its C processes with `site.node(...)` or
`site.popen(...)` (in the slot's network namespace in the box) and opens the bus with `site.bus()` or
`site.bus_kwargs()` (python-can's socketcan on the host, its slcan interface on the slot's tap in the box: the
tap sees and may send every frame of the slot's vcan0)."""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can

from bench.paths import binary
from bench.run.bus.nodes import NodeProcess


@dataclass
class Site:
    iface: str  # the bus's name where the processes run (vcan0, can0 ...)
    lease: Any = None  # a bench.run.bus.box.lease.Lease, or None: the host's own kernel
    # popen()'s output files in the box: a name of their own in the slot's stage, held for the whole session
    # (a second test's echo.out must not find the first's "echo: ready")
    _staged: dict[Path, Path] = field(default_factory=dict)

    @property
    def in_box(self) -> bool:
        return self.lease is not None

    def bus_kwargs(self) -> dict[str, Any]:
        """python-can's (and canopen.Network.connect's) arguments for this site's bus."""
        if self.lease is None:
            return {"interface": "socketcan", "channel": self.iface, "receive_own_messages": False}
        return {"interface": "slcan", "channel": self.lease.tap_channel, "sleep_after_open": 0}

    def bus(self) -> can.BusABC:
        bus = can.Bus(**self.bus_kwargs())
        if self.lease is not None:
            self.drain(bus.recv)
        return bus

    @staticmethod
    def drain(recv: Any, quiet_s: float = 0.3, max_s: float = 5.0) -> int:
        """Frames the bridge delivers on connecting that were routed to the tap before (a loaded guest's
        console keeps them): read and dropped until the tap is quiet for `quiet_s` (at most `max_s`)."""
        n, deadline = 0, time.monotonic() + max_s
        while time.monotonic() < deadline and recv(timeout=quiet_s) is not None:
            n += 1
        return n

    def node(self, name: str, args: list[str], log: Path | None = None) -> NodeProcess:
        """A C node process (build/bin/NAME) on this site's bus, not started."""
        return NodeProcess(name, [*args], log=log, box=self.lease)

    def popen(self, argv: list[str], out: Path) -> Any:
        """Start `argv` (argv[0] a build/bin name or a program on the PATH) with its output (stdout and stderr)
        to the file `out`; a subprocess.Popen, or the box's BoxPopen (the same face)."""
        exe = argv[0] if "/" in argv[0] or shutil.which(argv[0]) else str(binary(argv[0]))
        if self.lease is None:
            with out.open("wb") as fh:
                return subprocess.Popen([exe, *argv[1:]], stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        staged = self.lease.stage / f"{len(self._staged)}-{out.name}"  # the stage: shared with the guest
        self._staged[out] = staged
        return self.lease.popen([exe, *argv[1:]], staged)

    def read(self, out: Path) -> str:
        """The output a process of popen() has written so far."""
        path = out if self.lease is None else self._staged.get(out, out)
        try:
            return path.read_text(errors="replace")
        except FileNotFoundError:
            return ""

    def wait_for_output(self, out: Path, text: str, timeout_s: float) -> bool:
        """Whether `text` appeared in the output within `timeout_s` (a bound, not a timing)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if text in self.read(out):
                return True
            time.sleep(0.05)
        return text in self.read(out)

    def now(self) -> float:
        """The wall clock (time.time()) of the machine whose kernel stamps the site's frames (candump -L): the
        host's, or the box's guest (asked over the control channel: a few ms late)."""
        if self.lease is None:
            return time.time()
        return float(self.lease.ctl.check("date +%s.%N", "reading the box's clock").strip())

    # ------------------------------------------------------------------ the processes of the bench's own runs
    def pids(self, pattern: str) -> list[int]:
        """Processes whose command line holds `pattern` (pgrep -f) where the runs' nodes run: this machine, or
        the box's guest (every slot's: one process namespace, a network namespace per slot)."""
        if self.lease is None:
            from bench_proc import pids

            return pids(pattern)
        _, out = self.lease.ctl.sh(f"pgrep -f {shlex.quote(pattern)}; true")
        return [int(p) for p in out.split() if p.isdigit()]

    def kill(self, pid: int, sig: int) -> None:
        """Signal a process of pids()."""
        if self.lease is None:
            os.kill(pid, sig)
        else:
            self.lease.ctl.check(f"kill -{int(sig)} {int(pid)}", f"signalling process {pid} in the box")

    def run_slot(self, pid: int, timeout_s: float = 240.0) -> int | None:
        """The box slot a run of process `pid` holds (not this site's own), waited for up to `timeout_s`; None on
        the host (a run there uses the host's vcan0, the site's own bus)."""
        if self.lease is None:
            return None
        from bench.run.bus.box import life

        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for slot in range(1, self.lease.info.slots + 1):
                meta = life.BOX_DIR / f"slot-{slot}.json"
                if slot == self.lease.slot or not meta.exists() or not life.slot_held(slot):
                    continue
                try:
                    if json.loads(meta.read_text()).get("pid") == pid:
                        return slot
                except (OSError, ValueError):
                    pass
            time.sleep(0.05)
        raise AssertionError(f"no slot of the CAN box taken by the run of PID {pid} within {timeout_s:.0f} s")

    def start_in_run(self, slot: int | None, argv: list[str]) -> Any:
        """Start `argv` (a program on the PATH, e.g. cangen vcan0 ...) on a run's bus: the host's, or in the run's
        slot of the box (run_slot); its output discarded."""
        if slot is None:
            return subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return _InSlot(self.lease, slot, argv)


class _InSlot:
    """A process started in another slot's namespace of the box over the control channel (kill() ends it)."""

    def __init__(self, lease: Any, slot: int, argv: list[str]) -> None:
        self.ctl = lease.ctl
        cmd = f"ip netns exec b{slot} " + " ".join(shlex.quote(a) for a in argv)
        self.pid = int(self.ctl.check(f"{cmd} >/dev/null 2>&1 </dev/null & echo $!", f"starting {argv[0]}").split()[-1])

    def kill(self) -> None:
        self.ctl.sh(f"kill -9 {self.pid} 2>/dev/null; true")

    def wait(self, timeout: float | None = None) -> int:
        deadline = time.monotonic() + (timeout or 30.0)
        while time.monotonic() < deadline:
            rc, _ = self.ctl.sh(f"kill -0 {self.pid} 2>/dev/null")
            if rc != 0:
                return -9
            time.sleep(0.05)
        raise TimeoutError(f"process {self.pid} in the box did not end")
