"""The SDO configuration of a run (a part of Session): the scenario's settings written by their EDS names,
each refusal named with the EDS's limits; heartbeats; the PDO wiring and the trace PDOs; the CiA 402 enable
by python canopen's State402 tables."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import canopen
from canopen.objectdictionary.datatypes import REAL32
from canopen.profiles.p402 import State402
from canopen.sdo.exceptions import SdoAbortedError

from bench.eds import eds_path, float_limits
from bench.run.bus.kind import SettingRefused
from bench.run.loop.reads import PLANT_VALUES
from bench.scenario import Setting
from bench.scenario.frames import (
    CAN_FD,
    CODING,
    COMPACT_MAP,
    PERIOD_MARKS,
    SINGLE_FRAME_MAP,
    coding_for,
    coding_refusal,
)

if TYPE_CHECKING:
    from bench.run.options import RunOptions
    from bench.scenario import Scenario

HOLD_TPDO = 4  # the plant TPDO the bench maps to the hold announcement
OBJECT_DOES_NOT_EXIST = 0x06020000  # SDO abort code (CiA 301)


def _entry(node: canopen.RemoteNode, obj: str, sub: str | None = None):  # type: ignore[no-untyped-def]
    return node.sdo[obj] if sub is None else node.sdo[obj][sub]


def enable_cia402(drive: canopen.RemoteNode) -> bool:
    """CiA 402: the drive commands voltage only in OPERATION ENABLED (drive.eds 0x6040/0x6041): SWITCH ON
    DISABLED -> READY TO SWITCH ON -> SWITCHED ON -> OPERATION ENABLED by SDO (controlword 6, 7, 15;
    transitions 2, 3, 4), written in PRE-OPERATIONAL by the bench, so that no frame of a run changes.
    A controller of drive.eds without CiA 402 (it answers "object does not exist") is left as it is:
    returns False then."""
    cw = drive.sdo["Controlword"]
    try:
        cw.raw = State402.CW_SHUTDOWN
    except SdoAbortedError as exc:
        if exc.code == OBJECT_DOES_NOT_EXIST:
            return False
        raise
    cw.raw = State402.CW_SWITCH_ON
    cw.raw = State402.CW_OPERATION_ENABLED
    sw = int(drive.sdo["Statusword"].raw)
    if not in_state(sw, "OPERATION ENABLED"):
        raise RuntimeError(f"the drive did not reach OPERATION ENABLED: statusword 0x{sw:04X}")
    return True


def in_state(statusword: int, state: str) -> bool:
    """Whether a CiA 402 statusword shows this state (canopen's State402.SW_MASK: mask, value)."""
    mask, value = State402.SW_MASK[state]
    return statusword & mask == value


class Configurator:
    """Writes a scenario into both nodes by SDO (Session owns one): at the start (`configure`) and at each
    event's period (`apply`, with `period` set by the session). What it learns is kept here: the plant's
    values, every setting applied and the reference changes with their periods, the hold announcement's
    COB-ID."""

    def __init__(
        self,
        sc: Scenario,
        opts: RunOptions,
        plant: canopen.RemoteNode,
        drive: canopen.RemoteNode,
        maps_from_eds: bool = False,
    ) -> None:
        self.sc = sc
        # the PDO maps read from the EDS, not by SDO (the in-process bus's nodes: BusKind.in_process, wire_pdos)
        self.maps_from_eds = maps_from_eds
        self.opts = opts
        self.plant = plant
        self.drive = drive
        # the nodes' consumer time (0x1016): the bench's own, longer in the CAN box (Session.open, BOX_CONSUMER_MS)
        self.consumer_ms = opts.heartbeat_timeout_ms
        self.plant_values: dict[str, Any] = {}
        self.references: list[tuple[int, str, float]] = []
        self.applied: list[tuple[int, str, float]] = []  # every setting with the period it took effect
        self.period = 0  # the period the next setting takes effect at
        self.hold_cob = 0  # the plant's hold announcement (wire_pdos)

    # ---------------------------------------------------------------- configuration
    def _write(self, var, value: float | int, what: str) -> None:  # type: ignore[no-untyped-def]
        """One SDO write; a refusal names the scenario key, the value and the node's reason."""
        try:
            var.raw = value
        except SdoAbortedError as exc:
            raise SettingRefused(
                f"{what} = {value:g} refused by node 0x{var.sdo_node.rx_cobid - 0x600:02X} (object "
                f"{var.od.qualname!r}) at period {self.period}: {exc}{self._limits(var)}"
            ) from None

    def _limits(self, var) -> str:  # type: ignore[no-untyped-def]
        """What the EDS says the value must be: its range, its description, and a limit in Ts worked out."""
        import re

        od = var.od
        node_name = "drive" if var.sdo_node is self.drive.sdo else "plant"
        # canopen reads integer limits only: a REAL32's come from the EDS text (bench/eds.py), as the scenario's do
        lo, hi = float_limits(eds_path(node_name), od) if od.data_type == REAL32 else (od.min, od.max)
        parts = []
        if lo is not None or hi is not None:
            parts.append(f"range {'-inf' if lo is None else f'{lo:g}'} .. {'inf' if hi is None else f'{hi:g}'}")
        if od.description:
            parts.append(od.description)
        m = re.search(r"1/\((\d+) Ts\)", od.description or "")
        if m:
            try:
                node = self.drive if node_name == "drive" else self.plant
                ts = float(
                    node.sdo["Controller"]["Ts_s"].raw if node is self.drive else node.sdo["Inverter"]["Ts_s"].raw
                )
                parts.append(
                    f"with the node's Ts_s = {ts:g} s now, 1/({m.group(1)} Ts) = {1.0 / (int(m.group(1)) * ts):.6g}"
                )
            except Exception:  # noqa: BLE001 - the message is still useful without it
                pass
        return ("; the EDS says: " + "; ".join(parts)) if parts else ""

    def apply(self, s: Setting) -> None:
        self.applied.append((self.period, s.key, float(s.value)))
        if s.param is None:  # ratio of a plant value
            for drive_name, plant_name in s.ratio_of:
                value = self.plant_values[plant_name] * float(s.value)
                self._write(_entry(self.drive, "Controller", drive_name), value, f"{s.key} -> {drive_name}")
            return
        node = self.plant if s.param.node == "plant" else self.drive
        self._write(_entry(node, s.param.obj, s.param.name), s.value, s.key)
        if s.param.obj == "References":
            self.references.append((self.period, s.param.name, float(s.value)))
        if (s.param.node, s.param.obj, s.param.name) == ("drive", "Safe state", "clear") and int(s.value) == 1:
            self._reenable_after_clear()

    def _write_flux_map(self, motor: Any) -> None:
        """The motor folder's flux map into the plant's 0x2008 (a segmented SDO download of its bytes)."""
        blob = motor.map.blob()
        try:
            self.plant.sdo["Flux map"].raw = blob
        except SdoAbortedError as exc:
            raise SettingRefused(
                f"the plant refused the flux map of {motor.map_file} ({len(blob)} bytes to 0x2008 Flux map): {exc}"
            ) from None

    def _write_fmu(self, fmu: Any) -> None:
        """The FMU's description into the plant's 0x2009 (the plant loads and initializes it there)."""
        try:
            self.plant.sdo["FMU"].raw = fmu.text.encode()
        except SdoAbortedError as exc:
            raise SettingRefused(
                f"the plant refused the FMU {fmu.path} (0x2009 FMU; the plant's log says why): {exc}"
            ) from None

    def configure(self) -> None:
        self.period = 0
        sc, plant, drive = self.sc, self.plant, self.drive
        self.configure_heartbeats()
        if sc.preset:
            plant.sdo["Motor preset"].raw = sc.preset
        if sc.motor_folder is not None and sc.motor_folder.map is not None:  # the map first: model = flux_map needs it
            self._write_flux_map(sc.motor_folder)
        if sc.motor_fmu is not None:  # the FMU first: the plant refuses model = fmu without one
            self._write_fmu(sc.motor_fmu)
        plant.sdo["Sensors"]["rng_seed"].raw = sc.seed
        plant.sdo["Run control"]["mode"].raw = 0 if sc.timing == "lockstep" else 1
        for s in sc.settings:
            if s.param is not None and s.param.node == "plant":
                self.apply(s)
        # Read back by SDO, so that the log carries the plant the run had (bench/run/decode/sdo_log.py).
        for obj, names in PLANT_VALUES:
            for name in names:
                self.plant_values[name] = plant.sdo[obj][name].raw
        # The controller starts from the plant's true values; the scenario's mismatch follows.
        ctl = drive.sdo["Controller"]
        for hat, true in (
            ("R_hat_ohm", "R_ohm"),
            ("Ld_hat_H", "Ld_H"),
            ("Lq_hat_H", "Lq_H"),
            ("psi_hat_Wb", "psi_Wb"),
            ("J_hat_kgm2", "J_kgm2"),
        ):
            self._write(ctl[hat], self.plant_values[true], f"controller.{hat}")
        explicit = {s.key for s in sc.settings}
        for s in sc.settings:
            if s.param is None or s.param.node == "drive":
                self.apply(s)
        # The controller runs at the plant's period with its pole pairs, unless the scenario says otherwise;
        # written after the scenario's bandwidths, which the drive checks against Ts.
        for name in ("Ts_s", "pole_pairs"):
            if f"controller.{name}" not in explicit:
                self._write(ctl[name], self.plant_values[name], f"controller.{name} (= the plant's {name})")
        for e in sc.events:
            if e.at_period == 0:
                for s in e.settings:
                    self.apply(s)
        self.wire_pdos()
        self.enable_drive()

    # ---------------------------------------------------------------- CiA 402
    def enable_drive(self) -> None:
        """CiA 402 enable before the run (enable_cia402); a refusal is named like a scenario's."""
        try:
            enable_cia402(self.drive)
        except SdoAbortedError as exc:
            raise SettingRefused(f"the drive refused the CiA 402 enable (controlword 6, 7, 15): {exc}") from None

    def _reenable_after_clear(self) -> None:
        """A scenario's fault reset (Safe state.clear = 1) leaves the CiA 402 FAULT for SWITCH ON DISABLED
        (transition 15): the bench enables the drive again, so the control goes on as before the fault.
        A clear that found no fault leaves the drive enabled, and nothing is written."""
        if in_state(int(self.drive.sdo["Statusword"].raw), "SWITCH ON DISABLED"):
            self.enable_drive()

    def configure_heartbeats(self) -> None:
        """CiA 301 error control: each node produces a heartbeat (0x1017) and consumes the other's
        (0x1016: a lost drive stops the plant, EMCY 0x8130 from either tells the bench)."""
        hb, to = self.opts.heartbeat_ms, self.consumer_ms
        if not 0 < hb < to <= 0xFFFF:
            raise ValueError(f"heartbeat {hb} ms, consumer time {to} ms: need 0 < heartbeat < consumer time <= 65535")
        for node, other in ((self.plant, self.drive), (self.drive, self.plant)):
            self._write(
                node.sdo["Consumer heartbeat time"][1],
                (other.id << 16) | to,
                f"consumer heartbeat time of node 0x{other.id:02X}",
            )
            self._write(node.sdo["Producer heartbeat time"], hb, "producer heartbeat time")

    def wire_can_fd(self) -> None:
        """[frames] can = "fd": both nodes' PDOs in CAN FD frames (0x2105:01, with or without the bit-rate switch),
        before any PDO is mapped beyond 8 bytes; the plant's hold announcement stays classic (0x2105:02) so that a
        master behind a classic-only link (the CAN box's SLCAN bridge) hears it."""
        fmt = 2 if self.sc.frames.bit_rate_switch else 1
        for node in (self.plant, self.drive):
            self._write(node.sdo[CAN_FD]["pdo_frame_format"], fmt, "frames.can")
        self._write(self.plant.sdo[CAN_FD]["classic_tpdos"], 1 << (HOLD_TPDO - 1), "frames.can (hold announcement)")

    def wire_single_frame(self) -> None:
        """[frames] measurement = "single_frame": the measurement's REAL32 values in one CAN FD frame, the plant's
        TPDO1 to the drive's RPDO1; TPDO2 and RPDO2 off."""
        self._map_measurement(SINGLE_FRAME_MAP)

    def _map_measurement(self, mapping: tuple[tuple[str, str], ...]) -> None:
        plant, drive = self.plant, self.drive
        for m, cob in ((plant.tpdo[1], None), (drive.rpdo[1], plant.tpdo[1].cob_id)):
            m.clear()
            for obj, name in mapping:
                m.add_variable(obj, name)
            if cob is not None:
                m.cob_id = cob
            m.enabled = True
            m.save()
        for m in (plant.tpdo[2], drive.rpdo[2]):
            m.enabled = False
            m.save()

    def wire_compact(self) -> None:
        """[frames] measurement = "compact" (bench/scenario/frames.py): the coding into both nodes' 0x2104, the
        measurement in the plant's TPDO1 and the drive's RPDO1, the plant's TPDO2 and the drive's RPDO2 off."""
        plant, drive = self.plant, self.drive
        sensors = plant.sdo["Sensors"]
        adc_lsb = float(sensors["adc_lsb_A"].raw)
        lsb, counts = coding_for(self.sc.frames, adc_lsb, int(sensors["encoder_lines"].raw))
        chosen = (
            "the scenario's"
            if self.sc.frames.current_lsb_A is not None
            else ("the ADC model's LSB" if adc_lsb > 0 else "the EDS default")
        )
        refusal = coding_refusal(lsb, chosen, float(sensors["adc_full_scale_A"].raw))
        if refusal is not None:
            raise SettingRefused(refusal)
        for node in (plant, drive):
            coding = node.sdo[CODING]
            self._write(coding["current_lsb_A"], lsb, "frames.current_lsb_A")
            self._write(coding["angle_counts"], counts, "frames.angle_counts")
        self._map_measurement(COMPACT_MAP)

    def wire_pdos(self) -> None:
        """Link the plant's measurement TPDOs to the drive's RPDOs and the drive's command
        TPDO to the plant's RPDO (COB-IDs read from the nodes), and map the trace PDOs."""
        plant, drive = self.plant, self.drive
        # Only the maps this links or maps are read (each map: COB-ID, transmission type, mapping), not all
        # sixteen: the same writes follow, with half the transfers. Over a bus by SDO (a physical drive may
        # keep a stored configuration); in direct mode from the EDS: the in-process nodes are this project's,
        # built from the same EDS and reset just before (tests/host/test_direct_sdo.py compares both reads).
        from_od = self.maps_from_eds
        for m in (plant.tpdo[1], plant.tpdo[2], drive.tpdo[1], drive.rpdo[1], drive.rpdo[2], plant.rpdo[1]):
            m.read(from_od=from_od)
        plant.tpdo[HOLD_TPDO].read(from_od=from_od)
        for num in self.sc.trace:
            drive.tpdo[num].read(from_od=from_od)
        if self.sc.frames.fd:
            self.wire_can_fd()
        if self.sc.frames.compact:
            self.wire_compact()
        elif self.sc.frames.measurement == "single_frame":
            self.wire_single_frame()
        else:
            for num in (1, 2):
                m = drive.rpdo[num]
                m.cob_id = plant.tpdo[num].cob_id
                m.enabled = True
                m.save()
        if self.sc.frames.sync_less:
            mark = PERIOD_MARKS.index("measurement")
            self._write(plant.sdo["Run control"]["period_mark"], mark, "frames.period_mark")
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
        self.hold_cob = m.cob_id
        for num, signals in self.sc.trace.items():
            m = drive.tpdo[num]
            m.clear()
            for sig in signals:
                obj, sub = sig.split(".")
                m.add_variable(obj, sub)
            # synchronous: the values after step k-1, sent at SYNC k; without SYNC frames event-driven: the drive
            # sends such a TPDO when measurement k arrives, before step k (drive_app.c period_trace_tpdo): the same
            m.trans_type = 254 if self.sc.frames.sync_less else 1
            m.enabled = True
            m.save()
