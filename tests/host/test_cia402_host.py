"""The CiA 402 master (`bench run --drive-profile cia402`) without a bus: the profile as CST targets,
the cycle planner, refusals (exit 2, nothing written), decoding a candump log into the trace."""

from __future__ import annotations

import argparse
import csv
import json
import math
import struct
from pathlib import Path

import can
import numpy as np
import pytest

from bench.cia402.layout import default_layout
from bench.cia402.plan import Frames, PlanError, bus_load, choose_cycle, ignored_keys, per_mille, targets
from bench.cia402.record import Trace, decode_log, state_name, states_passed, tracking, write_csv
from bench.paths import REPO
from bench.scenario import load

STEP = REPO / "scenarios" / "you2019_step.toml"


def parse_run(argv: list[str]) -> argparse.Namespace:
    """`bench run`'s arguments as the CLI parses them (its own and the CiA 402 master's)."""
    from bench.cli import build_parser

    return build_parser().parse_args(["run", *argv])


def test_profile_becomes_cst_targets() -> None:
    sc = load(STEP)
    segs = targets(sc, 4000, 1000)
    assert [(s.start_cycle, s.end_cycle, s.per_mille) for s in segs] == [(0, 20, 0), (20, 200, 250)]
    assert per_mille(1.0, 4000) == 250 and per_mille(-2.0, 1000) == -2000
    with pytest.raises(PlanError, match="0x6072"):
        targets(sc, 1000, 999)  # 1 A of 1 A rated = 1000 per mille > 999
    with pytest.raises(PlanError, match="INT16"):
        targets(sc, 10, None)  # 1 A of 10 mA = 100000 per mille
    keys = ignored_keys(sc)
    assert "motor.preset" in keys and "controller.controller" in keys and "drive.t_dead_s" in keys
    assert not any("iq_ref_A" in k for k in keys)


def test_cycle_planner() -> None:
    assert choose_cycle(1_000_000, None)[0] == 0.001
    assert choose_cycle(125_000, None)[0] == 0.005  # 2 ms would load the bus > 80 %
    assert bus_load(Frames.reference(), 0.002, 125_000) > 0.8
    with pytest.raises(PlanError, match="no cycle"):
        choose_cycle(20_000, None)
    assert choose_cycle(20_000, 50)[0] == 0.05
    for bad in (0.5, 2000.0):
        with pytest.raises(PlanError, match="1 .. 1000 ms"):
            choose_cycle(1_000_000, bad)
    with pytest.raises(PlanError, match="load"):
        choose_cycle(125_000, 1)


@pytest.mark.parametrize(
    "extra, why",
    [
        (["--drive-id", "0"], "node-ID"),
        (["--drive-id", "0x7F"], "heartbeat"),
        (["--cycle-ms", "0.2"], "1 .. 1000"),
        (["--set", "references.iq_ref_A=5"], "0x6072"),  # 5 A of 4 A rated: 1250 > 1000 per mille
        (["--drive-eds", "/nonexistent.eds"], "no such file"),
        (["--bus", "direct"], "CAN bus"),
        (["--drive-bus", "can1"], "--drive-bus"),
        (["--drive", "mcu"], "--drive mcu"),
    ],
)
def test_refusals_exit_2_and_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], why: str
) -> None:
    out = tmp_path / "out"
    args = parse_run([str(STEP), "--drive-profile", "cia402", "--out", str(out), *extra])
    assert args.func(args) == 2
    assert why in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_help_explains_the_profile(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        parse_run(["--help"])
    text = capsys.readouterr().out
    assert "--drive-profile" in text and "no lockstep" in text and "0x1016" in text


def test_state_names() -> None:
    assert state_name(0x0040) == "SWITCH ON DISABLED"
    assert state_name(0x0221) == "READY TO SWITCH ON"
    assert state_name(0x0627) == "OPERATION ENABLED"
    assert state_name(0x0008) == "FAULT"


def _synthetic_log(
    path: Path, cycles: int, drop_sw_at: int, prelude: tuple[can.Message, ...] = (), motion_cob: int = 0x4A0
) -> None:
    """A run as the master and a drive with drive.eds' PDOs would put it on the bus (after `prelude`)."""
    t = 1_700_000_000.0
    msgs = list(prelude)
    for k in range(cycles):
        target = 0 if k < 10 else 250
        actual = 0 if k < 12 else 240
        sw = 0x0040 if k < 3 else 0x0627
        msgs.append(can.Message(timestamp=t, arbitration_id=0x520, data=struct.pack("<Hh", 0x0F, target)))
        msgs.append(can.Message(timestamp=t + 2e-4, arbitration_id=0x80, data=[k % 240 + 1]))
        if k != drop_sw_at:
            data = struct.pack("<HbhH", sw, 10, actual, actual)
            msgs.append(can.Message(timestamp=t + 4e-4, arbitration_id=0x3A0, data=data))
        msgs.append(
            can.Message(timestamp=t + 5e-4, arbitration_id=motion_cob, data=struct.pack("<ii", 16384 * k, -65536))
        )
        if k % 5 == 0:
            msgs.append(can.Message(timestamp=t + 6e-4, arbitration_id=0x77F, data=[5]))
        t += 0.01
    with can.CanutilsLogWriter(str(path), channel="vcan0") as w:
        for m in msgs:
            m.is_extended_id = False
            w.on_message_received(m)


def test_decode_synthetic_log(tmp_path: Path) -> None:
    log = tmp_path / "bus.log"
    _synthetic_log(log, 40, drop_sw_at=20)
    layout = default_layout(0x20, 0.01)
    trace = decode_log(log, layout)
    c = trace.columns
    assert len(trace) == 40
    assert trace.cycles_without_statusword == 1 and math.isnan(c["statusword"][20]) and trace.state[20] == ""
    assert states_passed(trace) == ["SWITCH ON DISABLED", "OPERATION ENABLED"]
    # the RPDO sent before SYNC k is cycle k's target
    assert c["target_torque_permille"][10] == 250 and c["target_torque_permille"][9] == 0
    assert math.isnan(c["target_torque_permille"][0])
    assert c["torque_actual_Nm"][30] == pytest.approx(240 / 1000 * 1.26)
    assert c["current_actual_A"][30] == pytest.approx(0.96)
    assert c["position_rad"][3] == pytest.approx(3 * math.pi / 2)
    assert c["velocity_rad_s"][5] == pytest.approx(-2 * math.pi)
    assert np.all(c["mode_display"][~np.isnan(c["mode_display"])] == 10)
    assert c["t_s"][1] == pytest.approx(0.01, abs=1e-6)
    seg = tracking(trace)
    assert [s["target_permille"] for s in seg] == [0, 250]
    assert seg[1]["mean_actual_permille"] == pytest.approx(240) and seg[1]["relative_error"] == pytest.approx(-0.04)
    write_csv(trace, tmp_path / "trace.csv")
    rows = list(csv.DictReader(open(tmp_path / "trace.csv")))
    assert len(rows) == 40 and rows[30]["state"] == "OPERATION ENABLED" and rows[20]["statusword"] == ""
    json.dumps(layout.to_json())  # summary.json keeps the layout


def test_a_cycle_without_its_target_does_not_split_a_run_of_one_target() -> None:
    """A cycle whose RPDO the log lacks (a software periodic sender late by a cycle) inside a run of 250 per
    mille: one run, its window the second half of the whole run; a gap between two different targets stays."""
    n = 40
    tgt = np.full(n, 250.0)
    tgt[:10] = 0.0
    tgt[0] = tgt[25] = tgt[9] = np.nan
    act = np.where(np.arange(n) < 12, 0.0, np.linspace(100.0, 250.0, n))
    trace = Trace({"target_torque_permille": tgt, "torque_actual_permille": act}, ["OPERATION ENABLED"] * n, 0)
    seg = tracking(trace)
    assert [(s["start_cycle"], s["cycles"], s["target_permille"]) for s in seg] == [(1, 8, 0.0), (10, 30, 250.0)]
    assert seg[1]["mean_actual_permille"] == pytest.approx(float(np.mean(act[25:40])))


def _sdo(t: float, index: int, sub: int, value: int, upload: bool = False) -> tuple[can.Message, can.Message]:
    """An expedited SDO transfer of a 4-byte entry of drive 0x20 as the bus shows it: request, answer."""
    where = struct.pack("<HB", index, sub)
    if upload:
        req, ans = b"\x40" + where + bytes(4), b"\x43" + where + struct.pack("<I", value)
    else:
        req, ans = b"\x23" + where + struct.pack("<I", value), b"\x60" + where + bytes(4)
    return (
        can.Message(timestamp=t, arbitration_id=0x620, data=req),
        can.Message(timestamp=t + 1e-4, arbitration_id=0x5A0, data=ans),
    )


def test_the_layout_comes_from_the_bus(tmp_path: Path) -> None:
    """The record decodes with the run's decoder (bench/run/decode, profile cia402), which reads the layout off
    the master's SDO traffic in the log: a TPDO moved to another COB-ID and the rated current read from the
    drive win over the layout assumed before the first frame (drive.eds' own)."""
    t = 1_700_000_000.0 - 1.0
    prelude = (*_sdo(t, 0x1803, 1, 0x4B0), *_sdo(t + 0.01, 0x6075, 0, 2000, upload=True))
    log = tmp_path / "bus.log"
    _synthetic_log(log, 40, drop_sw_at=20, prelude=prelude, motion_cob=0x4B0)
    trace = decode_log(log, default_layout(0x20, 0.01))
    c = trace.columns
    assert len(trace) == 40 and trace.cycles_without_statusword == 1
    assert c["position_rad"][3] == pytest.approx(3 * math.pi / 2)
    assert c["current_actual_A"][30] == pytest.approx(240 / 1000 * 2.0)  # 0x6075 as read: 2 A
    assert c["target_torque_permille"][10] == 250


def test_cleanup_waits_for_a_slow_sdo_answer() -> None:
    """The master's way out reads the statusword by SDO: a drive (or the master's own Python, descheduled
    on a loaded machine or in the VM) answering after 1 s is still read, and the drive seen disabled.
    With python canopen's default 0.3 s (one retry) this read failed: 'NOT seen SWITCH ON DISABLED'."""
    import threading

    from bench.cia402.master import Master
    from bench.paths import EDS_DIR

    drive_id, channel = 0x20, "cia402-slow-sdo"
    drive = can.Bus(interface="virtual", channel=channel)
    stop = threading.Event()

    def answer() -> None:  # expedited upload of 0x6041:00 = 0x0040 (SWITCH ON DISABLED), 1 s late
        while not stop.is_set():
            msg = drive.recv(0.1)
            if msg is None or msg.arbitration_id != 0x600 + drive_id:
                continue
            if msg.data[0] & 0xE0 == 0x20:  # a download (controlword 0) is confirmed at once
                ack = bytes([0x60, msg.data[1], msg.data[2], msg.data[3], 0, 0, 0, 0])
                drive.send(can.Message(arbitration_id=0x580 + drive_id, data=ack, is_extended_id=False))
                continue
            if msg.data[0] & 0xE0 != 0x40 or stop.wait(1.0):
                continue
            data = bytes([0x4B, msg.data[1], msg.data[2], msg.data[3], 0x40, 0x00, 0x00, 0x00])
            drive.send(can.Message(arbitration_id=0x580 + drive_id, data=data, is_extended_id=False))

    th = threading.Thread(target=answer, daemon=True)
    th.start()
    master = Master(channel, "virtual", drive_id, EDS_DIR / "drive.eds", 0.01)
    said: list[str] = []
    try:
        disabled, sw = master.shutdown(said.append)
    finally:
        stop.set()
        master.close()
        th.join()
        drive.shutdown()
    assert sw == 0x0040 and disabled, said
