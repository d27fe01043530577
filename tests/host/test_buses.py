"""What `bench run` says about the buses asked for (--bus, --drive-bus) before anything starts: the bad
option, what this machine (or its VM) has, and the fix. The runs themselves: tests/can."""

from __future__ import annotations

import argparse

import pytest

from bench.canbus import probe_af_can
from bench.run.bus.buses import box_reason, bus_problem
from bench.run.vm_run import vm_options

HOST_CAN = probe_af_can().af_can


def _args(bus: str, drive_bus: str | None = None, no_drive: bool = False) -> argparse.Namespace:
    return argparse.Namespace(bus=bus, drive_bus=drive_bus, no_drive=no_drive, interface="socketcan", bitrate=None)


@pytest.mark.parametrize(
    "args,needle",
    [
        (_args("direct", "can1"), "--drive-bus needs a CAN bus"),
        (_args("can0", "can1", no_drive=True), "with --no-drive the bench starts no drive"),
        (_args("can9") if not HOST_CAN else _args("nosuchcan9"), "can9"),
    ],
)
def test_a_bus_that_cannot_be_had_is_named(args: argparse.Namespace, needle: str) -> None:
    problem, in_vm = bus_problem(args)
    assert problem is not None and needle in problem, problem
    assert not in_vm


def test_the_box_supplies_vcan_buses_and_a_vm_emulated_controllers_on_one_bus(monkeypatch: pytest.MonkeyPatch) -> None:
    """vcan buses: the CAN box where the host cannot carry them (the run itself stays here: in_vm False), a
    VM per run with BENCH_BOX=0; can0/can1: a VM of their own."""
    assert box_reason("vcan0", force=True) is not None and box_reason("can0", force=True) is None
    if HOST_CAN:  # the host's own interfaces are used: nothing to ask of the VM
        assert bus_problem(_args("direct")) == (None, False)
        return
    assert "no SocketCAN" in (box_reason("vcan0") or "")
    assert bus_problem(_args("vcan0")) == (None, False)  # the CAN box: the run stays here
    monkeypatch.setenv("BENCH_BOX", "0")  # the older way: a VM per run
    assert bus_problem(_args("vcan0")) == (None, True)
    monkeypatch.delenv("BENCH_BOX")
    assert bus_problem(_args("can0", "can1")) == (None, True)
    problem, _ = bus_problem(_args("vcan0", "can1"))
    assert problem is not None and "share one bus" in problem
    opts = vm_options(_args("can0", "can1"))
    assert opts.can_controllers == 2 and opts.interfaces == ()
    assert vm_options(_args("vcan1")).interfaces == ("vcan1",) and vm_options(_args("vcan1")).can_controllers == 0


@pytest.mark.parametrize("bus,interface", [("direct", "socketcan"), ("can0", "pcan")])
def test_the_mcu_image_needs_a_kernels_can_bus(bus: str, interface: str) -> None:
    """--drive mcu joins the image's UART to a SocketCAN bus: not the direct bus, not a python-can adapter's."""
    args = _args(bus)
    args.interface, args.drive, args.drive_id = interface, "mcu", 0x20
    problem, in_vm = bus_problem(args)
    assert problem is not None and "over a SocketCAN bus" in problem and not in_vm
