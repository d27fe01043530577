"""Run a scenario on a bus and capture every frame: the part of `bench run` that talks
CANopen. Works the same over SocketCAN (vcan0, can0) and in direct mode (in-process).

Sequence: recorder on -> node processes up -> NMT reset -> configuration by SDO from the
EDS names (preset, model, controller with its mismatch, PDO wiring, trace PDOs) -> NMT
start -> run the periods between events in lockstep ("run N periods then hold" object of
the plant), applying each event's SDO writes at its exact period -> read the statuses ->
NMT pre-operational -> recorder off. Output: frames.npy, layout.json, capture.json.
"""

from __future__ import annotations

import json
import shutil
import signal
import struct
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import can
import canopen
import numpy as np
from canopen.sdo.exceptions import SdoAbortedError

from .direct import FRAME_DTYPE, DirectBus, Hil
from .eds import eds_path
from .layout import BusLayout, read_layout
from .nodes import NodeProcess, in_vm
from .scenario import Scenario, Setting

PROGRESS = Callable[[int, int], None]
HOLD_TPDO = 4  # the plant TPDO the bench maps to the hold announcement
DIRECT_CHUNK = 50_000


@dataclass
class RunOptions:
    bus: str = "direct"            # "direct" or a CAN channel (vcan0, can0, ...)
    interface: str = "socketcan"   # python-can interface for non-direct buses
    bitrate: int | None = None
    fd: bool = False
    data_bitrate: int | None = None
    plant_id: int = 0x10
    drive_id: int = 0x20
    start_plant: bool = True       # start the C plant process (False: a physical plant/drive is on the bus)
    start_drive: bool = True       # start the C drive process (False: a physical drive implements drive.eds)
    out: Path = Path("runs/latest")
    record: bool = True            # record every frame (candump / in-process); off only for benchmarks
    decode_log: bool = True        # decode the recorder's log into frames.npy at the end (the VM leaves it to the host)


@dataclass
class Capture:
    scenario: str
    bus: str
    periods: int
    event_periods: list[int]
    wall_s: float
    run_wall_s: float
    frames: int
    counters: dict[str, float] = field(default_factory=dict)
    identified: dict[str, float] = field(default_factory=dict)
    plant: dict[str, float] = field(default_factory=dict)
    controller: dict[str, float] = field(default_factory=dict)
    references: list[tuple[int, str, float]] = field(default_factory=list)  # (period, name, value)
    applied: list[tuple[int, str, float]] = field(default_factory=list)     # (period, scenario key, value)


class Recorder:
    """Every frame of a SocketCAN bus, recorded by can-utils' candump (C, large socket buffer)
    so that no frame is lost at the lockstep rate even where Python is slow.

    Inside the VM the log is written to the guest's own /tmp (a shared 9p folder is far too
    slow for a frame per line) and copied in blocks to `path` every half second, so that a
    live view on the host can follow it; elsewhere candump writes `path` directly."""

    def __init__(self, iface: str, path: Path, decode: bool = True) -> None:
        self.path = path
        self.decode = decode
        exe = shutil.which("candump")
        if exe is None:
            raise RuntimeError("candump not found: apt-get install can-utils")
        self.local = path
        self._tmpdir: str | None = None
        if in_vm():
            self._tmpdir = tempfile.mkdtemp(prefix="bench-rec-")
            self.local = Path(self._tmpdir) / path.name
        self._fh = open(self.local, "wb")  # noqa: SIM115 - closed in stop()
        # -L: log-file format on stdout; -r: 8 MiB receive buffer; line-buffered (stdbuf) so that a
        # live view can follow the file while the run goes on.
        argv = [exe, "-L", "-r", str(8 << 20), iface]
        if shutil.which("stdbuf"):
            argv = ["stdbuf", "-oL", *argv]
        self.proc = subprocess.Popen(argv, stdout=self._fh, stderr=subprocess.PIPE)
        time.sleep(0.2)
        if self.proc.poll() is not None:
            raise RuntimeError(f"candump failed: {self.proc.stderr.read().decode() if self.proc.stderr else ''}")
        self._stop = threading.Event()
        self._copier: threading.Thread | None = None
        if self.local != path:
            self._copier = threading.Thread(target=self._copy_loop, daemon=True)
            self._copier.start()

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

    def stop(self) -> np.ndarray:
        time.sleep(0.2)
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self._fh.close()
        frames = frames_from_log(self.local) if self.decode else np.zeros(0, dtype=FRAME_DTYPE)
        if self._copier is not None:
            self._stop.set()
            self._copier.join(timeout=60)
        if self._tmpdir:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
        return frames


class _ListRecorder(can.Listener):
    def __init__(self, sink: list[can.Message]) -> None:
        self.sink = sink

    def on_message_received(self, msg: can.Message) -> None:
        self.sink.append(msg)


def frames_from_log(path: Path) -> np.ndarray:
    """Any log python-can reads (candump .log, .asc, .blf, ...) as the bench's frame array."""
    return frames_from_messages(list(can.LogReader(str(path))))


def frames_from_messages(msgs: list[can.Message]) -> np.ndarray:
    """Messages in bus order. A recorder's log may hold a few frames out of order (candump on a
    loaded machine writes a socket's queue after another's); the kernel receive time stamps give
    the order, so sort by them (stable, so equal stamps keep the log order)."""
    msgs = sorted(msgs, key=lambda m: m.timestamp)
    arr = np.zeros(len(msgs), dtype=FRAME_DTYPE)
    t0 = msgs[0].timestamp if msgs else 0.0
    for i, m in enumerate(msgs):
        arr[i]["t_us"] = int(round((m.timestamp - t0) * 1e6))
        arr[i]["seq"] = i
        arr[i]["cob_id"] = m.arbitration_id & 0x7FF
        arr[i]["dlc"] = m.dlc
        arr[i]["sender"] = 255
        arr[i]["data"][: len(m.data)] = np.frombuffer(bytes(m.data), dtype=np.uint8)
    return arr


def _entry(node: canopen.RemoteNode, obj: str, sub: str | None = None):  # type: ignore[no-untyped-def]
    return node.sdo[obj] if sub is None else node.sdo[obj][sub]


class Session:
    def __init__(self, sc: Scenario, opts: RunOptions) -> None:
        self.sc = sc
        self.opts = opts
        self.hil: Hil | None = None
        self.procs: list[NodeProcess] = []
        self.recorder: Recorder | None = None
        self.net = canopen.Network()
        self.plant = canopen.RemoteNode(opts.plant_id, str(eds_path("plant")))
        self.drive = canopen.RemoteNode(opts.drive_id, str(eds_path("drive")))
        self.plant_values: dict[str, float] = {}
        self.kernel_filters: list[dict[str, int]] | None = None
        self.references: list[tuple[int, str, float]] = []
        self.applied: list[tuple[int, str, float]] = []  # every setting with the period it took effect
        self._hold = threading.Event()
        self._hold_index = -1
        self._hold_cob = 0

    # ---------------------------------------------------------------- bus
    def open(self) -> None:
        out = self.opts.out
        if self.opts.bus == "direct":
            self.hil = Hil(self.opts.plant_id, self.opts.drive_id)
            self.hil.start_recorder(self.sc.periods * 8 + 20000)
            self.net.bus = DirectBus(self.hil)
        else:
            self.recorder = (Recorder(self.opts.bus, out / "candump.log", self.opts.decode_log)
                             if self.opts.interface == "socketcan" and self.opts.record else None)
            if self.opts.start_plant:
                self.procs.append(NodeProcess("plant_node", ["--iface", self.opts.bus, "--node-id",
                                                             str(self.opts.plant_id)], out / "plant_node.out").start())
            if self.opts.start_drive:
                self.procs.append(NodeProcess("drive_node", ["--iface", self.opts.bus, "--node-id",
                                                             str(self.opts.drive_id)], out / "drive_node.out").start())
            # The master only needs SDO answers, NMT error control and EMCY: filtering in the kernel keeps
            # the PDO stream (thousands of frames per second) out of this process's socket, which a slow
            # Python (the VM) could not drain, and which the recorder records anyway.
            ids = (self.opts.plant_id, self.opts.drive_id)
            filters = [{"can_id": 0x580 + i, "can_mask": 0x7FF} for i in ids]
            filters += [{"can_id": 0x080 + i, "can_mask": 0x7FF} for i in ids]
            filters.append({"can_id": 0x700, "can_mask": 0x780})
            self.kernel_filters = filters if self.opts.interface == "socketcan" else None
            kwargs: dict[str, object] = {"interface": self.opts.interface, "channel": self.opts.bus}
            if self.kernel_filters is not None:
                kwargs["can_filters"] = filters
            if self.opts.bitrate:
                kwargs["bitrate"] = self.opts.bitrate
            if self.opts.fd:
                kwargs["fd"] = True
                if self.opts.data_bitrate:
                    kwargs["data_bitrate"] = self.opts.data_bitrate
            self.net.bus = can.Bus(**kwargs)  # type: ignore[arg-type]
        self.net.connect()
        if self.hil is None and self.recorder is None and self.opts.record:
            # Not SocketCAN (a USB adapter, a log replay interface ...): record in this process.
            self.py_recorder: list[can.Message] = []
            self.net.notifier.add_listener(_ListRecorder(self.py_recorder))
        self.net.add_node(self.plant)
        self.net.add_node(self.drive)
        for n in (self.plant, self.drive):
            n.sdo.RESPONSE_TIMEOUT = 5.0

    def close(self) -> np.ndarray:
        frames = np.zeros(0, dtype=FRAME_DTYPE)
        try:
            for n in (self.plant, self.drive):
                try:
                    n.nmt.send_command(0x80)
                except Exception:  # noqa: BLE001 - shutting down whatever happened
                    pass
        finally:
            try:
                self.net.disconnect()
            except Exception:  # noqa: BLE001
                pass
            for p in self.procs:
                p.stop()
            if self.hil is not None:
                frames = self.hil.recorded()
            elif self.recorder is not None:
                frames = self.recorder.stop()
            elif hasattr(self, "py_recorder"):
                frames = frames_from_messages(self.py_recorder)
        return frames

    # ---------------------------------------------------------------- NMT
    def reset_nodes(self) -> None:
        booted: dict[int, bool] = {}

        def on_boot(cob_id: int, data: bytearray, ts: float) -> None:
            if len(data) == 1 and data[0] == 0:
                booted[cob_id - 0x700] = True

        for n in (self.plant, self.drive):
            self.net.subscribe(0x700 + n.id, on_boot)
        deadline = time.monotonic() + 10
        # Nodes just started announce themselves; a reset node announces again.
        for n in (self.plant, self.drive):
            n.nmt.send_command(0x81)
        while time.monotonic() < deadline and not all(booted.get(n.id) for n in (self.plant, self.drive)):
            time.sleep(0.01)
        for n in (self.plant, self.drive):
            self.net.unsubscribe(0x700 + n.id, on_boot)
            if not booted.get(n.id):
                raise RuntimeError(f"node 0x{n.id:02X} did not answer the NMT reset with a boot-up message "
                                   f"(is it on bus {self.opts.bus}?)")

    # ---------------------------------------------------------------- configuration
    def _write(self, var, value: float | int, what: str) -> None:  # type: ignore[no-untyped-def]
        """One SDO write; a refusal names the scenario key, the value and the node's reason."""
        try:
            var.raw = value
        except SdoAbortedError as exc:
            raise RuntimeError(f"{what} = {value:g} refused by node 0x{var.sdo_node.rx_cobid - 0x600:02X} (object "
                               f"{var.od.qualname!r}) at period {self._period}: {exc}") from None

    def _apply(self, s: Setting) -> None:
        self.applied.append((self._period, s.key, float(s.value)))
        if s.param is None:  # ratio of a plant value
            for drive_name, plant_name in s.ratio_of:
                value = self.plant_values[plant_name] * float(s.value)
                self._write(_entry(self.drive, "Controller", drive_name), value, f"{s.key} -> {drive_name}")
            return
        node = self.plant if s.param.node == "plant" else self.drive
        self._write(_entry(node, s.param.obj, s.param.name), s.value, s.key)
        if s.param.obj == "References":
            self.references.append((self._period, s.param.name, float(s.value)))

    def configure(self) -> BusLayout:
        self._period = 0
        sc, plant, drive = self.sc, self.plant, self.drive
        if sc.preset:
            plant.sdo["Motor preset"].raw = sc.preset
        plant.sdo["Sensors"]["rng_seed"].raw = sc.seed
        plant.sdo["Run control"]["mode"].raw = 0 if sc.timing == "lockstep" else 1
        for s in sc.settings:
            if s.param is not None and s.param.node == "plant":
                self._apply(s)
        mm = plant.sdo["Motor model"]
        for name in ("R_ohm", "Ld_H", "Lq_H", "psi_Wb", "pole_pairs", "J_kgm2"):
            self.plant_values[name] = mm[name].raw
        self.plant_values["Ts_s"] = plant.sdo["Inverter"]["Ts_s"].raw
        self.plant_values["Vdc_V"] = plant.sdo["Inverter"]["Vdc_V"].raw
        # The controller starts from the plant's true values; the scenario's mismatch follows.
        ctl = drive.sdo["Controller"]
        for hat, true in (("R_hat_ohm", "R_ohm"), ("Ld_hat_H", "Ld_H"), ("Lq_hat_H", "Lq_H"), ("psi_hat_Wb", "psi_Wb"),
                          ("J_hat_kgm2", "J_kgm2")):
            self._write(ctl[hat], self.plant_values[true], f"controller.{hat}")
        explicit = {s.key for s in sc.settings}
        for s in sc.settings:
            if s.param is None or s.param.node == "drive":
                self._apply(s)
        # The controller runs at the plant's period with its pole pairs, unless the scenario says otherwise;
        # written after the scenario's bandwidths, which the drive checks against Ts.
        for name in ("Ts_s", "pole_pairs"):
            if f"controller.{name}" not in explicit:
                self._write(ctl[name], self.plant_values[name], f"controller.{name} (= the plant's {name})")
        for e in sc.events:
            if e.at_period == 0:
                for s in e.settings:
                    self._apply(s)
        self.wire_pdos()
        return read_layout(plant, drive)

    def wire_pdos(self) -> None:
        """Link the plant's measurement TPDOs to the drive's RPDOs and the drive's command
        TPDO to the plant's RPDO (COB-IDs read from the nodes), and map the trace PDOs."""
        plant, drive = self.plant, self.drive
        plant.tpdo.read()
        drive.tpdo.read()
        drive.rpdo.read()
        plant.rpdo.read()
        for num in (1, 2):
            m = drive.rpdo[num]
            m.cob_id = plant.tpdo[num].cob_id
            m.enabled = True
            m.save()
        m = plant.rpdo[1]
        m.cob_id = drive.tpdo[1].cob_id
        m.enabled = True
        m.save()
        # The plant's hold announcement: an event-driven TPDO carrying the run state, sent once when the
        # plant holds with the last command in (plant_app.c). The master waits for it instead of polling.
        m = plant.tpdo[HOLD_TPDO]
        m.clear()
        m.add_variable("Run control", "period_index")
        m.add_variable("Run control", "state")
        m.trans_type = 254
        m.enabled = True
        m.save()
        self._hold_cob = m.cob_id
        for num, signals in self.sc.trace.items():
            m = drive.tpdo[num]
            m.clear()
            for sig in signals:
                obj, sub = sig.split(".")
                m.add_variable(obj, sub)
            m.trans_type = 1  # synchronous: the values after step k-1, sent at SYNC k
            m.enabled = True
            m.save()

    # ---------------------------------------------------------------- run
    def _on_hold(self, cob_id: int, data: bytearray, ts: float) -> None:
        index, state = struct.unpack_from("<IB", bytes(data))
        if state == 0:
            self._hold_index = index
            self._hold.set()

    def _run_segment(self, n: int, target_index: int) -> None:
        rc = self.plant.sdo["Run control"]
        self._hold.clear()
        rc["run_periods"].raw = n
        if self.hil is not None:
            ran = 0
            while ran < n:  # in chunks, so that Ctrl-C is seen promptly
                got = self.hil.run(min(DIRECT_CHUNK, n - ran))
                if got == 0:
                    break
                ran += got
            if ran != n:
                raise RuntimeError(f"direct run stopped after {ran} of {n} periods")
            return
        t0 = time.monotonic()
        deadline = t0 + 30 + n * 0.01
        index = -1
        while time.monotonic() < deadline:
            # the hold announcement (no bus load, no CPU while the loop runs) ...
            if self._hold.wait(timeout=min(2.0, max(0.05, deadline - time.monotonic()))) \
                    and self._hold_index >= target_index:
                self._hold.clear()
                return
            self._hold.clear()
            # ... and, should it be missed, the same information by SDO
            index = rc["period_index"].raw
            if index >= target_index and rc["state"].raw == 0:
                return
        raise RuntimeError(f"the plant did not reach period {target_index} in time (at {index})")

    def run(self, progress: PROGRESS | None = None) -> float:
        sc = self.sc
        if self.hil is None:
            self.net.subscribe(self._hold_cob, self._on_hold)
            if self.kernel_filters is not None:
                self.net.bus.set_filters([*self.kernel_filters, {"can_id": self._hold_cob, "can_mask": 0x7FF}])
        for n in (self.plant, self.drive):
            n.nmt.send_command(0x01)
        bounds = [p for p in sc.event_periods() if p > 0] + [sc.periods]
        start = 0
        t0 = time.monotonic()
        events = {e.at_period: e for e in sc.events}
        for stop in bounds:
            if stop > start:
                self._run_segment(stop - start, stop - 1)
            self._period = stop
            if stop in events:
                for s in events[stop].settings:
                    self._apply(s)
            start = stop
            if progress:
                progress(start, sc.periods)
        return time.monotonic() - t0

    def statuses(self) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
        rc = self.plant.sdo["Run control"]
        ds = self.drive.sdo["Drive status"]
        tun = self.drive.sdo["Online tuning"]
        counters = {"plant_missed_commands": rc["missed_commands"].raw, "plant_late_commands": rc["late_commands"].raw,
                    "plant_period_index": rc["period_index"].raw, "drive_current_steps": ds["current_steps"].raw,
                    "drive_lost_measurements": ds["lost_measurements"].raw,
                    "drive_late_measurements": ds["late_measurements"].raw}
        identified = {n: tun[n].raw for n in ("K1_avg", "K2_avg", "L_hat_H", "identifications", "K1_active_V_A",
                                              "K2_active_V_A", "gain_updates")}
        ctl = self.drive.sdo["Controller"]
        controller = {n: ctl[n].raw for n in ("controller", "R_hat_ohm", "Ld_hat_H", "Lq_hat_H", "psi_hat_Wb",
                                              "Vmax_V", "Ts_s", "pole_pairs")}
        return counters, identified, controller


def capture(sc: Scenario, opts: RunOptions, progress: PROGRESS | None = None) -> Capture:
    """Run the scenario and write frames.npy, layout.json and capture.json into opts.out."""
    opts.out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    sess = Session(sc, opts)
    frames = np.zeros(0, dtype=FRAME_DTYPE)
    try:
        sess.open()
        sess.reset_nodes()
        layout = sess.configure()
        layout.save(opts.out / "layout.json")
        (opts.out / "plant.json").write_text(json.dumps(sess.plant_values))
        run_wall = sess.run(progress)
        counters, identified, controller = sess.statuses()
    finally:
        frames = sess.close()
    np.save(opts.out / "frames.npy", frames)
    cap = Capture(sc.name, opts.bus, sc.periods, sc.event_periods(), time.monotonic() - t0, run_wall, len(frames),
                  counters, identified, sess.plant_values, controller, sess.references, sess.applied)
    (opts.out / "capture.json").write_text(json.dumps(asdict(cap), indent=2))
    return cap
