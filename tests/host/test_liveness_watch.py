"""The liveness verdict does not wait for the master's main thread: a node that falls silent while the
main thread is busy (decoding, in the VM for seconds) is named when it happens, not when the thread is free."""

from __future__ import annotations

import time
from typing import Any

from bench.run.bus.liveness import Liveness


class _Net:
    """What Liveness needs of a canopen.Network: subscriptions, fed by hand."""

    def __init__(self) -> None:
        self.subs: dict[int, list[Any]] = {}

    def subscribe(self, cob: int, cb: Any) -> None:
        self.subs.setdefault(cob, []).append(cb)

    def unsubscribe(self, cob: int, cb: Any) -> None:
        self.subs[cob].remove(cb)

    def heartbeat(self, node_id: int) -> None:
        for cb in self.subs.get(0x700 + node_id, []):
            cb(0x700 + node_id, bytearray([0x05]), time.time())


def _busy(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:  # pure Python: holds the GIL as a decoder would
        sum(range(1000))


def test_a_silent_node_is_named_while_the_main_thread_is_busy() -> None:
    net = _Net()
    live = Liveness(net, {"plant": 0x10, "drive": 0x20}, {}, timeout_ms=300, heartbeat_ms=50)  # type: ignore[arg-type]
    live.arm()
    try:
        # the plant keeps beating from the main thread's point of view only until it gets busy
        net.heartbeat(0x10)
        net.heartbeat(0x20)
        t_silent = time.time()
        _busy(3.0)
        t_free = time.time()
        lost = live.verdict()
        assert lost is not None and lost.status == "node_lost"
        assert lost.details["cause"] == "heartbeat_timeout"
        # found by the watcher during the busy stretch, after the consumer time
        assert t_silent + 0.3 <= lost.detected_at_unix < t_free
    finally:
        live.close()
    assert not any(net.subs.values())


def test_beating_nodes_are_not_named() -> None:
    net = _Net()
    live = Liveness(net, {"plant": 0x10}, {}, timeout_ms=300, heartbeat_ms=50)  # type: ignore[arg-type]
    live.arm()
    try:
        for _ in range(20):
            net.heartbeat(0x10)
            time.sleep(0.05)
        assert live.verdict() is None
    finally:
        live.close()


def test_a_stall_of_the_watcher_itself_is_not_a_silent_node() -> None:
    """Under load (the VM's vCPUs descheduled by a busy host) the whole guest stops, and its clock jumps
    when it runs again: the watcher, woken that much late, must not take its own stall for the node's
    silence. A real silence, with the watcher on time, is still named."""

    class Net:
        def subscribe(self, cob: int, cb: object) -> None:
            pass

    def watcher(silent_s: float) -> Liveness:
        lv = Liveness(Net(), {"plant": 0x10}, {}, timeout_ms=1000, heartbeat_ms=100)  # type: ignore[arg-type]
        lv.armed = True
        lv.last["plant"] = time.monotonic() - silent_s
        return lv

    assert watcher(1.9).tick(late_s=1.85) is None  # 1.9 s without a heartbeat, 1.85 s of it the watcher's own
    lost = watcher(1.9).tick(late_s=0.0)
    assert lost is not None and lost.status == "node_lost" and lost.node == "plant", lost


def test_a_running_silent_node_of_ours_is_taken_for_starved_a_stopped_one_for_frozen() -> None:
    """A node process the bench started that still runs (a vCPU of the loaded VM descheduled) is allowed
    STARVED_S of silence; stopped (SIGSTOP: kernel state T) it is named after the consumer time."""
    import signal
    import subprocess
    from types import SimpleNamespace

    from bench.run.bus import liveness

    node = SimpleNamespace(name="sleep", proc=subprocess.Popen(["sleep", "60"]))
    net = _Net()
    live = Liveness(net, {"drive": 0x20}, {"drive": node}, 300, 50, starved_s=liveness.STARVED_S)  # type: ignore[arg-type]
    try:
        live.arm()
        net.heartbeat(0x20)
        live.last["drive"] -= 1.0  # silent for a second: beyond the consumer time, far within STARVED_S
        assert liveness.STARVED_S > 1.5 and live.check() is None  # (with starved_s=0, as in real time: named)
        node.proc.send_signal(signal.SIGSTOP)
        for _ in range(100):  # the kernel's state follows the signal at once; bounded, not timed
            lost = live.check()
            if lost is not None:
                break
            time.sleep(0.01)
        assert lost is not None and lost.node == "drive" and lost.details["cause"] == "heartbeat_timeout", lost
        assert "allowed" not in lost.message
    finally:
        live.close()
        node.proc.send_signal(signal.SIGCONT)
        node.proc.kill()
        node.proc.wait()
