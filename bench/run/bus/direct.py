"""Direct mode: the C plant and drive node apps in-process (build/libhil.so), on an
in-memory CAN bus, exposed to Python as a python-can bus so `canopen` configures them
exactly as over vcan."""

from __future__ import annotations

import ctypes
import functools
import threading
import time
from typing import Any

import can
import numpy as np

from bench.eds import default_node_id
from bench.paths import BUILD
from bench.run.bus.frames import FRAME_DTYPE, FRAME_FD_DTYPE, frame_dtype


class _Frame(ctypes.Structure):
    _fields_ = [
        ("t_us", ctypes.c_uint64),
        ("seq", ctypes.c_uint32),
        ("cob_id", ctypes.c_uint16),
        ("dlc", ctypes.c_uint8),
        ("sender", ctypes.c_uint8),
        ("data", ctypes.c_uint8 * 8),
    ]


class FaultEvent(ctypes.Structure):
    """fi_event_t (protocols/faults/fault_injector.h): one action of the fault injector."""

    _fields_ = [
        ("period", ctypes.c_int64),
        ("t_us", ctypes.c_int64),
        ("rule", ctypes.c_uint16),
        ("kind", ctypes.c_uint8),
        ("side", ctypes.c_uint8),
        ("cob_id", ctypes.c_uint16),
        ("dlc", ctypes.c_uint8),
        ("data", ctypes.c_uint8 * 8),
    ]


def probe_host_floor(period_ns: int, seconds: float = 0.3) -> dict[str, float] | None:
    """The host's floor at a period: a plain absolute-deadline timer loop at the plant's priority on the plant's CPU
    (the first this process may use: cyclictest's measurement) for about `seconds` (1,000 to 5,000 wake-ups); its
    wake-up lateness, us. None when no thread could be started. Any bus: the plant's pacing is the same code."""
    n = max(1000, min(5000, round(seconds * 1e9 / max(period_ns, 1))))
    out = (ctypes.c_float * 4)()
    if _lib().hil_probe_floor(period_ns, n, out) < 0:
        return None
    vals = [round(float(v), 3) for v in out]
    return {
        "periods": n,
        "period_us": period_ns / 1e3,
        **dict(zip(("p50_us", "p99_us", "p99_9_us", "max_us"), vals, strict=True)),
    }


@functools.cache
def _lib() -> ctypes.CDLL:
    """libhil.so with its functions' C types, once per process (a sweep opens a Hil per point)."""
    path = BUILD / "libhil.so"
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing: run `make all`")
    lib = ctypes.CDLL(str(path))
    lib.hil_open.argtypes = [ctypes.c_uint8, ctypes.c_uint8]
    lib.hil_send.argtypes = [ctypes.c_uint16, ctypes.c_char_p, ctypes.c_uint8]
    lib.hil_recv.argtypes = [ctypes.POINTER(_Frame)]
    lib.hil_sdo.argtypes = [ctypes.c_uint16, ctypes.c_char_p, ctypes.c_uint16, ctypes.c_char_p]
    lib.hil_run.argtypes = [ctypes.c_uint32]
    lib.hil_run.restype = ctypes.c_uint32
    lib.hil_set_recorder.argtypes = [ctypes.c_void_p, ctypes.c_uint32]
    lib.hil_set_recorder_fd.argtypes = [ctypes.c_int]
    lib.hil_recorded.restype = ctypes.c_uint32
    lib.hil_record_dropped.restype = ctypes.c_uint64
    lib.hil_now_us.restype = ctypes.c_int64
    lib.hil_plant_period.restype = ctypes.c_uint64
    lib.hil_bus_frames.restype = ctypes.c_uint64
    lib.hil_faults.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
    lib.hil_fault_log.argtypes = [ctypes.POINTER(FaultEvent), ctypes.c_uint32]
    lib.hil_fault_log.restype = ctypes.c_uint32
    lib.hil_fault_overflows.restype = ctypes.c_uint64
    lib.hil_nodes_down.restype = ctypes.c_uint32
    lib.hil_node_state.argtypes = [ctypes.c_uint32]
    lib.hil_node_state.restype = ctypes.c_uint32
    lib.hil_linger.argtypes = [ctypes.c_int64]
    lib.hil_take.argtypes = [ctypes.c_void_p, ctypes.c_uint32]
    lib.hil_take.restype = ctypes.c_uint32
    lib.hil_run_realtime.argtypes = [ctypes.c_uint32]
    lib.hil_run_realtime.restype = ctypes.c_int32
    lib.hil_realtime_note.restype = ctypes.c_char_p
    lib.hil_pylaw_install.argtypes = [ctypes.c_uint8, ctypes.c_void_p]
    lib.hil_pylaw_install.restype = ctypes.c_int32
    lib.hil_pylaw_layout.argtypes = [ctypes.c_void_p, ctypes.c_uint32]
    lib.hil_pylaw_layout.restype = ctypes.c_uint32
    lib.hil_pylaw_record_bytes.argtypes = [ctypes.c_uint8]
    lib.hil_pylaw_record_bytes.restype = ctypes.c_uint32
    lib.hil_rt_dropped.restype = ctypes.c_uint64
    lib.hil_rt_period_ns.restype = ctypes.c_uint64
    lib.hil_probe_floor.argtypes = [ctypes.c_uint32, ctypes.c_uint32, ctypes.POINTER(ctypes.c_float)]
    lib.hil_probe_floor.restype = ctypes.c_int32
    assert lib.hil_frame_size() == FRAME_DTYPE.itemsize
    assert lib.hil_frame_fd_size() == FRAME_FD_DTYPE.itemsize
    assert lib.hil_fault_event_size() == ctypes.sizeof(FaultEvent)
    return lib


# One run at a time on the in-process bus: one plant and one drive per process, in libhil's statics (and one Python
# law: bench/direct/hil_pylaw.c). bench.run.run_scenario holds it for a direct run's whole life.
ONE_AT_A_TIME = threading.Lock()


class Hil:
    """The in-process plant + drive (one per process: the C side holds them in statics)."""

    _lock = threading.RLock()

    def __init__(self, plant_id: int | None = None, drive_id: int | None = None) -> None:
        self.lib = _lib()
        self._rec: np.ndarray | None = None
        with self._lock:
            self.lib.hil_open(
                default_node_id("plant") if plant_id is None else plant_id,
                default_node_id("drive") if drive_id is None else drive_id,
            )

    def set_faults(self, rules: str) -> int:
        """The fault injector's rules (protocols/faults/fault_rules.h text), before the run."""
        err = ctypes.create_string_buffer(256)
        with self._lock:
            n = self.lib.hil_faults(rules.encode(), err, len(err))
        if n < 0:
            raise ValueError(err.value.decode())
        return int(n)

    def fault_log(self) -> tuple[list[tuple[int, int, int, int, int, int, bytes]], int]:
        """Every action of the injector: (period, t_us, rule, kind, side, cob_id, data), and how many
        could not be kept (log full, hold queue full, a frozen node's queue full)."""
        with self._lock:
            total = self.lib.hil_fault_log(None, 0)
            buf = (FaultEvent * max(1, total))()
            self.lib.hil_fault_log(buf, total)
            lost = int(self.lib.hil_fault_overflows())
        return [(e.period, e.t_us, e.rule, e.kind, e.side, e.cob_id, bytes(e.data[: e.dlc])) for e in buf[:total]], lost

    def send(self, cob_id: int, data: bytes) -> None:
        with self._lock:
            if self.lib.hil_send(cob_id, bytes(data), len(data)) != 0:
                raise can.CanOperationError("in-process bus queue full")

    def sdo(self, req_cob: int, req: bytes, resp_cob: int, resp: ctypes.Array[ctypes.c_char]) -> int:
        """One SDO transfer (hil_sdo): the 8-byte request on req_cob, the server's answer on resp_cob into
        `resp`. 1 answered, 0 no answer, -1 the bus queue full."""
        with self._lock:
            return int(self.lib.hil_sdo(req_cob, req, resp_cob, resp))

    def recv(self) -> _Frame | None:
        f = _Frame()
        with self._lock:
            return f if self.lib.hil_recv(ctypes.byref(f)) else None

    def start_recorder(self, capacity: int, fd: bool = False) -> None:
        """Every frame on the in-process bus goes into a buffer of `capacity` frames, emptied by `take`; `fd`: in
        the wide record (FRAME_FD_DTYPE) of a run whose PDOs are CAN FD frames."""
        self._rec = np.empty(capacity, dtype=frame_dtype(fd))  # written frame by frame: never read unwritten
        with self._lock:
            self.lib.hil_set_recorder_fd(int(fd))
            self.lib.hil_set_recorder(self._rec.ctypes.data, capacity)

    def take(self) -> np.ndarray:
        """The frames recorded since the last call. The recorder moves on to a fresh buffer (no copy), in one
        step in C (in real time the nodes' threads record meanwhile)."""
        assert self._rec is not None
        fresh = np.empty(len(self._rec), dtype=self._rec.dtype)
        with self._lock:
            if self.lib.hil_record_dropped():
                raise RuntimeError(
                    f"direct recorder overflow: {self.lib.hil_record_dropped()} frames dropped "
                    f"(buffer of {len(self._rec)} frames)"
                )
            n = self.lib.hil_take(fresh.ctypes.data, len(fresh))
            out, self._rec = self._rec[:n], fresh
        return out

    def frames(self) -> int:
        """Frames the in-process bus has carried since it opened (every node's and the master's)."""
        with self._lock:
            return int(self.lib.hil_bus_frames())

    def run(self, max_periods: int) -> int:
        with self._lock:
            return int(self.lib.hil_run(max_periods))

    def run_realtime(self, max_periods: int) -> int:
        """The loop in real time (hil_realtime.c): the plant and the drive on threads of their own, the plant
        paced as plant_node paces itself, until the plant holds. Not under the lock: `take` runs meanwhile."""
        got = int(self.lib.hil_run_realtime(max_periods))
        if got < 0:
            raise RuntimeError("direct real time: the plant's or the drive's thread could not be started")
        return got

    def stop(self) -> None:
        """Ask a real-time run to stop (Ctrl-C): it returns at its next deadline (also asked before it started)."""
        self.lib.hil_stop()

    def receive_overflows(self) -> int:
        """Frames a node's receive FIFO could not take in real time (the node was not scheduled for that long):
        lost to it, as on a CAN controller; the loop shows them as overruns or lost frames."""
        return int(self.lib.hil_rt_dropped())

    def probe_floor(self, seconds: float = 0.3) -> dict[str, float] | None:
        """The host's floor at the plant's period: a plain absolute-deadline timer loop at the plant's priority and
        CPU (cyclictest's measurement) for about `seconds` (1,000 to 5,000 wake-ups); its wake-up lateness, us.
        None when no thread could be started."""
        return probe_host_floor(int(self.lib.hil_rt_period_ns()), seconds)

    def realtime_note(self) -> str:
        """What the plant's thread got of SCHED_FIFO / mlockall, in one line (after a real-time run)."""
        return (self.lib.hil_realtime_note() or b"").decode()

    def nodes_down(self) -> dict[str, int]:
        """The nodes out of the loop: name -> 0xFF killed, else its NMT state (not OPERATIONAL)."""
        with self._lock:
            down = self.lib.hil_nodes_down()
            return {n: int(self.lib.hil_node_state(i)) for i, n in enumerate(("plant", "drive")) if down >> i & 1}

    def linger(self, seconds: float) -> None:
        """Simulated time goes on with the nodes' timers only (after a node was lost)."""
        with self._lock:
            self.lib.hil_linger(int(seconds * 1e6))

    def period(self) -> int:
        return int(self.lib.hil_plant_period())

    def install_law(self, obj: Any) -> Any:
        """A current law prototyped in Python (bench/law_py.py) in place of the registered law its `law` names, until
        uninstall_law: its calls (bench.law_py.Calls: steps, first failure). LawError when it cannot stand in."""
        from bench.law_py import LAYOUT, Calls, LawError, callbacks, law_value, record_struct

        got = (ctypes.c_uint32 * 32)()
        n = self.lib.hil_pylaw_layout(got, len(got))
        if tuple(got[:n]) != LAYOUT:
            raise LawError(f"bench/law_py.py's structs {LAYOUT} are not {self.lib._name}'s {tuple(got[:n])}: rebuild")
        value = law_value(obj)
        rec = record_struct(obj.law)
        if (ctypes.sizeof(rec) if rec is not None else 0) != self.lib.hil_pylaw_record_bytes(value):
            raise LawError(f"the record of {obj.law} as bench/law_py.py reads drive.eds is not the drive's: rebuild")
        lib = self.lib

        def stop() -> None:  # the lockstep loop at its next step, a real-time run at its next deadline
            lib.hil_pylaw_interrupt()
            lib.hil_stop()

        calls = Calls(obj, rec, stop=stop)
        cb = callbacks(calls)
        calls.keep.append(cb)  # the callbacks live as long as the law is installed
        with self._lock:
            if self.lib.hil_pylaw_install(value, ctypes.byref(cb)) != 0:
                raise LawError(f"{obj.law}: the drive has no such law")
        return calls

    def uninstall_law(self) -> None:
        with self._lock:
            self.lib.hil_pylaw_uninstall()


class DirectBus(can.BusABC):
    """python-can bus over the in-process CAN bus of :class:`Hil`.

    The nodes answer a frame while it is sent (hil_send delivers it and everything it causes), so once
    `deliver_to` names the master's listeners (canopen's Network.listeners, `attach`), every answer is handed
    to them on the sending thread, before `send` returns: an SDO transfer costs a function call, not a wake-up
    of the notifier's thread (python-can's Notifier then only waits for the bus to close)."""

    def __init__(self, hil: Hil, **kwargs: object) -> None:
        self.hil = hil
        self.deliver_to: list[can.Listener] | None = None
        self._closed = threading.Event()
        self._sent = threading.Event()  # a frame went in: answers may be waiting (no polling delay)
        super().__init__(channel="direct", **kwargs)  # type: ignore[arg-type]
        self.channel_info = "in-process bus (direct mode)"

    def attach(self, listeners: list[can.Listener]) -> None:
        """Hand the nodes' answers to these listeners on the sending thread (what was queued before, too)."""
        self.deliver_to = listeners
        self._hand_over()

    def _hand_over(self) -> None:
        assert self.deliver_to is not None
        while (msg := self._take()) is not None:
            for listener in self.deliver_to:
                listener(msg)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.hil.send(msg.arbitration_id, bytes(msg.data))
        if self.deliver_to is not None:
            self._hand_over()
        else:
            self._sent.set()

    def _take(self) -> can.Message | None:
        f = self.hil.recv()
        if f is None:
            return None
        return can.Message(
            timestamp=f.t_us * 1e-6,
            arbitration_id=f.cob_id,
            is_extended_id=False,
            dlc=f.dlc,
            data=bytes(f.data[: f.dlc]),
            channel="direct",
        )

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.deliver_to is not None:  # answers go out on the sending thread: nothing to poll
                self._closed.wait(timeout)
                return None, False
            msg = self._take()
            if msg is not None:
                return msg, False
            if self._closed.is_set() or (deadline is not None and time.monotonic() >= deadline):
                return None, False
            # The nodes answer only to what is sent (in direct mode nothing else happens while the master
            # waits): sleep until the next send, or briefly (the lockstep loop's frames are not for the master).
            self._sent.wait(0.002 if deadline is None else max(0.0, min(0.002, deadline - time.monotonic())))
            self._sent.clear()

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """As BusABC.recv, but returns at once when the bus is closing (BusABC would keep polling
        `_recv_internal` until its timeout ends: a second at every disconnect)."""
        if self._closed.is_set():
            return None
        msg, _ = self._recv_internal(timeout)
        return msg

    def close_soon(self) -> None:
        """The notifier's recv returns at once from now on (before Network.disconnect)."""
        self._closed.set()

    def shutdown(self) -> None:
        self.close_soon()
        super().shutdown()
