"""The CANopen master of a run: the part of `bench run` that talks to the nodes. Works the
same over SocketCAN (vcan0, can0) and in direct mode (in-process).

Sequence: node processes up -> NMT reset -> configuration by SDO from the EDS names (preset,
model, controller with its mismatch, PDO wiring, trace PDOs) -> NMT start -> run the periods
between events in lockstep ("run N periods then hold" object of the plant), applying each
event's SDO writes at its exact period -> read the statuses -> NMT Stop (the teardown). Every
frame of it is on the bus, where the recorder (bench/run/record/sources.py) takes it: the session
returns nothing the frames do not also say (bench/run/decode/sdo_log.py reads it back from them).

This module owns Session's opening and closing, the NMT commands, the run of the periods and the statuses
read at the end; the nodes and buses it opens over SocketCAN are its base, bench/run/loop/session_bus.py.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable
from typing import Any

import can
from canopen.sdo.base import SdoVariable
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench.run.bus.buses import bus_of
from bench.run.bus.direct import DirectBus, Hil
from bench.run.bus.direct_sdo import DirectSdo
from bench.run.bus.kind import BusKind, SettingRefused
from bench.run.bus.liveness import STARVED_S, Liveness, LoopStopped
from bench.run.bus.nodes import NodeProcess
from bench.run.loop import master
from bench.run.loop.bus_loop import BusLoop
from bench.run.loop.configure import Configurator
from bench.run.loop.direct_loop import DirectLoop
from bench.run.loop.reads import END_READS, REALTIME_READS, STEP_COST
from bench.run.loop.session_bus import SessionBus
from bench.run.options import MCU_STALL_S, RunOptions
from bench.scenario import Scenario
from bench.scenario.faults import rules_text

PROGRESS = Callable[[int, int], None]
BOOT_S = 10.0  # the nodes' boot-up messages after the NMT reset: the wait for a node that is not ours
BOOT_ALIVE_S = 120.0  # ... and for nodes whose processes this run started, while they are all alive


class Session(SessionBus):
    """The master of one run, made of parts: the nodes (processes, or libhil's in direct mode: SessionBus), the
    canopen network, a Configurator (the SDO configuration), the loop driver (DirectLoop in process, lockstep
    segments over a bus) and the Liveness watch."""

    def __init__(self, sc: Scenario, opts: RunOptions, kind: BusKind | None = None) -> None:
        """`kind`: the run's bus (buses.bus_of; by default the one its options name, never the CAN box: a box is
        leased by run_scenario, which passes the kind it chose)."""
        kind = kind or bus_of(opts, bool(sc.faults), box=False)
        # the master's Network and RemoteNodes (bench/run/loop/master.py): on the in-process bus kept between runs
        self.master = (master.take if kind.in_process else master.new_master)(opts.plant_id, opts.drive_id)
        self._kept = kind.in_process  # given back at close
        super().__init__(sc, opts, self.master.net, self.master.plant, kind)
        self.drive = self.master.drive
        self.config = Configurator(sc, opts, self.plant, self.drive, maps_from_eds=kind.in_process)
        self.direct: DirectLoop | None = None  # direct mode: the in-process loop (its on_chunk, on_stop)
        self.bus_loop: BusLoop | None = None  # over a bus: the lockstep segments (run())
        self.liveness: Liveness | None = None
        self.py_law: Any = None  # a Python law in the loop: its calls (bench.law_py.Calls)

    def open(self) -> None:
        if self.kind.in_process:
            self.hil = Hil(self.opts.plant_id, self.opts.drive_id)
            if self.opts.py_law is not None:  # before the configuration, which configures the law
                self.py_law = self.hil.install_law(self.opts.py_law)
            if self.sc.faults:
                self.hil.set_faults(
                    rules_text(self.sc.faults, self.opts.plant_id, self.opts.drive_id, self.sc.frames.sync_less)
                )
            self.net.bus = self.kind.master_bus(self.opts, self.hil)
            self.direct = DirectLoop(self.hil, self.opts, realtime=self.sc.timing == "realtime")
        else:
            if self.opts.py_law is not None:
                raise SettingRefused(
                    "a current law in Python runs in the direct loop only (--bus direct): its methods are called in "
                    "this process; over a bus, run its C port (--law DIR)"
                )
            self._open_bus()
            # the CAN box: QEMU's emulation may starve one node for seconds (options.py BOX_CONSUMER_MS)
            self.config.consumer_ms = self.kind.consumer_ms(self.config.consumer_ms)
        if isinstance(self.net.bus, DirectBus):
            # The nodes' answers go to the master's listeners on the sending thread (DirectBus.attach): no
            # notifier thread to start and stop per run (what canopen's connect() would do), nothing to poll.
            self.net.bus.attach(self.net.listeners)
        else:
            self.net.connect()
        for n in (self.plant, self.drive):  # added and subscribed by master.new_master
            n.sdo.RESPONSE_TIMEOUT = (
                MCU_STALL_S if n is self.drive and self.opts.drive == "mcu" else self.kind.sdo_timeout_s()
            )
            if self.hil is not None:  # expedited transfers in one C call each (bench/run/bus/direct_sdo.py)
                DirectSdo(n.sdo, self.hil).install()
        if self.hil is None:  # in direct mode the loop is in this process, on simulated time
            self.liveness = Liveness(
                self.net,
                {"plant": self.opts.plant_id, "drive": self.opts.drive_id},
                self.node_procs,
                self.opts.heartbeat_timeout_ms,
                self.opts.heartbeat_ms,
                starved_s=(MCU_STALL_S if self.opts.drive == "mcu" else STARVED_S)
                if self.sc.timing == "lockstep"
                else 0.0,
            )

    def close(self) -> None:
        if self.plant_cpu is not None:
            self.plant_cpu.release()
            self.plant_cpu = None
        if self.liveness is not None:
            self.liveness.disarm()
            self.liveness.close()
        try:
            # The teardown begins with NMT Stop to both nodes, before any process is stopped: a STOPPED node
            # sends no PDO and no EMCY (CiA 301), so a drive that outlives the plant's heartbeat by more than its
            # consumer time (a loaded host stops the processes one after the other) raises no alarm; and the
            # decoder takes every frame from this command on as the teardown's, never the run's
            # (bench/run/decode/decoder.py TEARDOWN_NMT), whatever a slow node still sends.
            for n in (self.plant, self.drive):
                try:
                    n.nmt.state = "STOPPED"  # python canopen's NMT table: the command 0x02
                except Exception:  # noqa: BLE001 - shutting down whatever happened
                    pass
        finally:
            try:
                self.net.disconnect()
            except Exception:  # noqa: BLE001
                pass
            if self._kept:  # once: a second close gives nothing back
                self._kept = False
                master.give_back(self.master)
            self._stop_nodes()
            if self.py_law is not None and self.hil is not None:  # after the NMT Stop: the law's last calls are its
                self.hil.uninstall_law()

    def configure(self) -> None:
        try:
            self.config.configure()
        except (SdoCommunicationError, can.CanError):  # a box that ended while its nodes were configured
            self._check_box(-1)
            raise

    def linger(self) -> None:
        """After a lost node: let the survivor's reaction happen and be recorded (its heartbeat consumer
        fires after the consumer time): the consumer time plus a margin, simulated in direct mode."""
        wait = self.config.consumer_ms / 1000.0 + 0.3
        if self.hil is not None:
            self.hil.linger(wait)  # its frames go with the final drain of the recorder
        else:
            time.sleep(wait)

    # ---------------------------------------------------------------- NMT
    def reset_nodes(self) -> None:
        """NMT reset of both nodes and their boot-up awaited; a CAN box that ends meanwhile stops the run as in
        its loop (node_lost, cause box_lost)."""
        try:
            self._reset_nodes()
        except (RuntimeError, can.CanError):
            self._check_box(-1)
            raise

    def _reset_nodes(self) -> None:
        booted: dict[int, bool] = {}
        all_booted = threading.Event()  # set by the notifier (a bus) or at once (direct): no polling delay

        def on_boot(cob_id: int, data: bytearray, ts: float) -> None:
            if len(data) == 1 and data[0] == 0:
                booted[cob_id - 0x700] = True
                if all(booted.get(n.id) for n in (self.plant, self.drive)):
                    all_booted.set()

        for n in (self.plant, self.drive):
            self.net.subscribe(0x700 + n.id, on_boot)
        # Nodes just started announce themselves; a reset node announces again.
        for n in (self.plant, self.drive):
            n.nmt.send_command(0x81)
        self._wait_booted(all_booted, booted)
        for n in (self.plant, self.drive):
            self.net.unsubscribe(0x700 + n.id, on_boot)
            if not booted.get(n.id):
                ended = [f"the {name}'s process ended" for name, p in self.node_procs.items() if not p.alive()]
                raise RuntimeError(
                    f"node 0x{n.id:02X} did not answer the NMT reset with a boot-up message "
                    f"({'; '.join(ended) or f'is it on bus {self.opts.bus}?'})"
                )

    def _wait_booted(self, all_booted: threading.Event, booted: dict[int, bool]) -> None:
        """BOOT_S for the boot-up messages; longer, up to BOOT_ALIVE_S, while each node still silent is one whose
        process this run started and which still runs (a loaded host, the CAN box under load: a node process once
        took over 10 s to start there). A node of no process of ours (a physical one, --no-plant) gets BOOT_S."""
        # a node process of this run's (not the MCU image's serial bridge, alive whatever the image does)
        ours = {
            n.id: p if isinstance(p, NodeProcess) else None
            for n, p in ((self.plant, self.node_procs.get("plant")), (self.drive, self.node_procs.get("drive")))
        }
        t0 = time.monotonic()
        while not all_booted.wait(timeout=0.2):
            waited = time.monotonic() - t0
            silent = [ours[n] for n in ours if not booted.get(n)]
            if waited > BOOT_ALIVE_S or (waited > BOOT_S and not all(p is not None and p.alive() for p in silent)):
                return

    # ---------------------------------------------------------------- run
    def _run_segment(self, n: int, target_index: int, tick: Callable[[], None] | None) -> None:
        if self.bus_loop is not None:
            self.bus_loop.arm()
        self.plant.sdo["Run control"]["run_periods"].raw = n
        if self.direct is not None:
            self.direct.run(n, tick)
        elif self.bus_loop is not None:
            self.bus_loop.run(target_index, tick)

    def _check_alive(self, index: int) -> None:
        if self.bus_loop is not None:
            self.bus_loop.check_alive(index)

    def run(self, progress: PROGRESS | None = None, tick: Callable[[], None] | None = None) -> float:
        """Run every period; `tick` is called between chunks (direct) or while waiting (bus)."""
        sc = self.sc
        if self.hil is None:
            self.bus_loop = BusLoop(self.plant, self.opts, self.liveness, self.kind.stall_s(self.opts.stall_s))
            self.net.subscribe(self.config.hold_cob, self.bus_loop.on_hold)
            self.kind.hear_also(self.net.bus, self.box, self.config.hold_cob)
        for n in (self.plant, self.drive):
            n.nmt.send_command(0x01)
        if self.liveness is not None:
            self.liveness.arm()
        bounds = [p for p in sc.event_periods() if p > 0] + [sc.periods]
        start = 0
        t0 = time.monotonic()
        events = {e.at_period: e for e in sc.events}
        for stop in bounds:
            try:
                if stop > start:
                    self._run_segment(stop - start, stop - 1, tick)
                    if tick and self.hil is None:
                        tick()  # over a bus: decode what the segment recorded (short segments never wait)
                self.config.period = stop
                if stop in events:
                    for s in events[stop].settings:
                        self.config.apply(s)
            except SdoCommunicationError:  # a node that stopped answering: named if it is lost
                self._check_alive(self.config.period - 1)
                self._check_box(self.config.period - 1)
                raise
            except can.CanError:  # the master's bridge port broke: the box ended?
                self._check_box(self.config.period - 1)
                raise
            start = stop
            if progress:
                progress(start, sc.periods)
        return time.monotonic() - t0

    def _check_box(self, index: int) -> None:
        """LoopStopped (node_lost, cause box_lost) when the run's CAN box no longer answers: both nodes, the
        recorder and the bus ended with it; what was recorded until then is kept."""
        why = self.box.gone() if self.box is not None else None
        if why is not None:
            raise LoopStopped(
                "node_lost",
                f"the CAN box ended during the run ({why}); both nodes ran in it. The next run starts a new box",
                at_period=index if index >= 0 else None,
                details={"cause": "box_lost"},
            ) from None

    def box_ended(self, failure: BaseException) -> dict[str, Any] | None:
        """When the run's CAN box ended (killed, crashed) while the run's processes started: the early stop it is
        (LoopStopped.to_dict(), node_lost, cause box_lost, with `failure`, what it made fail); None otherwise."""
        try:
            self._check_box(-1)
        except LoopStopped as stop:
            out = stop.to_dict()
            out["failed"] = str(failure)
            return out
        return None

    def fault_log(self) -> tuple[list[tuple[Any, ...]], int]:
        """The fault injector's actions (period, t_us, rule, kind, side, cob_id, data) and how many it could
        not log; after the run (direct: from the in-process injector; a bus: from the gateway's log)."""
        if self.hil is not None:
            return self.hil.fault_log()
        if self.gateway is not None:
            return self.gateway.events()
        return [], 0

    def statuses(self) -> dict[str, float]:
        """Counters and identified values, read by SDO (so they are in the log too)."""
        if self.liveness is not None:
            self.liveness.disarm()
        out: dict[str, float] = {}
        reads = (
            END_READS
            + ((REALTIME_READS,) if self.sc.timing == "realtime" else ())
            + ((STEP_COST,) if self.opts.drive == "mcu" else ())
        )
        for node_name, obj, names in reads:
            node = self.plant if node_name == "plant" else self.drive
            for name in names:
                out[f"{node_name}.{obj}.{name}"] = _read(node.sdo[obj][name])
        return out


def _read(var: SdoVariable, attempts: int = 3) -> Any:
    """An SDO read that survives a foreign frame on the SDO identifiers (a stray response taken for the
    answer): asked again, up to `attempts` times."""
    for i in range(attempts):
        try:
            return var.raw
        except (SdoCommunicationError, SdoAbortedError, struct.error):
            if i == attempts - 1:
                raise
            time.sleep(0.05)
    return None
