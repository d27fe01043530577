"""Which bus a run uses, chosen here and nowhere else (choose_bus: the one module that reads bus names; every other
module asks the chosen kind, bench/run/bus/kind.py), and whether this host, or the VM, can give the buses a run asks
for (--bus, --drive-bus): what is wrong is said with the fix (the bad option, what the machine has, the command that
would help)."""

from __future__ import annotations

import argparse
import re
from typing import Any

from bench.run.bus.kind import BusKind, SettingRefused
from bench.run.bus.kind_adapter import AdapterKind
from bench.run.bus.kind_box import CanBoxKind
from bench.run.bus.kind_direct import DirectKind
from bench.run.bus.kind_socketcan import HostSocketCanKind
from bench.run.options import RunOptions

DIRECT = "direct"  # --bus direct: libhil's in-process bus
SOCKETCAN = "socketcan"  # python-can's interface for the kernel's CAN (the default --interface)
VM_CAN = re.compile(r"can[0-3]")  # the emulated controllers the VM can supply
VCAN = re.compile(r"vcan\d{1,3}")


def choose_bus(
    bus: str,
    interface: str = SOCKETCAN,
    drive_bus: str | None = None,
    *,
    faults: bool = False,
    force_box: bool = False,
    box: bool = True,
) -> BusKind:
    """The kind of the bus `bus` (through python-can's `interface`; the drive on `drive_bus`): the direct bus, a
    python-can adapter, vcan buses in the CAN box (when `box` allows it and box_wanted says why), or SocketCAN on this
    host. `faults`: the scenario has [[faults]] (over SocketCAN the drive gets a bus of its own: drive_side)."""
    if bus == DIRECT:
        return DirectKind(bus, drive_bus)
    drive = drive_side(bus, drive_bus, faults)
    if interface != SOCKETCAN:
        return AdapterKind(bus, drive)
    names = tuple(dict.fromkeys((bus, drive)))
    why = box_wanted(names[0], names[1] if len(names) > 1 else None, force_box) if box else None
    if why is not None:
        return CanBoxKind(bus, drive, why)
    make = tuple(n for n in names if faults and VCAN.fullmatch(n))
    return HostSocketCanKind(bus, drive, make=make, virtual=bus.startswith("vcan"))


def bus_of(opts: RunOptions, faults: bool = False, box: bool = True) -> BusKind:
    """choose_bus for a run's options (its scenario has [[faults]]: `faults`; `box` False: never the CAN box, as for
    a Session made outside run_scenario, which leases none)."""
    return choose_bus(opts.bus, opts.interface, opts.drive_bus, faults=faults, force_box=opts.box, box=box)


def bus_of_args(args: Any) -> BusKind:
    """choose_bus for a command line's --bus, --interface, --drive-bus and --box (those it has)."""
    return choose_bus(
        args.bus,
        getattr(args, "interface", SOCKETCAN),
        getattr(args, "drive_bus", None),
        force_box=getattr(args, "box", False),
    )


def vm_links(names: tuple[str, ...]) -> tuple[tuple[str, ...], int]:
    """For a VM of the run's own (bench/run/vm_run.py): the interfaces it makes (vcanN) and how many emulated CAN
    controllers (Kvaser PCIcan, SJA1000) it gives on one emulated bus: as many as the highest canN asks."""
    cans = [int(n[3:]) for n in names if VM_CAN.fullmatch(n)]
    return tuple(n for n in names if not VM_CAN.fullmatch(n)), max(cans) + 1 if cans else 0


def drive_side(bus: str, drive_bus: str | None, faults: bool) -> str:
    """The drive's interface: --drive-bus, or with [[faults]] a bus of its own joined to the plant's by the fault
    gateway (vcanN -> vcanN+1 unless --drive-bus names another)."""
    if not faults:
        return drive_bus or bus
    name = drive_bus
    if name is None:
        m = re.fullmatch(r"vcan(\d+)", bus)
        if m is None:
            raise SettingRefused(
                f"[[faults]] over {bus}: name the drive's own bus with --drive-bus (the fault gateway joins two "
                "buses; on one bus every node hears every frame and nothing can be injected)"
            )
        name = f"vcan{int(m.group(1)) + 1}"
    if name == bus:
        raise SettingRefused(f"[[faults]]: --drive-bus {name} is the plant's bus; the fault gateway needs two buses")
    return name


def bus_problem(args: argparse.Namespace) -> tuple[str | None, bool]:
    """(what is wrong with --bus / --drive-bus, whether the VM supplies them)."""
    from bench.canbus import probe_af_can

    kind = choose_bus(args.bus, args.interface, args.drive_bus, box=False)  # the box is asked below, when it can be
    if args.drive_bus is not None:
        if kind.in_process:
            return "--drive-bus needs a CAN bus (--bus can0 --drive-bus can1); the direct bus has no interfaces", False
        if args.no_drive:
            return "--drive-bus names the drive node's interface; with --no-drive the bench starts no drive", False
    if getattr(args, "drive", "node") == "mcu":  # through the VM, whose serial port joins the image's UART
        problem = _mcu_problem(args, kind)
        if problem:
            return problem, False
        problem = _vm_problem(args, "--drive mcu runs in the VM (its serial port joins the image's UART)")
        return problem, problem is None
    if not kind.kernel_can:
        return None, False
    names = list(dict.fromkeys(n for n in (args.bus, args.drive_bus) if n))
    if box_wanted(args.bus, args.drive_bus, getattr(args, "box", False)):
        return None, False  # the CAN box (run_scenario leases it): every line of Python stays here
    if not probe_af_can().af_can:
        problem = _vm_problem(args, "this host's kernel has no SocketCAN")
        return problem, problem is None
    for n in names:
        problem = _host_link_problem(n, "--bus" if n == args.bus else "--drive-bus", args.bitrate)
        if problem:
            return problem, False
    return None, False


def _vm_problem(args: argparse.Namespace, why: str) -> str | None:
    """What the VM cannot supply of the buses asked for, or None."""
    names = list(dict.fromkeys(n for n in (args.bus, args.drive_bus) if n))
    bad = [n for n in names if not (VCAN.fullmatch(n) or VM_CAN.fullmatch(n))]
    if bad:
        opt = "--bus" if bad[0] == args.bus else "--drive-bus"
        return (
            f"{opt} {bad[0]}: {why}; the VM supplies virtual buses (vcan0, vcan1, ...) and emulated CAN "
            "controllers on one bus (can0 .. can3)" + ("" if "mcu" in why else ", or use --bus direct")
        )
    if len(names) == 2 and not all(VM_CAN.fullmatch(n) for n in names):
        return (
            f"--bus {args.bus} --drive-bus {args.drive_bus}: in the VM only the emulated controllers can0 .. can3 "
            "share one bus (vcan interfaces are separate buses)"
        )
    return None


def _host_link_problem(name: str, opt: str, bitrate: int | None) -> str | None:
    """What stops this user from running on the host's interface `name`, or None."""
    import os

    from bench.canbus import DEFAULT_BITRATE, RESTART_MS, can_interfaces, host_has_vcan, link_info

    if VCAN.fullmatch(name) and host_has_vcan(name):  # a vcan is made when missing (as root)
        return None
    info = link_info(name)
    cans = can_interfaces()
    buses = ", ".join(f"{n} ({s})" for n, s in cans) or "none"
    if info is None:
        return f"{opt} {name}: no such CAN interface; this machine has: {buses}; or use --bus direct or a vcan name"
    if name not in {n for n, _ in cans}:
        return f"{opt} {name}: a network interface, but not a CAN one; the CAN interfaces here: {buses}"
    if info["up"]:
        return None
    if info["kind"] != "can":
        return f"{opt} {name}: the interface is down (bring it up: ip link set {name} up)"
    if os.geteuid() != 0:  # the bench brings a controller up itself only with the rights to
        rate = bitrate or info.get("bitrate") or DEFAULT_BITRATE
        return (
            f"{opt} {name}: the CAN controller is down and configuring it needs root (CAP_NET_ADMIN): "
            f"sudo ip link set {name} type can bitrate {rate} restart-ms {RESTART_MS} && "
            f"sudo ip link set {name} up; or run the bench as root (it does this itself)"
        )
    return None


def _mcu_problem(args: argparse.Namespace, kind: BusKind) -> str | None:
    """What stops `--drive mcu` (the Cortex-M4F image over SLCAN) here, or None."""
    import shutil

    from bench.eds import default_node_id

    if not kind.kernel_can:
        return "--drive mcu reaches the image over a SocketCAN bus: use --bus vcan0 (or can0 --drive-bus can1)"
    if getattr(args, "no_drive", False):
        return "--drive mcu starts the drive image; with --no-drive the bench starts no drive"
    node_id = default_node_id("drive")
    if args.drive_id != node_id:
        return f"--drive mcu: the image is node 0x{node_id:02X} (drive.eds), not --drive-id 0x{args.drive_id:02X}"
    for tool, pkg in (("qemu-system-arm", "qemu-system-arm"), ("arm-none-eabi-gcc", "gcc-arm-none-eabi")):
        if shutil.which(tool) is None:
            return f"--drive mcu needs {tool}: apt-get install {pkg} (or make setup)"
    return None


def box_reason(bus: str, drive_bus: str | None = None, force: bool = False) -> str | None:
    """Why a run on these vcan buses goes through the CAN box (bench/run/bus/box), or None when the host's
    own kernel carries them. Only vcan buses go to the box; the emulated controllers (can0 ..) and --drive
    mcu boot a VM of their own (bench/run/vm_run.py)."""
    import os

    from bench.canbus import host_has_vcan, probe_af_can

    names = [n for n in (bus, drive_bus) if n]
    if not names or not all(VCAN.fullmatch(n) for n in names):
        return None
    if force or os.environ.get("BENCH_BOX") == "1":
        return "asked for (--box or BENCH_BOX=1)"
    probe = probe_af_can()
    if not probe.af_can:
        return f"this host's kernel has no SocketCAN ({probe.detail})"
    missing = [n for n in names if not host_has_vcan(n)]
    if missing:
        return (
            f"SocketCAN works here but {missing[0]} cannot be made (no vcan module, or no CAP_NET_ADMIN: "
            "a container without --cap-add NET_ADMIN)"
        )
    return None


def box_wanted(bus: str, drive_bus: str | None = None, force: bool = False) -> str | None:
    """Why this run's vcan buses go to the CAN box, or None: asked for (--box, BENCH_BOX=1), or the host cannot
    carry them (box_reason). BENCH_BOX=0 keeps the older way, a VM of its own per run (bench/run/vm_run.py)."""
    import os

    if os.environ.get("BENCH_BOX") == "0" and not force:
        return None
    return box_reason(bus, drive_bus, force)
