"""The CANopen master of a run: the part of `bench run` that talks to the nodes. Works the
same over SocketCAN (vcan0, can0) and in direct mode (in-process).

Sequence: node processes up -> NMT reset -> configuration by SDO from the EDS names (preset,
model, controller with its mismatch, PDO wiring, trace PDOs) -> NMT start -> run the periods
between events in lockstep ("run N periods then hold" object of the plant), applying each
event's SDO writes at its exact period -> read the statuses -> NMT pre-operational. Every
frame of it is on the bus, where the recorder (bench/run/record/sources.py) takes it: the session
returns nothing the frames do not also say (bench/run/decode/sdo_log.py reads it back from them).
"""

from __future__ import annotations

import re
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench.canbus import ensure_vcan, link_info, prepare_can_link
from bench.run.bus.buses import VCAN
from bench.run.bus.cpus import PlantCpu, plant_cpu
from bench.run.bus.direct import DirectBus, Hil, probe_host_floor
from bench.run.bus.direct_sdo import DirectSdo
from bench.run.bus.gateway import FaultGateway
from bench.run.bus.liveness import STARVED_S, Liveness, LoopStopped
from bench.run.bus.nodes import NodeProcess
from bench.run.bus.slcan_bridge import SlcanBridge
from bench.run.loop import master
from bench.run.loop.bus_loop import BusLoop
from bench.run.loop.configure import Configurator, SettingRefused
from bench.run.loop.direct_loop import DirectLoop
from bench.run.loop.reads import END_READS, REALTIME_READS, STEP_COST
from bench.run.options import MCU_STALL_S, RunOptions
from bench.scenario import Scenario
from bench.scenario.faults import rules_text

PROGRESS = Callable[[int, int], None]


class Session:
    """The master of one run, made of parts: the nodes (processes, or libhil's in direct mode), the canopen
    network, a Configurator (the SDO configuration), the loop driver (DirectLoop in process, lockstep
    segments over a bus) and the Liveness watch."""

    def __init__(self, sc: Scenario, opts: RunOptions) -> None:
        self.sc = sc
        self.opts = opts
        self.hil: Hil | None = None
        self.procs: list[NodeProcess | SlcanBridge] = []
        self.node_procs: dict[str, NodeProcess | SlcanBridge] = {}  # over a bus: the processes by node
        # the master's Network and RemoteNodes (bench/run/loop/master.py): in direct mode kept between runs
        direct = opts.bus == "direct"
        self.master = (master.take if direct else master.new_master)(opts.plant_id, opts.drive_id)
        self._kept = direct  # given back at close
        self.net, self.plant, self.drive = self.master.net, self.master.plant, self.master.drive
        self.config = Configurator(sc, opts, self.plant, self.drive)
        self.direct: DirectLoop | None = None  # direct mode: the in-process loop (its on_chunk, on_stop)
        self.kernel_filters: list[dict[str, int]] | None = None
        self.bus_loop: BusLoop | None = None  # over a bus: the lockstep segments (run())
        self.liveness: Liveness | None = None
        self.gateway: FaultGateway | None = None  # the fault injector between the buses (faults over SocketCAN)
        # each SocketCAN interface of the run: what the kernel reports of it before and after (canbus.link_info)
        self.links: dict[str, dict[str, Any]] = {}
        # the run's share of the CAN box (bench/run/bus/box/lease.py) when its buses are in the box: the node
        # processes, the gateway and the recorder run there, the master here over the slot's SLCAN port
        self.box: Any = None
        self.plant_cpu: PlantCpu | None = None  # real time over this host's SocketCAN (hold_plant_cpu)
        self.floor: dict[str, float] | None = None  # the host's floor, probed by hold_plant_cpu

    # ---------------------------------------------------------------- bus
    def drive_side_bus(self) -> str:
        """The drive's interface: --drive-bus, or with [[faults]] over SocketCAN a bus of its own joined to
        the plant's by the fault gateway (vcanN -> vcanN+1 unless --drive-bus names another)."""
        if not self.sc.faults or self.opts.bus == "direct":
            return self.opts.drive_bus or self.opts.bus
        name = self.opts.drive_bus
        if name is None:
            m = re.fullmatch(r"vcan(\d+)", self.opts.bus)
            if m is None:
                raise SettingRefused(
                    f"[[faults]] over {self.opts.bus}: name the drive's own bus with --drive-bus (the fault gateway "
                    "joins two buses; on one bus every node hears every frame and nothing can be injected)"
                )
            name = f"vcan{int(m.group(1)) + 1}"
        if name == self.opts.bus:
            raise SettingRefused(
                f"[[faults]]: --drive-bus {name} is the plant's bus; the fault gateway needs two buses"
            )
        return name

    def _check_node_faults(self) -> None:
        """Over a bus the gateway freezes and kills node processes the bench started (their PIDs): a fault on a
        node it did not start (--no-drive, a physical drive, the MCU image) is refused before anything starts."""
        if self.opts.interface != "socketcan" and self.sc.faults:
            raise SettingRefused("[[faults]] need SocketCAN (the fault gateway joins two SocketCAN interfaces)")
        ours = {"plant": self.opts.start_plant, "drive": self.opts.start_drive and self.opts.drive == "node"}
        for f in self.sc.faults:
            if f.kind in ("freeze", "kill") and f.node is not None and not ours[f.node]:
                raise SettingRefused(
                    f"faults[{f.index}]: {f.kind} the {f.node}: over a bus the fault gateway stops or kills the "
                    f"{f.node}'s process, and this run does not start one (a physical node, --no-{f.node} or "
                    "--drive mcu); use reset or silence_heartbeat"
                )

    def prepare_links(self) -> None:
        """CAN controllers up at their bit rate (canbus.prepare_can_link), their state before the run noted;
        before anything listens on them (the recorder). Once per session."""
        if self.links or self.opts.bus == "direct" or self.opts.interface != "socketcan":
            return
        if self.box is not None:  # in the run's namespace of the box
            infos = self.box.link_infos(list(dict.fromkeys((self.opts.bus, self.drive_side_bus()))))
            self.links.update({name: {"before": info} for name, info in infos.items()})
            return
        for name in dict.fromkeys((self.opts.bus, self.drive_side_bus())):
            if VCAN.fullmatch(name) and self.sc.faults:
                ensure_vcan(name)
            prepare_can_link(name, self.opts.bitrate)
            self.links[name] = {"before": link_info(name)}

    def open(self) -> None:
        if self.opts.bus == "direct":
            self.hil = Hil(self.opts.plant_id, self.opts.drive_id)
            if self.sc.faults:
                self.hil.set_faults(rules_text(self.sc.faults, self.opts.plant_id, self.opts.drive_id))
            self.net.bus = DirectBus(self.hil)
            self.direct = DirectLoop(self.hil, self.opts, realtime=self.sc.timing == "realtime")
        else:
            self._open_bus()
        if isinstance(self.net.bus, DirectBus):
            # The nodes' answers go to the master's listeners on the sending thread (DirectBus.attach): no
            # notifier thread to start and stop per run (what canopen's connect() would do), nothing to poll.
            self.net.bus.attach(self.net.listeners)
        else:
            self.net.connect()
        for n in (self.plant, self.drive):  # added and subscribed by master.new_master
            n.sdo.RESPONSE_TIMEOUT = MCU_STALL_S if n is self.drive and self.opts.drive == "mcu" else 5.0
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

    def _open_bus(self) -> None:
        """Over SocketCAN (or another python-can interface): the node processes (or the MCU image's serial
        bridge), the fault gateway between two buses, and the master's own bus with kernel filters."""
        out = self.opts.out

        def log(name: str) -> Path | None:
            return None if out is None else out / f"{name}.out"

        drive_bus = self.drive_side_bus()
        self._check_node_faults()
        self.prepare_links()
        if self.opts.start_plant:
            # real time on this host's SocketCAN: the plant's CPU kept out of its halt (issue 40; hold_plant_cpu
            # moves what else runs here off it); not in the CAN box, whose emulated CPUs a busy loop would take whole
            awake = ["--keep-awake"] if self._plant_here_in_real_time() else []
            self.node_procs["plant"] = NodeProcess(
                "plant_node",
                ["--iface", self.opts.bus, "--node-id", str(self.opts.plant_id), *awake],
                log("plant_node"),
                box=self.box,
            )
        if self.opts.start_drive and self.opts.drive == "mcu":
            if self.opts.drive_tty is None:
                raise ValueError("RunOptions.drive = 'mcu' needs drive_tty (the image's serial line)")
            self.node_procs["drive"] = SlcanBridge(self.opts.drive_tty, drive_bus, log=log("slcand"))
        elif self.opts.start_drive:
            self.node_procs["drive"] = NodeProcess(
                "drive_node",
                ["--iface", drive_bus, "--node-id", str(self.opts.drive_id)],
                log("drive_node"),
                box=self.box,
            )
        for proc in self.node_procs.values():
            self.procs.append(proc.start())
        if self.sc.faults:
            pids = {n: p.proc.pid for n, p in self.node_procs.items() if isinstance(p, NodeProcess) and p.proc}
            if out is None:
                raise ValueError("a run with [[faults]] over SocketCAN needs opts.out (the gateway's rules and log)")
            rules = rules_text(self.sc.faults, self.opts.plant_id, self.opts.drive_id)
            self.gateway = FaultGateway(rules, self.opts.bus, drive_bus, out, pids, box=self.box).start()
        if self.box is not None:
            # the slot's SLCAN port (python-can's slcan interface): the box passes it SDO answers and heartbeats
            # only (box/life.py MASTER_IDS), and the hold announcement once configured (run())
            self.net.bus = can.Bus(interface="slcan", channel=self.box.master_channel, sleep_after_open=0)
            self.net.listeners.append(_BridgeErrors())  # a box that ends breaks the port: judged in run()
            return
        # The master only needs its nodes' SDO answers and heartbeats: filtering in the kernel keeps the
        # PDO stream (thousands of frames per second) out of this process's socket, which a slow Python
        # (the VM) could not drain, and which the recorder records anyway. EMCYs stay out too: a node
        # may send hundreds a second (one per foreign SYNC), which left the master's notifier seconds
        # behind in the VM (heartbeats and SDO answers queued behind them: a live node taken for lost);
        # the decoder lists every EMCY from the record, and the heartbeats judge liveness.
        ids = (self.opts.plant_id, self.opts.drive_id)
        filters = [{"can_id": 0x580 + i, "can_mask": 0x7FF} for i in ids]
        filters += [{"can_id": 0x700 + i, "can_mask": 0x7FF} for i in ids]
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

    def _plant_here_in_real_time(self) -> bool:
        return self.sc.timing == "realtime" and self.box is None and self.hil is None and self.opts.start_plant

    def hold_plant_cpu(self) -> None:
        """Real time with plant_node on this host, once configured: the host's floor probed at the plant's period on
        the plant's CPU (printed, a warning when it makes Ts impossible; summary.json realtime.floor), then the
        bench's threads and the processes it started here but the plant (candump, drive_node, the gateway) leave
        that CPU for the run (bench/run/bus/cpus.py; back at close())."""
        plant = self.node_procs.get("plant")
        cpu = plant_cpu()
        if not self._plant_here_in_real_time() or not isinstance(plant, NodeProcess) or cpu is None:
            return
        from bench.run.loop.direct_loop import floor_line

        ts_s = float(self.plant.sdo["Inverter"]["Ts_s"].raw)
        try:
            self.floor = probe_host_floor(round(ts_s * 1e9))
        except OSError:  # no libhil.so (a build without it): the run goes on without its floor
            self.floor = None
        if self.floor is not None:
            print(floor_line(self.floor), flush=True)
        self.plant_cpu = PlantCpu(cpu)
        self.plant_cpu.reserve()
        self.plant_cpu.isolate(spare=frozenset({int(plant.proc.pid)}))  # candump, drive_node, the gateway, ...
        print(f"bench run: the plant's CPU kept for the run: {self.plant_cpu.summary()}", flush=True)

    def close(self) -> None:
        if self.plant_cpu is not None:
            self.plant_cpu.release()
            self.plant_cpu = None
        if self.liveness is not None:
            self.liveness.disarm()
            self.liveness.close()
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
            if self._kept:  # once: a second close gives nothing back
                self._kept = False
                master.give_back(self.master)
            for p in self.procs:
                p.stop()
            if self.gateway is not None:
                self.gateway.stop()  # after the nodes: it writes its log of actions
            after = self.box.link_infos(list(self.links)) if self.box is not None and self.links else {}
            for name, rec in self.links.items():
                rec["after"] = after[name] if self.box is not None else link_info(name)

    def configure(self) -> None:
        self.config.configure()

    def linger(self) -> None:
        """After a lost node: let the survivor's reaction happen and be recorded (its heartbeat consumer
        fires after the consumer time): the consumer time plus a margin, simulated in direct mode."""
        wait = self.opts.heartbeat_timeout_ms / 1000.0 + 0.3
        if self.hil is not None:
            self.hil.linger(wait)  # its frames go with the final drain of the recorder
        else:
            time.sleep(wait)

    # ---------------------------------------------------------------- NMT
    def reset_nodes(self) -> None:
        booted: dict[int, bool] = {}
        all_booted = threading.Event()  # set by the notifier (a bus) or at once (direct): no polling delay

        def on_boot(cob_id: int, data: bytearray, ts: float) -> None:
            if len(data) == 1 and data[0] == 0:
                booted[cob_id - 0x700] = True
                if all(booted.get(n.id) for n in (self.plant, self.drive)):
                    all_booted.set()

        for n in (self.plant, self.drive):
            self.net.subscribe(0x700 + n.id, on_boot)
        deadline = time.monotonic() + 10
        # Nodes just started announce themselves; a reset node announces again.
        for n in (self.plant, self.drive):
            n.nmt.send_command(0x81)
        all_booted.wait(timeout=max(0.0, deadline - time.monotonic()))
        for n in (self.plant, self.drive):
            self.net.unsubscribe(0x700 + n.id, on_boot)
            if not booted.get(n.id):
                raise RuntimeError(
                    f"node 0x{n.id:02X} did not answer the NMT reset with a boot-up message "
                    f"(is it on bus {self.opts.bus}?)"
                )

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
            self.bus_loop = BusLoop(self.plant, self.opts, self.liveness)
            self.net.subscribe(self.config.hold_cob, self.bus_loop.on_hold)
            if self.kernel_filters is not None:
                self.net.bus.set_filters([*self.kernel_filters, {"can_id": self.config.hold_cob, "can_mask": 0x7FF}])
            elif self.box is not None:
                self.box.add_master_ids([(self.config.hold_cob, 0x7FF)])
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


class _BridgeErrors(can.Listener):
    """Takes the errors of the master's SLCAN bridge port (python-can's notifier thread would print a traceback
    for each): a port that breaks ends the run through Session._check_box."""

    def __init__(self) -> None:
        self.errors: list[Exception] = []

    def on_message_received(self, msg: can.Message) -> None:
        pass

    def on_error(self, exc: Exception) -> None:
        self.errors.append(exc)


def _read(var, attempts: int = 3):  # type: ignore[no-untyped-def]
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
