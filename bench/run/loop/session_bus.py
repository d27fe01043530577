"""The nodes and buses of a run's master (SessionBus, the base of Session in bench/run/loop/session.py): the CAN
links brought up and their state noted before and after, the node processes (or the MCU image's serial bridge) and
the fault gateway started and stopped, the master's own bus, and the plant's CPU kept for a real-time run on this
host. What differs between kinds of bus (the drive's side, the links, the master's bus and its filters) the run's
BusKind answers (bench/run/bus/kind.py)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import canopen

from bench.run.bus.cpus import PlantCpu, plant_cpu
from bench.run.bus.direct import Hil, probe_host_floor
from bench.run.bus.gateway import FaultGateway
from bench.run.bus.kind import BusKind, SettingRefused
from bench.run.bus.nodes import NodeProcess
from bench.run.bus.slcan_bridge import SlcanBridge
from bench.run.options import RunOptions
from bench.scenario import Scenario
from bench.scenario.faults import rules_text


class SessionBus:
    """The nodes and buses of one run: what Session.open starts over a bus and Session.close stops. What differs
    from one kind of bus to another the run's BusKind says (bench/run/bus/kind.py), chosen once (buses.choose_bus)."""

    def __init__(
        self, sc: Scenario, opts: RunOptions, net: canopen.Network, plant: canopen.RemoteNode, kind: BusKind
    ) -> None:
        self.sc = sc
        self.opts = opts
        self.kind = kind
        self.net, self.plant = net, plant
        self.hil: Hil | None = None
        self.procs: list[NodeProcess | SlcanBridge] = []
        self.node_procs: dict[str, NodeProcess | SlcanBridge] = {}  # over a bus: the processes by node
        self.gateway: FaultGateway | None = None  # the fault injector between the buses (faults over SocketCAN)
        # each SocketCAN interface of the run: what the kernel reports of it before and after (canbus.link_info)
        self.links: dict[str, dict[str, Any]] = {}
        # the run's share of the CAN box (bench/run/bus/box/lease.py) when its buses are in the box: the node
        # processes, the gateway and the recorder run there, the master here over the slot's SLCAN port
        self.box: Any = None
        self.plant_cpu: PlantCpu | None = None  # real time over this host's SocketCAN (hold_plant_cpu)
        self.floor: dict[str, float] | None = None  # the host's floor, probed by hold_plant_cpu

    def _check_node_faults(self) -> None:
        """Over a bus the gateway freezes and kills node processes the bench started (their PIDs): a fault on a
        node it did not start (--no-drive, a physical drive, the MCU image) is refused before anything starts."""
        refusal = self.kind.faults_refusal() if self.sc.faults else None
        if refusal is not None:
            raise SettingRefused(refusal)
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
        if self.links or not self.kind.kernel_can:
            return
        infos = self.kind.prepare_links(self.box, self.opts.bitrate)
        self.links.update({name: {"before": info} for name, info in infos.items()})
        if self.sc.frames.fd:
            self._check_fd_links(infos)

    def _check_fd_links(self, infos: dict[str, dict[str, Any] | None]) -> None:
        """A scenario with CAN FD PDOs (frames.can = "fd") needs links that carry CAN FD frames (MTU 72): refused
        before the nodes start, naming the link and how to set it."""
        for name, info in infos.items():
            mtu = None if info is None else info.get("mtu")
            if mtu is not None and int(mtu) < 72:
                fix = (
                    "`bench box down`: the next run boots the CAN box with CAN FD links"
                    if self.box is not None
                    else f"`ip link set {name} down && ip link set {name} mtu 72 up` (vcan)"
                    if (info or {}).get("kind") == "vcan"
                    else f"`ip link set {name} down && ip link set {name} type can bitrate B dbitrate D fd on && "
                    f"ip link set {name} up`"
                )
                raise SettingRefused(
                    f"frames.can = 'fd': {name} carries classic CAN frames only (MTU {mtu}); CAN FD needs MTU 72: {fix}"
                )

    def _open_bus(self) -> None:
        """Over SocketCAN (or another python-can interface): the node processes (or the MCU image's serial
        bridge), the fault gateway between two buses, and the master's own bus (BusKind.master_bus)."""
        out = self.opts.out

        def log(name: str) -> Path | None:
            return None if out is None else out / f"{name}.out"

        drive_bus = self.kind.drive_bus
        self._check_node_faults()
        if self.sc.frames.fd and self.opts.start_drive and self.opts.drive == "mcu":
            raise SettingRefused(
                "frames.can = 'fd': the Cortex-M4F image (--drive mcu) keeps classic CAN frames (its frames hold 8 "
                "bytes and its link is SLCAN, a classic protocol): run it with frames.can = 'classic'"
            )
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
            rules = rules_text(self.sc.faults, self.opts.plant_id, self.opts.drive_id, self.sc.frames.sync_less)
            self.gateway = FaultGateway(rules, self.opts.bus, drive_bus, out, pids, box=self.box).start()
        # a python-can adapter's bus opened for CAN FD frames when the scenario's PDOs are (the caller's options kept)
        opts = replace(self.opts, fd=True) if self.sc.frames.fd and not self.opts.fd else self.opts
        self.net.bus = self.kind.master_bus(opts, self.box)
        self.net.listeners.extend(self.kind.master_listeners())

    def _plant_here_in_real_time(self) -> bool:
        return self.sc.timing == "realtime" and self.kind.nodes_here and self.opts.start_plant

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

    def _stop_nodes(self) -> None:
        """The node processes and the fault gateway stopped, and the links' state after the run noted (close())."""
        # together where that saves requests (the CAN box), then each its own stop (its log closed); 5 s: stop's own
        self.kind.end_processes([p.proc for p in self.procs if isinstance(p, NodeProcess) and p.proc], 5.0)
        for p in self.procs:
            p.stop()
        if self.gateway is not None:
            self.gateway.stop()  # after the nodes: it writes its log of actions
        after = self.kind.link_infos(self.box, list(self.links)) if self.links else {}
        for name, rec in self.links.items():
            rec["after"] = after[name]
