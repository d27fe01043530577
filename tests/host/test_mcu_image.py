"""The drive firmware as a Cortex-M4F image (build/mcu/drive_mcu.elf, `make mcu`) under QEMU mps2-an386.

No CAN interface is needed: the image speaks SLCAN on its UART0, which QEMU puts on a local TCP port,
and python-can's `slcan` interface opens it (socket://127.0.0.1:PORT).  With `canopen` as the master
the test reads the identity by SDO, writes and reads back a configuration entry, starts the node, and
plays the plant: measurement frames on the drive's RPDO1/RPDO2 (COB-IDs and mappings read from
drive.eds).  Every voltage command (the drive's TPDO1) must equal, bit for bit, what the same firmware
answers in-process (bench direct mode: build/libhil.so) to the same frames, for every controller.
The step cost of each controller (0x2208, SysTick ticks; x40 = instructions under -icount shift=0)
is printed.
"""

from __future__ import annotations

import math
import queue
import shutil
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field

import can
import canopen
import pytest

from bench.mcu import INSTRUCTIONS_PER_TICK, SYSCLK_HZ, McuImage
from bench.paths import EDS_DIR
from bench.run.bus.direct import DirectBus, Hil
from bench.run.loop.configure import enable_cia402

DRIVE_ID = 0x20  # OD_DRIVE_DEFAULT_NODE_ID: the image's node-ID
CONTROLLERS = (0, 1, 2, 3, 4, 5)  # 0x2200:01: open loop, PI, You 2019, Yao 2020, Zhao 2022 x2
STEPS = 40
REPLY_TIMEOUT_S = 5.0


def _need(tool: str, package: str) -> None:
    if shutil.which(tool) is None:
        pytest.fail(f"{tool} not found: apt-get install {package} (or run `make setup`)")


@dataclass
class Result:
    identity: dict[str, int] = field(default_factory=dict)
    config_read_back: float = 0.0
    commands: dict[int, list[bytes]] = field(default_factory=dict)  # controller -> TPDO1 payloads
    aborts: dict[int, int] = field(default_factory=dict)  # controller refused -> SDO abort code
    step_cost: dict[int, dict[str, float]] = field(default_factory=dict)


def measurements(n: int, k0: int) -> Iterator[tuple[int, float, float, float]]:
    """(sample_index, i_a_A, i_b_A, theta_m_rad) of a plant turning slowly with a few amperes."""
    for k in range(k0, k0 + n):
        th = 0.01 * k
        yield k & 0xFFFF, 3.0 * math.cos(5 * th + 0.3), 3.0 * math.sin(5 * th + 0.3), th % (2 * math.pi)


def run_master(bus: can.BusABC) -> Result:
    """The whole exchange as the bench master and the plant would do it; the drive's answers."""
    res = Result()
    net = canopen.Network(bus)
    net.connect()
    try:
        node = net.add_node(DRIVE_ID, str(EDS_DIR / "drive.eds"))
        od = node.object_dictionary
        res.identity = {
            "device_type": node.sdo[0x1000].raw,
            "vendor_id": node.sdo[0x1018][1].raw,
            "product_code": node.sdo[0x1018][2].raw,
        }
        assert res.identity["device_type"] == od[0x1000].default
        assert res.identity["vendor_id"] == od[0x1018][1].default
        node.sdo["Online tuning"]["pi_bandwidth_Hz"].raw = 800.0
        res.config_read_back = node.sdo["Online tuning"]["pi_bandwidth_Hz"].raw

        node.rpdo.read(from_od=True)  # the drive's RPDOs as drive.eds maps them (the plant's TPDOs)
        node.tpdo.read(from_od=True)
        rpdo1, rpdo2, tpdo1 = node.rpdo[1], node.rpdo[2], node.tpdo[1]
        replies: queue.Queue[bytes] = queue.Queue()
        net.subscribe(tpdo1.cob_id, lambda _cob, data, _ts: replies.put(bytes(data)))
        assert enable_cia402(node)  # CiA 402: the power stage acts in OPERATION ENABLED only
        node.nmt.state = "OPERATIONAL"

        k0 = 0
        for ctrl in CONTROLLERS:
            try:
                node.sdo["Controller"]["controller"].raw = ctrl
            except canopen.SdoAbortedError as e:
                res.aborts[ctrl] = e.code
                continue
            cmds: list[bytes] = []
            for si, ia, ib, th in measurements(STEPS, k0):
                rpdo1["Measurement.i_a_A"].raw = ia
                rpdo1["Measurement.i_b_A"].raw = ib
                rpdo2["Measurement.theta_m_rad"].raw = th
                rpdo2["Measurement.sync_counter"].raw = 0
                rpdo2["Measurement.status"].raw = 0
                rpdo2["Measurement.sample_index"].raw = si
                rpdo1.transmit()
                rpdo2.transmit()
                cmds.append(replies.get(timeout=REPLY_TIMEOUT_S))
            k0 += STEPS
            res.commands[ctrl] = cmds
            cost = node.sdo["Step cost"]
            res.step_cost[ctrl] = {
                name: float(cost[name].raw)
                for name in (
                    "step_cycles_last",
                    "step_cycles_max",
                    "step_cycles_mean",
                    "cycle_clock_Hz",
                    "steps_measured",
                )
            }
        node.nmt.state = "PRE-OPERATIONAL"
    finally:
        net.disconnect()
    return res


@pytest.fixture(scope="module")
def mcu_result() -> Result:
    _need("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    _need("qemu-system-arm", "qemu-system-arm")
    with McuImage() as mcu:
        res = run_master(mcu.open_bus())
        assert "HardFault" not in mcu.console(), mcu.console()
    return res


@pytest.fixture(scope="module")
def host_result() -> Result:
    return run_master(DirectBus(Hil(0x10, DRIVE_ID)))


def test_identity_and_configuration(mcu_result: Result) -> None:
    assert mcu_result.identity["product_code"] == canopen.import_od(str(EDS_DIR / "drive.eds"))[0x1018][2].default
    assert mcu_result.config_read_back == 800.0


def command_differences(a: Result, b: Result) -> dict[int, tuple[int, float, int]]:
    """Per controller: (commands that differ, largest |difference| in V, largest difference in ULP)."""
    out = {}
    for ctrl, cmds in b.commands.items():
        n, worst_v, worst_ulp = 0, 0.0, 0
        for x, y in zip(a.commands[ctrl], cmds, strict=True):
            n += x != y
            fx, fy = struct.unpack("<2f", x), struct.unpack("<2f", y)
            ix, iy = struct.unpack("<2i", x), struct.unpack("<2i", y)
            worst_v = max(worst_v, *(abs(p - q) for p, q in zip(fx, fy, strict=True)))
            worst_ulp = max(worst_ulp, *(abs(p - q) for p, q in zip(ix, iy, strict=True)))
        out[ctrl] = (n, worst_v, worst_ulp)
    return out


def test_commands_match_the_host_build(mcu_result: Result, host_result: Result) -> None:
    """Same frames, same answers: the same controllers accepted, every command present, none all zero,
    and each within 0.5 % of Vmax of the host build's (the step-by-step numbers are printed)."""
    assert mcu_result.aborts == host_result.aborts
    assert set(mcu_result.commands) == set(host_result.commands) and len(mcu_result.commands) >= 3
    for ctrl, cmds in host_result.commands.items():
        assert len(mcu_result.commands[ctrl]) == len(cmds) == STEPS
        assert any(c != bytes(8) for c in cmds), f"controller {ctrl}: the commands are all zero"
    diff = command_differences(mcu_result, host_result)
    for ctrl, (n, volts, ulp) in diff.items():
        print(f"controller {ctrl}: {n}/{STEPS} commands differ, largest {volts:.3g} V ({ulp} ULP)")
    vmax = canopen.import_od(str(EDS_DIR / "drive.eds"))["Controller"]["Vmax_V"].default
    # the PI (1) amplifies a 1-ULP seed through its speed-loop update (every 10th step): see docs/PORTING.md
    assert all(volts <= 0.005 * vmax for ctrl, (_, volts, _) in diff.items() if ctrl != 1), diff


def test_the_open_loop_is_bit_identical_to_the_host_build(mcu_result: Result, host_result: Result) -> None:
    # where the arithmetic is the same (no libm call: newlib's sinf/cosf/expf/logf are not glibc's), the
    # answers are the same bits
    n, volts, _ = command_differences(mcu_result, host_result)[0]
    assert n == 0, f"open loop: {n} commands differ, largest {volts:.3g} V"


def test_step_cost_is_published(mcu_result: Result, host_result: Result) -> None:
    for ctrl, cost in mcu_result.step_cost.items():
        assert cost["cycle_clock_Hz"] == SYSCLK_HZ
        assert cost["steps_measured"] == STEPS, cost
        assert 0 < cost["step_cycles_mean"] <= cost["step_cycles_max"], cost
        print(
            f"controller {ctrl}: {cost['step_cycles_mean'] * INSTRUCTIONS_PER_TICK:.0f} instructions per step "
            f"(mean), {cost['step_cycles_max'] * INSTRUCTIONS_PER_TICK:.0f} max"
        )
    for cost in host_result.step_cost.values():  # in-process: no cycle counter
        assert cost["cycle_clock_Hz"] == 0 and cost["step_cycles_mean"] == 0
