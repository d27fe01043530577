"""The live CiA 402 master: python `canopen` (BaseNode402) for SDO/NMT/the state machine, CAN_BCM
periodic tasks (python-can `send_periodic`) for SYNC, the RPDO and the bench's heartbeat, so that
no Python runs in the per-cycle path; the target torque changes by modifying the RPDO task's data.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.pdo.base import PdoMap
from canopen.profiles.p402 import BaseNode402, OperationMode, State402

from bench.cia402.layout import REFERENCE_PDOS, Layout, Pdo, reference_pdo
from bench.cia402.record import state_name

BENCH_ID = 0x7F
BENCH_HEARTBEAT_S = 0.1
CONSUMER_MS = 500
CST = OperationMode.CYCLIC_SYNCHRONOUS_TORQUE
CST_SUPPORTED = OperationMode.SUPPORTED["CYCLIC SYNCHRONOUS TORQUE"]  # its bit in 0x6502
DISABLE = State402.CW_DISABLE_VOLTAGE  # the controlword of the way out (and of the start)
# How long an SDO answer is waited for (python canopen's default is 0.3 s): a drive answers in a few ms,
# but the master's own Python may be descheduled for longer on a loaded machine or in the CI's VM (~50x
# slower), and a cleanup read that gives up too early reports a disabled drive as not seen disabled
SDO_RESPONSE_TIMEOUT_S = 5.0


class DriveRefused(RuntimeError):
    """The drive cannot run this (no CST, a mode not taken, a mapping refused): exit 1."""


class DriveStopped(RuntimeError):
    """FAULT, a state other than OPERATION ENABLED, or the statusword TPDO gone silent: exit 1."""


class Node402(BaseNode402):
    """BaseNode402 with timeouts for slow hosts (Python in the CI's VM is ~50x slower)."""

    def __init__(self, node_id: int, od: Any, cycle_s: float, slow: float = 50.0) -> None:
        super().__init__(node_id, od)
        self.sdo.RESPONSE_TIMEOUT = SDO_RESPONSE_TIMEOUT_S
        self.TIMEOUT_RESET_FAULT = max(0.4 * slow, 20 * cycle_s)
        self.TIMEOUT_SWITCH_OP_MODE = max(0.5 * slow, 20 * cycle_s)
        self.TIMEOUT_SWITCH_STATE_FINAL = max(0.8 * slow, 80 * cycle_s)
        self.TIMEOUT_SWITCH_STATE_SINGLE = max(0.4 * slow / 4, 20 * cycle_s)
        self.TIMEOUT_CHECK_TPDO = max(0.2 * slow / 4, 20 * cycle_s)


@dataclass
class MasterInfo:
    """What the master found and did (summary.json)."""

    rated_current_mA: int = 0
    rated_torque_mNm: int = 0
    max_torque_pm: int | None = None
    supported_modes: int = 0
    sync_cob: int = 0x80
    sync_overflow: int = 0
    pdos: dict[str, Any] = field(default_factory=dict)
    watches_bench: bool = False
    heartbeat_entry: int | None = None
    notes: list[str] = field(default_factory=list)


def _mapped(pdo: PdoMap) -> tuple[int, ...]:
    return tuple(v.index for v in pdo)


def _as_pdo(pdo: PdoMap) -> Pdo:
    com = int(pdo.com_record.od.index)
    name = f"TPDO{com - 0x1800 + 1}" if com >= 0x1800 else f"RPDO{com - 0x1400 + 1}"
    entries = tuple((v.index, v.subindex, int(v.length)) for v in pdo)
    return Pdo(name, int(pdo.cob_id or 0) & 0x7FF, int(pdo.trans_type or 0), entries)


class Master:
    def __init__(self, bus: str, interface: str, drive_id: int, eds: Path, cycle_s: float) -> None:
        self.drive_id = drive_id
        self.cycle_s = cycle_s
        self.network = canopen.Network()
        self.network.connect(interface=interface, channel=bus)
        self.bus: can.BusABC = self.network.bus
        self.node = Node402(drive_id, str(eds), cycle_s)
        self.network.add_node(self.node)
        self.info = MasterInfo()
        self.tasks: list[Any] = []
        self.rpdo: PdoMap | None = None
        self.tpdo_sw: PdoMap | None = None
        self.tpdo_pos: PdoMap | None = None
        self.last_sw = 0.0  # time.monotonic() of the last statusword TPDO

    # ------------------------------------------------------------------ set-up
    def start_heartbeat(self) -> None:
        msg = can.Message(arbitration_id=0x700 + BENCH_ID, data=[0x05], is_extended_id=False)
        self.tasks.append(self.bus.send_periodic(msg, BENCH_HEARTBEAT_S))

    def prepare(self, say: Callable[[str], None]) -> Layout:
        sdo = self.node.sdo
        sdo[0x6040].raw = DISABLE
        self.node.nmt.state = "PRE-OPERATIONAL"
        info = self.info
        info.rated_current_mA = int(sdo[0x6075].raw)
        info.rated_torque_mNm = int(sdo[0x6076].raw)
        info.supported_modes = int(sdo[0x6502].raw)
        if not info.supported_modes & CST_SUPPORTED:
            raise DriveRefused(
                f"drive 0x{self.drive_id:02X} does not support cyclic synchronous torque: 0x6502 = "
                f"0x{info.supported_modes:08X} (bit {CST_SUPPORTED.bit_length() - 1} clear)"
            )
        sync = int(sdo[0x1005].raw)
        if sync & (1 << 30):
            raise DriveRefused(f"drive 0x{self.drive_id:02X} produces SYNC itself (0x1005 = 0x{sync:08X}, bit 30)")
        info.sync_cob = sync & 0x7FF
        info.sync_overflow = int(sdo[0x1019].raw)
        try:
            info.max_torque_pm = int(sdo[0x6072].raw)
        except (canopen.SdoAbortedError, KeyError):
            info.notes.append("0x6072 max torque not readable: targets limited by INT16 only")
        self._pdos(say)
        sdo[0x6060].raw = CST
        mode = self._wait(lambda: int(sdo[0x6061].raw) == CST, 20)
        if not mode:
            raise DriveRefused(f"drive 0x{self.drive_id:02X}: 0x6061 = {int(sdo[0x6061].raw)}, not CST ({CST})")
        self._watch_bench(say)
        assert self.rpdo is not None and self.tpdo_sw is not None
        tp = [_as_pdo(self.tpdo_sw)] + ([_as_pdo(self.tpdo_pos)] if self.tpdo_pos is not None else [])
        return Layout(
            self.drive_id,
            info.sync_cob,
            info.sync_overflow,
            _as_pdo(self.rpdo),
            tp,
            info.rated_current_mA,
            info.rated_torque_mNm,
            self.cycle_s,
        )

    def _wait(self, ok: Callable[[], bool], tries: int) -> bool:
        for _ in range(tries):
            if ok():
                return True
            time.sleep(self.cycle_s)
        return False

    def _pdos(self, say: Callable[[str], None]) -> None:
        """The drive's PDOs that map what drive.eds' REFERENCE_PDOS map (the RPDO all of it, a TPDO its first
        entry), else those of drive.eds' numbers mapped by the bench as drive.eds maps them."""
        node = self.node
        node.rpdo.read()
        node.tpdo.read()
        ref_r, *ref_t = (reference_pdo(name, self.drive_id) for name in REFERENCE_PDOS)
        own = "the drive's own mapping"
        rpdo = next((p for p in node.rpdo.map.values() if set(ref_r.objects) <= set(_mapped(p))), None)
        if rpdo is None:
            rpdo, own = node.rpdo[ref_r.number], "mapped by the bench"
            rpdo.clear()
            for index, sub, _ in ref_r.entries:
                rpdo.add_variable(index, sub)
            rpdo.trans_type = ref_r.trans_type
        if rpdo.trans_type not in (*range(1, 241), 254, 255):
            rpdo.trans_type = ref_r.trans_type
        rpdo.enabled = True
        rpdo.save()
        tpdos = []
        for ref in ref_t:
            t = next((p for p in node.tpdo.map.values() if ref.objects[0] in _mapped(p)), None)
            how = "the drive's own mapping"
            if t is None:
                t, how = node.tpdo[ref.number], "mapped by the bench"
                t.clear()
                for index, sub, _ in ref.entries:
                    t.add_variable(index, sub)
            t.trans_type = ref.trans_type
            t.enabled = True
            t.save()
            tpdos.append((t, how))
        self.rpdo = rpdo
        (self.tpdo_sw, sw_how), (self.tpdo_pos, pos_how) = tpdos
        self.tpdo_sw.add_callback(self._on_sw)
        node.setup_402_state_machine(read_pdos=False)
        for name, p, how in (
            ("rpdo", rpdo, own),
            ("tpdo_status", self.tpdo_sw, sw_how),
            ("tpdo_motion", self.tpdo_pos, pos_how),
        ):
            self.info.pdos[name] = {
                "pdo": p.name,
                "cob_id": f"0x{int(p.cob_id) & 0x7FF:03X}",
                "transmission_type": int(p.trans_type or 0),
                "mapping": [f"0x{v.index:04X}" for v in p],
                "how": how,
            }
            say(
                f"  {name}: {p.name} COB 0x{int(p.cob_id) & 0x7FF:03X} type {p.trans_type} "
                f"{self.info.pdos[name]['mapping']} ({how})"
            )

    def _on_sw(self, pdo: PdoMap) -> None:
        self.last_sw = time.monotonic()

    def _watch_bench(self, say: Callable[[str], None]) -> None:
        sdo = self.node.sdo
        want = (BENCH_ID << 16) | CONSUMER_MS
        try:
            count = int(sdo[0x1016][0].raw)
            for sub in range(1, count + 1):
                value = int(sdo[0x1016][sub].raw)
                if value == 0 or (value >> 16) & 0xFF == BENCH_ID:
                    sdo[0x1016][sub].raw = want
                    self.info.heartbeat_entry, self.info.watches_bench = sub, True
                    say(f"  the drive watches the bench's heartbeat: 0x1016:{sub:02X} = 0x{want:08X}")
                    return
        except (canopen.SdoAbortedError, KeyError) as exc:
            self.info.notes.append(f"0x1016 not usable: {exc}")
        say("  the drive has no free 0x1016 entry: it does NOT watch the bench's heartbeat")

    # ------------------------------------------------------------------ run
    def start_cycle(self) -> None:
        info = self.info
        if info.sync_overflow >= 2:
            msgs = [
                can.Message(arbitration_id=info.sync_cob, data=[c], is_extended_id=False)
                for c in range(1, info.sync_overflow + 1)
            ]
        else:
            msgs = [can.Message(arbitration_id=info.sync_cob, data=[], is_extended_id=False)]
        assert self.rpdo is not None
        self.rpdo[0x6040].raw = DISABLE
        self.rpdo[0x6071].raw = 0
        self.rpdo.start(self.cycle_s)  # canopen: bus.send_periodic (CAN_BCM); .raw = ... modifies its data
        self.tasks.append(self.bus.send_periodic(msgs, self.cycle_s))
        self.node.nmt.state = "OPERATIONAL"

    def enable(self, say: Callable[[str], None]) -> None:
        assert self.tpdo_sw is not None
        if self.tpdo_sw.wait_for_reception(self.node.TIMEOUT_CHECK_TPDO) is None:
            raise DriveStopped("no statusword TPDO after NMT start")
        state = self.node.state
        say(f"  drive state {state}")
        if state == "FAULT":
            say(f"  FAULT (0x603F = 0x{int(self.node.sdo[0x603F].raw):04X}): fault reset")
            self.node.reset_from_fault()
        self.node.state = "OPERATION ENABLED"
        self.last_sw = time.monotonic()

    def set_target(self, per_mille: int) -> None:
        assert self.rpdo is not None
        self.rpdo[0x6071].raw = per_mille

    def check(self, silence_s: float) -> None:
        if time.monotonic() - self.last_sw > silence_s:
            raise DriveStopped(f"no statusword TPDO for {silence_s:g} s")
        state = self.node.state  # canopen's State402.SW_MASK on the last statusword TPDO
        if state != "OPERATION ENABLED":
            code = ""
            if state == "FAULT":
                try:
                    code = f" (0x603F = 0x{int(self.node.sdo[0x603F].raw):04X})"
                except canopen.SdoCommunicationError:
                    pass
            raise DriveStopped(f"drive left OPERATION ENABLED: {state}{code}")

    # ------------------------------------------------------------------ the way out
    def shutdown(self, say: Callable[[str], None]) -> tuple[bool, int | None]:
        """Every step in its own try: (drive seen SWITCH ON DISABLED, statusword read by SDO)."""
        sw: int | None = None

        def step(what: str, fn: Callable[[], Any]) -> Any:
            try:
                return fn()
            except Exception as exc:  # noqa: BLE001 - the next steps must run whatever this one did
                say(f"  cleanup: {what} failed: {exc}")
                return None

        if self.rpdo is not None:
            step("controlword 0 by RPDO", lambda: self._rpdo_zero())
        step("controlword 0 by SDO", lambda: self.node.sdo[0x6040].__setattr__("raw", DISABLE))
        time.sleep(2 * self.cycle_s)
        sw = step("statusword by SDO", lambda: int(self.node.sdo[0x6041].raw))
        time.sleep(3.5 * self.cycle_s)  # 3 more SYNCs from the running task
        if self.info.heartbeat_entry is not None:
            sub = self.info.heartbeat_entry
            step("clearing 0x1016", lambda: self.node.sdo[0x1016][sub].__setattr__("raw", 0))
        if self.rpdo is not None:
            step("stopping the RPDO task", self.rpdo.stop)
        for task in self.tasks:
            step("stopping a periodic task", task.stop)
        self.tasks.clear()
        step("NMT pre-operational", lambda: self.node.nmt.__setattr__("state", "PRE-OPERATIONAL"))
        disabled = sw is not None and state_name(sw) == "SWITCH ON DISABLED"
        return disabled, sw

    def _rpdo_zero(self) -> None:
        assert self.rpdo is not None
        self.rpdo[0x6071].raw = 0
        self.rpdo[0x6040].raw = DISABLE
        if self.rpdo.period is None:
            self.rpdo.transmit()

    def close(self) -> None:
        try:
            self.network.disconnect()
        except Exception:  # noqa: BLE001 - closing after a failure
            pass
