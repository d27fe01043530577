"""One bus interface (issue 53): a run's kind of bus is chosen in one place (bench/run/bus/buses.py choose_bus) and
asked everywhere else (bench/run/bus/kind.py BusKind). The bench's sources compare no bus name outside the chooser,
read here from the files, so that a new comparison fails; and the chooser gives each kind for its options."""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import pytest

from bench.paths import REPO
from bench.run.bus.buses import choose_bus
from bench.run.bus.kind import BusKind, SettingRefused
from bench.run.bus.kind_adapter import AdapterKind
from bench.run.bus.kind_box import CanBoxKind
from bench.run.bus.kind_direct import DirectKind
from bench.run.bus.kind_socketcan import HostSocketCanKind

BENCH = REPO / "bench"
CHOOSER = BENCH / "run" / "bus" / "buses.py"  # the one module that reads bus names
KIND_NAMES = {"direct", "socketcan"}  # the values of --bus / --interface that name a kind rather than a channel
NAME_PREFIX = re.compile(r"^\^?(v|sl)?can")  # a test of a channel's name: startswith("vcan"), r"vcan(\d+)", ...


def _literals(node: ast.AST) -> list[str]:
    """The string constants of an expression: itself, or the elements of a tuple, list or set."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return [s for e in node.elts for s in _literals(e)]
    return []


def name_comparisons(source: str, filename: str = "<source>") -> list[int]:
    """The lines of `source` that tell a kind of bus by its name: a comparison (==, !=, in, not in) with "direct" or
    "socketcan", a prefix test of a name (startswith("vcan"), "can"), or a regular expression over CAN names."""
    lines = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(s in KIND_NAMES for side in sides for s in _literals(side)):
                lines.append(node.lineno)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.args:
            attr, arg = node.func.attr, node.args[0]
            if attr in ("startswith", "endswith") and any(NAME_PREFIX.match(s) for s in _literals(arg)):
                lines.append(node.lineno)
            elif attr in ("match", "fullmatch", "search", "compile") and any(
                NAME_PREFIX.match(s) for s in _literals(arg)
            ):
                lines.append(node.lineno)
    return sorted(set(lines))


def _bench_files() -> list[Path]:
    return sorted(p for p in BENCH.rglob("*.py") if "__pycache__" not in p.parts)


def test_the_rule_finds_what_it_forbids() -> None:
    src = (
        'if opts.bus == "direct":\n    pass\n'
        'ok = args.interface != "socketcan"\n'
        'x = bus in ("direct", "vcan0")\n'
        'y = bus.startswith("vcan")\n'
        'm = re.fullmatch(r"vcan(\\d+)", bus)\n'
        'fine = kind.in_process and bus == "vcan0" and drive == "mcu"\n'
    )
    assert name_comparisons(src) == [1, 3, 4, 5, 6]


def test_no_bus_name_is_compared_outside_the_chooser() -> None:
    found = [
        f"{p.relative_to(REPO)}:{n}: {p.read_text().splitlines()[n - 1].strip()}"
        for p in _bench_files()
        if p != CHOOSER
        for n in name_comparisons(p.read_text(), str(p))
    ]
    assert not found, "ask the chosen BusKind (bench/run/bus/kind.py) instead:\n" + "\n".join(found)


def test_the_chooser_reads_the_names() -> None:
    """The rule's exception is where the names are read: the chooser has them (else the rule reads nothing)."""
    assert name_comparisons(CHOOSER.read_text()), "bench/run/bus/buses.py no longer chooses by name: move the rule"


def test_every_kind_is_a_bus_kind_the_chooser_can_give(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BENCH_BOX", raising=False)
    kinds = {
        type(choose_bus("direct")),
        type(choose_bus("can0", "pcan")),
        type(choose_bus("vcan0", force_box=True)),
        type(choose_bus("vcan0", box=False)),
    }
    assert kinds == {DirectKind, AdapterKind, CanBoxKind, HostSocketCanKind}
    assert {c for c in BusKind.__subclasses__()} == kinds  # no kind the chooser cannot reach


def test_the_chooser_gives_the_box_vcan_buses_only(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BENCH_BOX", "0")  # the box only when asked for: this host's kernel is not probed
    assert isinstance(choose_bus("vcan0"), HostSocketCanKind)
    box = choose_bus("vcan3", force_box=True)
    assert isinstance(box, CanBoxKind) and box.box_why() and box.names == ("vcan3",)
    assert isinstance(choose_bus("can0", force_box=True), HostSocketCanKind)  # a controller: the VM's, not the box's
    assert isinstance(choose_bus("vcan0", "kvaser", force_box=True), AdapterKind)  # an adapter's channel, not a vcan
    assert choose_bus("vcan0", box=False).box_why() is None


def test_with_faults_the_drive_gets_a_bus_of_its_own() -> None:
    host = choose_bus("vcan4", faults=True, box=False)
    assert isinstance(host, HostSocketCanKind)
    assert (host.bus, host.drive_bus, host.names) == ("vcan4", "vcan5", ("vcan4", "vcan5"))
    assert set(host.make) == {"vcan4", "vcan5"}  # made when missing, as the fault gateway needs both
    assert choose_bus("vcan4", box=False).names == ("vcan4",)
    assert choose_bus("can0", drive_bus="can1", faults=True, box=False).drive_bus == "can1"
    with pytest.raises(SettingRefused, match="--drive-bus"):
        choose_bus("can0", faults=True, box=False)  # no second bus to join the plant's to
    with pytest.raises(SettingRefused, match="the plant's bus"):
        choose_bus("vcan0", drive_bus="vcan0", faults=True, box=False)
    assert choose_bus("direct", faults=True).faults_refusal() is None  # libhil's injector
    assert choose_bus("can0", "pcan", drive_bus="can1", faults=True).faults_refusal() is not None


class _Recorders:
    """bench.run.bus.kind.Recorders that notes which source a kind asked for."""

    def __init__(self) -> None:
        self.asked: list[tuple[str, Any]] = []

    def candump(self, bus: str) -> Any:
        self.asked.append(("candump", bus))
        return object()

    def box_candump(self, bus: str) -> Any:
        self.asked.append(("box_candump", bus))
        return object()

    def in_process(self) -> Any:
        self.asked.append(("in_process", None))
        return object()

    def listener(self) -> Any:
        self.asked.append(("listener", None))
        return object()


@pytest.mark.parametrize(
    "kind",
    [DirectKind("direct"), HostSocketCanKind("vcan0"), CanBoxKind("vcan0", None, "asked for"), AdapterKind("can0")],
)
def test_each_kind_names_one_recorder_at_one_moment(kind: BusKind) -> None:
    """Exactly one source per run: candump before the nodes start (a kernel's CAN: it hears the first frames), else
    the in-process bus's frames or a listener once the bus is open; what writes bus.log follows from it."""
    before, after = _Recorders(), _Recorders()
    got = (kind.recorder(before, opened=False), kind.recorder(after, opened=True))
    assert sum(g is not None for g in got) == 1 and len(before.asked) + len(after.asked) == 1
    asked = (before.asked or after.asked)[0][0]
    assert (asked in ("candump", "box_candump")) == kind.kernel_can == (got[0] is not None)
    assert kind.log_from_frames == (asked == "in_process")  # candump's own log is the log of a kernel's CAN


@pytest.mark.parametrize("bus,drive_bus", [("can0", "can1"), ("vcan1", None), ("can2", None), ("vcan0", "vcan3")])
def test_the_vm_links_are_the_vm_runs(bus: str, drive_bus: str | None) -> None:
    """buses.vm_links gives a VM of the run's own what bench/run/vm_run.py's vm_options gives it (which may then ask
    the chooser's module instead of matching the names itself)."""
    import argparse

    from bench.run.bus.buses import vm_links
    from bench.run.vm_run import vm_options

    vm = vm_options(argparse.Namespace(bus=bus, drive_bus=drive_bus))
    assert vm_links(tuple(dict.fromkeys(n for n in (bus, drive_bus) if n))) == (vm.interfaces, vm.can_controllers)


def test_a_python_can_adapters_run_is_the_masters_bus_and_its_listener(tmp_path: Path) -> None:
    """The adapter kind over python-can's virtual interface (an adapter with no hardware): the master's bus is on the
    run's channel (what it sends reaches a peer there), the run notes no kernel links, and the recorder is a listener
    on the master's bus that takes what the peer sends. No node is started (a physical plant and drive would be)."""
    import time

    import can

    from bench.run.loop.session import Session
    from bench.run.options import RunOptions
    from bench.run.recorder import RunRecorders
    from bench.scenario import load

    channel = f"bus-kinds-{id(tmp_path)}"
    opts = RunOptions(bus=channel, interface="virtual", start_plant=False, start_drive=False, out=tmp_path)
    sc = load(REPO / "tests" / "scenarios" / "parity.toml")
    sess = Session(sc, opts, choose_bus(channel, "virtual"))
    peer = can.Bus(interface="virtual", channel=channel)
    try:
        assert sess.kind.recorder(RunRecorders(sess), opened=False) is None  # nothing to start before the bus
        sess.open()
        source = sess.kind.recorder(RunRecorders(sess), opened=True)
        assert source is not None and sess.links == {}
        sess.plant.nmt.send_command(0x81)
        got = peer.recv(2.0)
        assert got is not None and (got.arbitration_id, bytes(got.data)) == (0x000, bytes([0x81, opts.plant_id]))
        peer.send(can.Message(arbitration_id=0x123, data=b"\x01\x02", is_extended_id=False))
        frames: list[Any] = []
        for _ in range(100):
            frames += list(source.drain())
            if frames:
                break
            time.sleep(0.02)
        assert [int(f["cob_id"]) for f in frames].count(0x123) == 1
    finally:
        sess.close()
        peer.shutdown()
