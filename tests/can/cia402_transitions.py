"""The walk of BaseNode402 (python `canopen`, an independent CiA 402 master) through the project's drive node:
shared by tests/can/test_cia402_vcan.py (vcan) and tests/can/test_can_controllers.py (two emulated CAN
controllers). Every transition of CiA 402-2 Figure 8 that a master can command, the statusword seen by
BaseNode402 from the drive's statusword TPDO; a CST torque command with SYNC from a CAN_BCM task; a fault
and its reset."""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass, field

import can
import canopen
from canopen.profiles.p402 import State402

from bench.paths import EDS_DIR

# the master's commands, in order: (target state, the transitions of CiA 402-2 it takes)
WALK: list[tuple[str, str]] = [
    ("READY TO SWITCH ON", "2"),
    ("SWITCHED ON", "3"),
    ("OPERATION ENABLED", "4"),
    ("SWITCHED ON", "5"),
    ("READY TO SWITCH ON", "6"),
    ("SWITCH ON DISABLED", "7"),
    ("OPERATION ENABLED", "2 3 4"),
    ("READY TO SWITCH ON", "8"),
    ("SWITCHED ON", "3"),
    ("SWITCH ON DISABLED", "10"),
    ("OPERATION ENABLED", "2 3 4"),
    ("SWITCH ON DISABLED", "9"),
]


@dataclass
class Report:
    transitions_done: int = 0
    transitions_failed: list[str] = field(default_factory=list)
    torque_mean_per_mille: float = 0.0
    current_mean_per_mille: float = 0.0
    fault_error_code: int = 0
    emcy_codes: list[int] = field(default_factory=list)
    state_after_reset: str = ""
    final_state: str = ""
    statusword_tpdos: int = 0
    samples: list[tuple[int, int]] = field(default_factory=list)

    def text(self) -> str:
        return (
            f"{self.transitions_done} transitions, failed: {self.transitions_failed or 'none'}; "
            f"{self.statusword_tpdos} statusword TPDOs; CST 250 per mille -> torque actual "
            f"{self.torque_mean_per_mille:.1f}, current actual {self.current_mean_per_mille:.1f} per mille "
            f"(torque, current: {self.samples}); fault "
            f"0x603F = 0x{self.fault_error_code:04X}, EMCY {[hex(c) for c in self.emcy_codes]}; after "
            f"reset_from_fault: {self.state_after_reset}; final {self.final_state}"
        )


def new_drive_402(node_id: int) -> canopen.BaseNode402:
    node = canopen.BaseNode402(node_id, str(EDS_DIR / "drive.eds"))
    # BaseNode402's waits are tuned for a fast host; Python in the CI's VM is ~50x slower
    node.TIMEOUT_SWITCH_STATE_FINAL = 10.0
    node.TIMEOUT_SWITCH_STATE_SINGLE = 5.0
    node.TIMEOUT_RESET_FAULT = 1.0  # reset_from_fault waits all of it (its FIXME: no edge before 0x80)
    node.TIMEOUT_SWITCH_OP_MODE = 5.0
    node.TIMEOUT_CHECK_TPDO = 2.0
    return node


def _sync_task(bus: can.BusABC, cycle_s: float) -> can.broadcastmanager.CyclicSendTaskABC:
    """SYNC with the counter 1..240 the nodes' 0x1019 asks, from the kernel (CAN_BCM: one task cycling
    through 240 frames), so no Python runs per cycle."""
    frames = [can.Message(arbitration_id=0x80, data=[c], is_extended_id=False) for c in range(1, 241)]
    return bus.send_periodic(frames, cycle_s)


def walk(loop, iface: str, cycle_s: float) -> Report:  # type: ignore[no-untyped-def]
    """Run the walk on `loop` (tests/can/cia402_loop.py: the drive a BaseNode402, PRE-OPERATIONAL)."""
    drive: canopen.BaseNode402 = loop.drive
    rep = Report()
    emcys: list[int] = []
    sw_count = [0]

    def on_emcy(cob_id: int, data: bytearray, ts: float) -> None:
        emcys.append(struct.unpack_from("<H", data)[0])

    loop.net.subscribe(0x80 + drive.id, on_emcy)
    # the drive's default CiA 402 PDOs: RPDO4 {controlword, target torque}, TPDO3 {statusword, mode,
    # torque, current}; mapped in the EDS, made valid here as a master does
    drive.nmt.state = "PRE-OPERATIONAL"
    drive.rpdo.read()
    drive.tpdo.read()
    drive.rpdo[4].enabled = True
    drive.rpdo[4].save()
    drive.tpdo[3].enabled = True
    drive.tpdo[3].trans_type = 1  # cyclic synchronous, as a CiA 402 master runs a drive: at every SYNC
    drive.tpdo[3].save()
    drive.setup_402_state_machine(read_pdos=False)
    drive.tpdo[3].add_callback(lambda m: sw_count.__setitem__(0, sw_count[0] + 1))
    drive.nmt.send_command(0x01)
    task = _sync_task(loop.net.bus, cycle_s)
    try:
        _walk(loop, drive, cycle_s, rep)
    finally:
        task.stop()
        drive.rpdo[4]["Target torque"].raw = 0
        drive.controlword = 0
        rep.final_state = _state_by_sdo(drive)
        loop.net.unsubscribe(0x80 + drive.id, on_emcy)
    rep.emcy_codes = sorted(set(emcys))
    rep.statusword_tpdos = sw_count[0]
    return rep


def _state_by_sdo(drive: canopen.BaseNode402) -> str:
    sw = int(drive.sdo["Statusword"].raw)
    for state, (mask, bits) in State402.SW_MASK.items():
        if sw & mask == bits:
            return state
    return f"0x{sw:04X}"


def _walk(loop, drive: canopen.BaseNode402, cycle_s: float, rep: Report) -> None:  # type: ignore[no-untyped-def]
    drive.check_statusword()
    for target, numbers in WALK:
        try:
            drive.state = target
            ok = drive.state == target
        except RuntimeError:
            ok = False
        if ok:
            rep.transitions_done += len(numbers.split())
        else:
            rep.transitions_failed.append(f"{numbers} -> {target} (statusword 0x{drive.statusword:04X})")

    # quick stop with option code 6 (stay): 11, then 16 back; option 2 (default) ends in SWITCH ON DISABLED
    drive.sdo["Quick stop option code"].raw = 6
    for target, numbers in (
        ("OPERATION ENABLED", "2 3 4"),
        ("QUICK STOP ACTIVE", "11"),
        ("OPERATION ENABLED", "16"),
        ("QUICK STOP ACTIVE", "11"),
        ("SWITCH ON DISABLED", "12"),
    ):
        drive.state = target
        if drive.state == target:
            rep.transitions_done += len(numbers.split())
        else:
            rep.transitions_failed.append(f"{numbers} -> {target} (statusword 0x{drive.statusword:04X})")
    drive.sdo["Quick stop option code"].raw = 2

    # command: CST, 250 per mille; the drive's actual values read back after the current settled
    drive.op_mode = "CYCLIC SYNCHRONOUS TORQUE"
    if drive.sdo["Modes of operation display"].raw != 10:
        rep.transitions_failed.append("CST not selected")
    drive.state = "OPERATION ENABLED"
    drive.rpdo[4]["Target torque"].raw = 250
    drive.controlword = 0x0F  # RPDO4 carries controlword and target torque together
    time.sleep(40 * cycle_s)  # the current settles (PI at 1/(12 Ts))
    torque, current = [], []
    for _ in range(10):  # read together: the TPDO3 of one SYNC carries both
        drive.check_statusword()
        torque.append(int(drive.tpdo_values[0x6077]))
        current.append(int(drive.tpdo_values[0x6078]))
    rep.samples = list(zip(torque, current, strict=True))
    rep.torque_mean_per_mille = sum(torque) / len(torque)
    rep.current_mean_per_mille = sum(current) / len(current)

    # fault: the motor falls silent (plant NMT stopped: no measurement) -> measurement timeout
    loop.plant.nmt.send_command(0x02)
    deadline = time.monotonic() + 60 * cycle_s + 5.0
    while time.monotonic() < deadline and not drive.is_faulted():
        drive.check_statusword()
    rep.fault_error_code = int(drive.sdo["Error code"].raw)
    loop.plant.nmt.send_command(0x01)
    time.sleep(5 * cycle_s)
    drive.reset_from_fault()  # 0 then 0x80: transition 15, then 2 3 4
    rep.state_after_reset = drive.state
    if rep.state_after_reset == "OPERATION ENABLED":
        rep.transitions_done += 4
    drive.state = "SWITCH ON DISABLED"
