"""Is the loop alive? The bench's judgement while a run goes on a bus, from CiA 301 error control.

Both nodes produce a heartbeat (0x1017) and consume each other's (0x1016); the bench consumes
both too (python `canopen` delivers the frames; the judgement is ours because canopen's
`NmtMaster` has no consumer timeout). A node is named as soon as:

- its process (when the bench started it) has exited: at once, with its exit status;
- its heartbeat has not been seen for the consumer time (`heartbeat_timeout_ms`): dead or silent
  (frozen, unplugged, bus-off); in lockstep a node process of the bench's that still runs is allowed
  STARVED_S (a loaded host starves it; lockstep waits);
- its heartbeat says it left OPERATIONAL (an NMT command from elsewhere, a reset);
- the other node reports losing it (EMCY 0x8130 with its node-ID), on interfaces where the master sees
  EMCYs (over SocketCAN its kernel filter keeps them out: bench/run/loop/session.py).

In lockstep the plant waits for each command without a time limit (plant.eds 0x2003:04 = 0):
load slows the loop, it never changes it. A loop whose nodes are both alive but whose period
index stops moving has lost a frame on the bus; `Stall` says so after `stall_s`.
"""

from __future__ import annotations

import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import canopen

from bench.emcy import emcy_codes
from bench.run.bus.nodes import NodeProcess, process_state

NMT_STATES = canopen.nmt.NMT_STATES  # a heartbeat's state byte -> its name (CiA 301)
EMCY_HEARTBEAT = emcy_codes("heartbeat")[0]  # a node's heartbeat consumer lost its producer (common.ini)
WATCH_S = 0.1  # how often the watcher thread judges
# A watcher that wakes this much later than it asked was not running itself (a loaded machine, the VM's
# vCPUs descheduled by the host: the whole guest stops, and its clock jumps when it runs again): the silence
# it would now see is its own, not the nodes', so that time is not counted against them
STALL_S = 0.3
# In lockstep, a node process the bench started that is alive and not stopped (its kernel state is not T) but
# silent was most likely starved of CPU: a loaded host deschedules one of the VM's vCPUs, and the node on it
# stops while the watcher on the other vCPU runs on. Lockstep waits for it: that changes nothing but time, so
# such a node is named after this much silence (a hung or unplugged node of ours too, later than the consumer
# time). A stopped or exited process, a node the bench did not start (a physical drive) and every node of a
# real-time run (where the other node's own consumer reacts after the consumer time) are judged by the
# consumer time.
STARVED_S = 5.0


@dataclass
class LoopStopped(Exception):
    """The run ended before its last period: a node died or went silent (`node_lost`), or the loop
    stalled with both nodes alive (`frames_lost`)."""

    status: str  # node_lost | frames_lost
    message: str
    node: str | None = None  # plant | drive
    node_id: int | None = None
    at_period: int | None = None  # the plant's last period, when known
    detected_after_s: float | None = None  # since the node's last sign of life
    details: dict[str, Any] = field(default_factory=dict)

    def __str__(self) -> str:
        return self.message

    detected_at_unix: float = field(default_factory=time.time)  # when the bench noticed (wall clock)

    def to_dict(self) -> dict[str, Any]:
        return {
            "status": self.status,
            "message": self.message,
            "node": self.node,
            "node_id": self.node_id,
            "at_period": self.at_period,
            "detected_after_s": self.detected_after_s,
            "detected_at_unix": self.detected_at_unix,
            **self.details,
        }


def _exit_text(rc: int) -> str:
    if rc < 0:
        try:
            return f"was killed by {signal.Signals(-rc).name}"
        except ValueError:
            return f"was killed by signal {-rc}"
    return f"exited with status {rc}"


class Liveness:
    """Heartbeats, EMCYs and node processes, watched from the master's network."""

    def __init__(
        self,
        net: canopen.Network,
        nodes: dict[str, int],
        procs: dict[str, NodeProcess],
        timeout_ms: int,
        heartbeat_ms: int,
        starved_s: float = 0.0,
    ) -> None:
        self.nodes = nodes  # name -> node-ID
        self.procs = procs  # name -> process the bench started
        self.timeout_s = timeout_ms / 1000.0
        self.starved_s = starved_s  # STARVED_S in lockstep, 0: the consumer time for every node
        self.last: dict[str, float] = {}  # name -> monotonic time of the last heartbeat
        self.state: dict[str, int] = {}
        self.emcy: list[tuple[str, int, bytes, float]] = []
        self.emcy_seen = 0
        self.armed = False
        # heartbeats sent before the nodes took the NMT start may still be on their way when judging starts
        self.grace_s = 2 * heartbeat_ms / 1000.0 + 0.2
        self._armed_at = 0.0
        self._lock = threading.Lock()
        # judged in a thread of its own, every WATCH_S: the master's main thread may be busy for seconds
        # (decoding what the recorder wrote, slower still in the VM) and must not delay the verdict
        self._found: LoopStopped | None = None
        self._watch_stop = threading.Event()
        self._watcher: threading.Thread | None = None
        self._net = net
        self._subs: list[tuple[int, Any]] = []
        for name, nid in nodes.items():
            self._sub(net, 0x700 + nid, self._hb(name))
            self._sub(net, 0x080 + nid, self._em(name))

    def _sub(self, net: canopen.Network, cob: int, cb: Any) -> None:
        net.subscribe(cob, cb)
        self._subs.append((cob, cb))

    def close(self) -> None:
        self.disarm()
        for cob, cb in self._subs:
            try:
                self._net.unsubscribe(cob, cb)
            except (KeyError, ValueError):
                pass
        self._subs.clear()

    def _hb(self, name: str):  # type: ignore[no-untyped-def]
        def cb(cob_id: int, data: bytearray, ts: float) -> None:
            if len(data) != 1:  # not a heartbeat (a foreign frame on its identifier)
                return
            now = time.monotonic()
            st = data[0] & 0x7F
            with self._lock:
                self.last[name] = now
                # judged from the first OPERATIONAL heartbeat after the start (an older one may be late)
                if st == 0x05 or (name in self.state and now - self._armed_at > self.grace_s):
                    self.state[name] = st

        return cb

    def _em(self, name: str):  # type: ignore[no-untyped-def]
        def cb(cob_id: int, data: bytearray, ts: float) -> None:
            # only the heartbeat-loss EMCY matters here (the decoder lists every EMCY from the log); bounded
            if len(data) == 8 and int.from_bytes(data[:2], "little") == EMCY_HEARTBEAT and len(self.emcy) < 1000:
                with self._lock:
                    self.emcy.append((name, EMCY_HEARTBEAT, bytes(data), time.monotonic()))

        return cb

    def arm(self) -> None:
        """Start judging (the nodes are OPERATIONAL): silence counts from now for a node not yet heard."""
        now = time.monotonic()
        with self._lock:
            self._armed_at = now
            self.state.clear()
            for name in self.nodes:
                self.last[name] = max(self.last.get(name, now), now)
            self.emcy_seen = len(self.emcy)
            self._found = None
        self.armed = True
        self._watch_stop.clear()
        self._watcher = threading.Thread(target=self._watch, name="liveness", daemon=True)
        self._watcher.start()

    def disarm(self) -> None:
        self.armed = False
        self._watch_stop.set()
        if self._watcher is not None and self._watcher is not threading.current_thread():
            self._watcher.join(timeout=5)
        self._watcher = None

    def _watch(self) -> None:
        asked = time.monotonic()
        while not self._watch_stop.wait(WATCH_S):
            lost = self.tick(time.monotonic() - asked - WATCH_S)
            asked = time.monotonic()
            if lost is not None:
                with self._lock:
                    self._found = lost
                return

    def tick(self, late_s: float) -> LoopStopped | None:
        """One look of the watcher, woken `late_s` later than it asked: after a stall of its own (> STALL_S)
        the nodes' silence is excused by as long (a node killed meanwhile is named that much later), else
        `check()`."""
        if late_s > STALL_S:
            with self._lock:
                for name in self.last:
                    self.last[name] += late_s
            return None
        return self.check()

    def verdict(self) -> LoopStopped | None:
        """The first sign of a lost node the watcher found (when it was found: `detected_at_unix`), or
        what a look now finds."""
        with self._lock:
            found = self._found
        return found if found is not None else self.check()

    def _silence_bound(self, name: str) -> float:
        """How long this node may be silent before it is named (starved_s for a running process of ours)."""
        proc = self.procs.get(name)
        pid = proc.proc.pid if proc is not None and proc.proc is not None else None
        if pid is None or self.starved_s <= self.timeout_s:
            return self.timeout_s
        state = process_state(proc.proc)
        if state is None:
            return self.timeout_s
        return self.timeout_s if state in ("T", "t") else self.starved_s

    def _who(self, name: str) -> str:
        return f"the {name} (node 0x{self.nodes[name]:02X})"

    def check(self) -> LoopStopped | None:
        """The first sign of a lost node, or None."""
        if not self.armed:
            return None
        now = time.monotonic()
        for name, proc in self.procs.items():
            rc = proc.proc.poll() if proc.proc is not None else None
            if rc is not None and getattr(proc.proc, "gone", None):  # the CAN box (its VM) ended
                return LoopStopped(
                    "node_lost",
                    f"{self._who(name)}: the CAN box it ran in ended during the run ({proc.proc.gone}); "
                    "the next run starts a new box",
                    name,
                    self.nodes[name],
                    details={"cause": "box_lost"},
                )
            if rc is not None:
                return LoopStopped(
                    "node_lost",
                    f"{self._who(name)}: its process {proc.name} {_exit_text(rc)}",
                    name,
                    self.nodes[name],
                    details={"cause": "process_exited", "exit_status": rc},
                )
        with self._lock:
            last, state, emcy = dict(self.last), dict(self.state), list(self.emcy[self.emcy_seen :])
        bound = {n: self._silence_bound(n) for n in self.nodes}
        if any(now - last[n] > bound[n] for n in self.nodes):
            # a heartbeat may wait in the socket while this process was busy: let the notifier run, look again
            time.sleep(self.grace_s / 2)
            now = time.monotonic()
            with self._lock:
                last = dict(self.last)
        for name in self.nodes:
            silent = now - last[name]
            if silent > bound[name]:
                starved = bound[name] > self.timeout_s
                return LoopStopped(
                    "node_lost",
                    f"{self._who(name)} sent no heartbeat for {silent:.2f} s (consumer "
                    f"time {self.timeout_s * 1000:.0f} ms"
                    + (f"; its process runs, allowed {bound[name]:.0f} s for a starved one" if starved else "")
                    + "): dead or silent",
                    name,
                    self.nodes[name],
                    detected_after_s=silent,
                    details={"cause": "heartbeat_timeout"},
                )
            st = state.get(name)
            if st is not None and st != 0x05:
                return LoopStopped(
                    "node_lost",
                    f"{self._who(name)} left OPERATIONAL: its heartbeat says {NMT_STATES.get(st, hex(st))}",
                    name,
                    self.nodes[name],
                    details={"cause": "nmt_state", "nmt_state": NMT_STATES.get(st, hex(st))},
                )
        # EMCY 0x8130 (a node lost the other's heartbeat) alone stops nothing: a node starved of CPU for a
        # moment reports it and resets it when the heartbeat is back. It names the node when the bench
        # has not heard it for half the consumer time either.
        for reporter, code, data, _t in emcy:
            lost = next((n for n, i in self.nodes.items() if i == data[3]), None)
            if (
                code == EMCY_HEARTBEAT
                and lost is not None
                and lost != reporter
                and now - last[lost] > self.timeout_s / 2
                and now - last[lost] > bound[lost] - self.timeout_s / 2
            ):
                return LoopStopped(
                    "node_lost",
                    f"{self._who(reporter)} lost the heartbeat of "
                    f"{self._who(lost)} (EMCY 0x8130), and so did the bench",
                    lost,
                    self.nodes[lost],
                    detected_after_s=now - last[lost],
                    details={"cause": "emcy_8130", "reported_by": reporter},
                )
        return None
