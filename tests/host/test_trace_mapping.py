"""Per-period tracing of the controllers' own objects through the C drive node (direct mode).

python `canopen` is the master of the in-process plant + drive (Hil + DirectBus: the same C node
apps and frames as over vcan). It maps "Zhao 2022" entries into the drive's synchronous TPDO3 by
SDO exactly as a scenario's [trace] does, runs the lockstep loop and decodes TPDO3 per period.
The node must accept every EDS entry marked PDOMapping=1 and refuse the others (0x06040041).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator

import canopen
import numpy as np
import pytest
from canopen.sdo.exceptions import SdoAbortedError

from bench.eds import enum
from bench.paths import EDS_DIR
from bench.run.bus.direct import DirectBus, Hil
from bench.run.loop.configure import enable_cia402

PLANT_ID, DRIVE_ID = 0x10, 0x20
SYNC_COB = 0x080
R, L, TS, PP = 48.9, 14e-3, 100e-6, 5  # zhao2022 preset (presets.c)
VMAX = 28.0 / math.sqrt(3.0)
INCREMENTAL_ZHAO2022 = 4
ABORT_NO_MAP = 0x06040041


@pytest.fixture
def nodes() -> Iterator[tuple[Hil, canopen.RemoteNode, canopen.RemoteNode]]:
    hil = Hil(PLANT_ID, DRIVE_ID)
    net = canopen.Network()
    net.bus = DirectBus(hil)
    net.connect()
    plant = canopen.RemoteNode(PLANT_ID, str(EDS_DIR / "plant.eds"))
    drive = canopen.RemoteNode(DRIVE_ID, str(EDS_DIR / "drive.eds"))
    for n in (plant, drive):
        net.add_node(n)
        n.sdo.RESPONSE_TIMEOUT = 5.0
    try:
        yield hil, plant, drive
    finally:
        net.disconnect()


def _configure_zhao(plant: canopen.RemoteNode, drive: canopen.RemoteNode, iq_ref_A: float) -> None:
    """zhao2022 plant (locked rotor, ideal sensors), incremental law with the true model, lockstep wiring."""
    plant.sdo["Motor preset"].raw = "zhao2022"
    ctl = drive.sdo["Controller"]
    ctl["controller"].raw = INCREMENTAL_ZHAO2022
    for name, value in (
        ("R_hat_ohm", R),
        ("Ld_hat_H", L),
        ("Lq_hat_H", L),
        ("psi_hat_Wb", 1.4213 / 7.5),
        ("Vmax_V", VMAX),
        ("Ts_s", TS),
        ("pole_pairs", PP),
    ):
        ctl[name].raw = value
    drive.sdo["References"]["iq_ref_A"].raw = iq_ref_A
    enable_cia402(drive)  # CiA 402: the power stage acts in OPERATION ENABLED only
    for n in (plant, drive):
        n.tpdo.read()
        n.rpdo.read()
    for num in (1, 2):  # measurement: plant TPDO1/2 -> drive RPDO1/2
        m = drive.rpdo[num]
        m.cob_id = plant.tpdo[num].cob_id
        m.enabled = True
        m.save()
    m = plant.rpdo[1]  # voltage command: drive TPDO1 -> plant RPDO1
    m.cob_id = drive.tpdo[1].cob_id
    m.enabled = True
    m.save()


def _map_tpdo3(drive: canopen.RemoteNode, entries: list[tuple[str, str]]) -> int:
    m = drive.tpdo[3]
    m.clear()
    for obj, sub in entries:
        m.add_variable(obj, sub)
    m.trans_type = 1  # synchronous: the values after step k-1, sent at SYNC k
    m.enabled = True
    m.save()
    return int(m.cob_id)


def test_node_refuses_an_unmappable_entry_and_accepts_zhao2022(nodes) -> None:  # type: ignore[no-untyped-def]
    hil, plant, drive = nodes
    drive.tpdo.read()
    with pytest.raises(SdoAbortedError) as exc:
        _map_tpdo3(drive, [("Controller", "Ts_s")])  # PDOMapping=0: a parameter, not a per-period value
    assert exc.value.code == ABORT_NO_MAP
    _map_tpdo3(drive, [("Zhao 2022", "K1_V_A"), ("Zhao 2022", "K2_V_A")])
    mapping = drive.sdo[0x1A02]
    assert mapping[0].raw == 2
    assert mapping[1].raw == 0x2502_01_20 and mapping[2].raw == 0x2502_02_20


def test_zhao2022_limited_traced_per_period(nodes) -> None:  # type: ignore[no-untyped-def]
    """A 0.2 A step asks for K1 * 0.2 = 38 V > Vmax = 16.2 V: `limited` is 1 for the first periods, then 0;
    TPDO3 carries it (and K1) once per period, in step with the voltage command."""
    hil, plant, drive = nodes
    _configure_zhao(plant, drive, iq_ref_A=0.2)
    cob3 = _map_tpdo3(drive, [("Zhao 2022", "limited"), ("Zhao 2022", "K1_V_A")])
    n = 60
    hil.start_recorder(n * 10 + 1000)
    for node in (plant, drive):
        node.nmt.send_command(0x01)
    plant.sdo["Run control"]["run_periods"].raw = n
    assert hil.run(n) == n
    frames = hil.take() if hasattr(hil, "take") else hil.recorded()  # `take` since the bench/run/ refactor
    sync_pos = np.nonzero(frames["cob_id"] == SYNC_COB)[0]
    assert len(sync_pos) == n
    period_of = np.cumsum(frames["cob_id"] == SYNC_COB) - 1  # SYNC index of every frame
    tp3 = np.nonzero(frames["cob_id"] == cob3)[0]
    cmd = np.nonzero(frames["cob_id"] == drive.tpdo[1].cob_id)[0]
    # one TPDO3 per SYNC: sent at SYNC j with the values after current step j-1 ...
    assert np.array_equal(period_of[tp3], np.arange(n))
    # ... and one voltage command per period: v*(k) of step k, after SYNC k
    assert np.array_equal(period_of[cmd], np.arange(n))
    vals = [struct.unpack_from("<Bf", bytes(frames["data"][p][:5])) for p in tp3[1:]]  # steps 0 .. n-2
    limited = np.array([v[0] for v in vals])
    k1 = np.array([v[1] for v in vals])
    v = np.array([struct.unpack_from("<ff", bytes(frames["data"][p][:8])) for p in cmd[: n - 1]])
    v_mag = np.hypot(v[:, 0], v[:, 1])
    print("limited after each step:", "".join(str(x) for x in limited))
    print("|v*| of the first steps:", np.round(v_mag[:6], 3))
    assert set(limited.tolist()) == {0, 1}, limited
    assert limited[0] == 1 and not limited[-20:].any(), limited  # limited by the step, then released
    # the traced flag is that of the same step as the command: |v*| = Vmax exactly where it is set
    assert np.allclose(v_mag[limited == 1], VMAX, rtol=1e-5), v_mag
    assert (v_mag[limited == 0] < VMAX * (1 - 1e-5)).all(), v_mag
    assert np.allclose(k1, R + L / TS, rtol=1e-6), k1  # Eq. 22/23: K1 = R0 + L0/Ts, constant
    # and the drive's own view agrees: the last value by SDO is the last one traced
    assert drive.sdo["Zhao 2022"]["limited"].raw == limited[-1]
    # the plant did not trip (the step is normal operation at the preset's level)
    assert plant.sdo["Run control"]["trip_active"].raw == 0


def _run_diverging(hil, plant, drive, n: int, trip_level_A: float | None):  # type: ignore[no-untyped-def]
    """Zhao 2022 incremental law at L/L0 = 0.68 (< the 0.7015 boundary), voltage limiter OFF (Vmax_V = 0), iq step:
    the loop diverges. Returns (sample index, i_a, i_b, status) per period, the drive's |v*| and trip_active."""
    _configure_zhao(plant, drive, iq_ref_A=0.1)
    ctl = drive.sdo["Controller"]
    for name in ("Ld_hat_H", "Lq_hat_H"):
        ctl[name].raw = L / 0.68
    ctl["Vmax_V"].raw = 0.0
    if trip_level_A is not None:
        plant.sdo["Inverter"]["I_trip_A"].raw = trip_level_A
    hil.start_recorder(n * 10 + 1000)
    for node in (plant, drive):
        node.nmt.send_command(0x01)
    plant.sdo["Run control"]["run_periods"].raw = n
    assert hil.run(n) == n
    frames = hil.take() if hasattr(hil, "take") else hil.recorded()
    m1 = frames[frames["cob_id"] == plant.tpdo[1].cob_id]
    m2 = frames[frames["cob_id"] == plant.tpdo[2].cob_id]
    cmd = frames[frames["cob_id"] == drive.tpdo[1].cob_id]
    ia, ib = (np.array([struct.unpack_from("<ff", bytes(d[:8]))[j] for d in m1["data"]]) for j in (0, 1))
    status = np.array([struct.unpack_from("<fBBH", bytes(d[:8]))[2] for d in m2["data"]])
    v = np.array([struct.unpack_from("<ff", bytes(d[:8])) for d in cmd["data"]])
    return ia, ib, status, np.hypot(v[:, 0], v[:, 1]), plant.sdo["Run control"]["trip_active"].raw


def test_diverging_zhao2022_loop_trips_at_the_preset_level(nodes) -> None:  # type: ignore[no-untyped-def]
    """The zhao2022 preset's default trip (Vdc/R = 0.573 A) stops the runaway early: latched, currents finite
    and back to zero, the drive's command still finite when the plant tripped."""
    hil, plant, drive = nodes
    ia, ib, status, v_mag, trip_active = _run_diverging(hil, plant, drive, 600, None)
    assert abs(plant.sdo["Inverter"]["I_trip_A"].raw - 28.0 / 48.9) < 1e-6  # the preset's level (presets.c)
    k = int(np.argmax(status & 1))
    print(
        f"trip bit from sample {k}; max |i| before {np.max(np.abs(np.r_[ia[:k], ib[:k]])):.3f} A; "
        f"|v*| up to {np.max(v_mag[:k]):.1f} V; i_a at the end {ia[-1]:.2e} A"
    )
    assert trip_active == 1 and 0 < k < 200 and (status[k:] & 1).all()
    assert np.isfinite(ia).all() and np.isfinite(ib).all() and np.isfinite(v_mag[: k + 1]).all()
    assert abs(ia[-1]) < 1e-3 and abs(ib[-1]) < 1e-3  # the bridge is off: the current decays


def test_diverging_zhao2022_loop_overflow_puts_the_drive_in_its_safe_state(nodes) -> None:  # type: ignore[no-untyped-def]
    """With the level off (I_trip_A = 0) the drive's float32 law overflows (inf, then NaN from 0 * inf in its
    inverse Park transform). The drive does not send that command (drive_core.c: a law's non-finite command is
    0 V): it enters its safe state (reason law_output, EMCY 0xFF06) and commands 0 V from then on, so the plant
    never sees a non-finite command and its currents stay finite. (The plant's own refusal of a non-finite
    command is tested in plant_rt/tests/test_node_nonfinite.c and tests/host/test_run_status.py.)"""
    hil, plant, drive = nodes
    ia, ib, status, v_mag, trip_active = _run_diverging(hil, plant, drive, 2400, 0.0)
    assert np.isfinite(v_mag).all()
    k = int(np.flatnonzero(v_mag > 0.0)[-1]) + 1  # 0 V from here on
    print(
        f"0 V from period {k} on (|v*| before: up to {np.max(v_mag[:k]):.3g} V), max |i_b| {np.max(np.abs(ib)):.2e} A"
    )
    assert 100 < k < len(v_mag) and (v_mag[k:] == 0.0).all() and np.max(v_mag[:k]) > 1e6
    assert drive.sdo["Safe state"]["reason"].raw == enum("drive", "Safe state", "reason")["law_output"]
    assert trip_active == 0 and not (status & 1).any()  # the plant got nothing to trip on
    assert np.isfinite(ia).all() and np.isfinite(ib).all()


# ------------------------------------------------------------------ a run's default trace follows its law
# (its record's Trace key in drive.eds, bench/laws.py): each law's live quantities, none of another law's leftovers
def _traces() -> dict[str, dict[int, tuple[str, ...]]]:
    from bench.laws import law_info, law_names

    return {law: law_info(law).trace for law in law_names()}


LAW_RUNS: dict[str, tuple[str, dict[str, float | int | str]]] = {
    "open_loop": ("you2019", {"Vmax_V": 139.0}),
    "pi": ("you2019", {"Vmax_V": 139.0}),
    "deadbeat_you2019": ("you2019", {"Vmax_V": 139.0, "enable": 1}),
    "dpcc_yao2020": ("yao2020_low", {"observer_enable": 1, "R_hat_ratio": 1.5}),
    "incremental_zhao2022": ("zhao2022", {"Vmax_V": VMAX}),
    "predictive_zhao2022": ("zhao2022", {"Vmax_V": VMAX}),
}


def _law_run(controller: str, **over: object):  # type: ignore[no-untyped-def]
    """A locked-rotor step of 1 A (0.1 A on the zhao2022 motor) under `controller`, no [trace]."""
    from bench.run import RunOptions, run_scenario
    from bench.scenario import parse

    preset, ctl = LAW_RUNS[controller]
    step = {"iq_ref_A": 0.1} if preset == "zhao2022" else ({"v_q_open_V": 2.0} if controller == "open_loop" else {})
    raw = {
        "scenario": {"name": f"trace-{controller}", "periods": 400, "expect": ["ok", "diverged", "tripped"]},
        "motor": {"preset": preset, "mech_mode": "locked"},
        "drive": {"preset": "ideal"},
        "controller": {"controller": controller, **ctl},
        "events": [{"at_period": 40, "references": step or {"iq_ref_A": 1.0}}],
        **over,
    }
    sc = parse(raw, f"<{controller}>")
    return sc, run_scenario(sc, RunOptions(bus="direct"), keep_trace=True)


@pytest.mark.parametrize("controller", sorted(LAW_RUNS))
def test_default_trace_follows_the_selected_controller(controller: str) -> None:
    from bench.signals import column_name

    law_traces = _traces()

    sc, res = _law_run(controller)
    own = {column_name(q) for sigs in law_traces[controller].values() for q in sigs}
    others = {column_name(q) for sigs in map(dict.values, law_traces.values()) for s in sigs for q in s} - own
    assert sc.trace == law_traces[controller]
    tr = res.trace
    assert tr is not None
    assert own <= set(tr), sorted(set(tr))
    assert not others & set(tr), sorted(others & set(tr))  # no other law's constant leftovers
    ident = res.summary["identified"]
    assert ident["controller"] == controller
    after = slice(60, None)  # after the step at 40

    def last(col: str) -> float:  # the last value traced (the last period's trace TPDOs never come: NaN)
        v = tr[col]
        return float(v[np.isfinite(v)][-1])

    if controller in ("open_loop", "pi"):  # the drive's own view of the current follows the plant's
        assert np.nanmax(np.abs(tr["drive_iq_A"][after])) > 0.1
        assert np.allclose(tr["drive_iq_A"][:-1], tr["iq_A"][:-1], atol=0.05)  # row k: the step of period k
    if controller == "deadbeat_you2019":
        assert last("K1_active_V_A") == pytest.approx(ident["K1_active_V_A"], rel=1e-6)
        assert np.nanmax(np.abs(tr["det_A2"][after])) > 0 and np.nanmax(np.abs(tr["K1_hat_V_A"][after])) > 0
    if controller == "dpcc_yao2020":  # R_hat 1.5 R: the observer's estimate takes up the mismatch
        for axis in ("d", "q"):
            # the summary reads it after the last step, whose trace never comes: one step later, settled
            assert last(f"Yao_2020_DPCC_p_hat_{axis}_A") == pytest.approx(ident[f"p_hat_{axis}_A"], rel=1e-3, abs=1e-6)
        assert np.nanmax(np.abs(tr["Yao_2020_DPCC_p_hat_q_A"][after])) > 1e-4
        assert last("Yao_2020_DPCC_R_hat_ohm") == pytest.approx(ident["R_hat_ohm"], rel=1e-6) and ident["R_hat_ohm"]
        assert last("Yao_2020_DPCC_L_hat_H") == pytest.approx(ident["L_hat_H"], rel=1e-6) and ident["L_hat_H"]
    if controller == "incremental_zhao2022":
        for k in ("K1_V_A", "K2_V_A"):
            assert np.all(tr[f"Zhao_2022_{k}"][1:-1] == np.float32(ident[k])) and ident[k] > 0
        assert set(np.unique(tr["Zhao_2022_limited"][1:-1])) <= {0.0, 1.0}
    if controller == "predictive_zhao2022":
        assert np.all(tr["Zhao_2022_G_V_A"][1:-1] == np.float32(ident["G_V_A"])) and ident["G_V_A"] > 0


def test_an_explicit_trace_wins_over_the_law_default() -> None:
    law_traces = _traces()

    pdo3 = ["Drive status.iq_ref_active_A", "Drive status.speed_rad_s"]
    sc, res = _law_run("incremental_zhao2022", trace={"pdo3": pdo3})
    assert sc.trace == {3: tuple(pdo3)} != law_traces["incremental_zhao2022"]
    assert res.trace is not None and "drive_iq_ref_active_A" in res.trace and "Zhao_2022_K1_V_A" not in res.trace


def test_every_default_trace_fits_its_tpdo() -> None:
    """Each law's default is checked as a scenario's [trace] is (drive.eds names, PDO-mappable, at most
    8 bytes a TPDO); every law of drive.eds has one."""
    from bench.eds import enum

    law_traces = _traces()
    from bench.scenario.trace import trace_table

    assert set(law_traces) == set(enum("drive", "Controller", "controller"))
    for law, pdos in law_traces.items():
        assert set(pdos) <= {3, 4}
        assert trace_table(law, {f"pdo{n}": list(s) for n, s in pdos.items()}) == pdos


def test_default_trace_is_the_law_of_period_0() -> None:
    """The law the run starts with: the EDS default without a setting, the [controller] setting, then a
    period-0 event (written after it, before the PDOs are mapped); a later switch leaves the mapping."""
    law_traces = _traces()
    from bench.scenario import parse

    def trace(**raw: object) -> dict[int, tuple[str, ...]]:
        return parse({"scenario": {"name": "t", "periods": 100}, **raw}, "<t>").trace

    assert trace() == law_traces["deadbeat_you2019"]  # drive.eds Controller.controller DefaultValue=2
    assert trace(controller={"controller": "pi"}) == law_traces["pi"]
    at0 = [{"at_period": 0, "controller": {"controller": "predictive_zhao2022"}}]
    assert trace(controller={"controller": "pi"}, events=at0) == law_traces["predictive_zhao2022"]
    later = [{"at_period": 50, "controller": {"controller": "predictive_zhao2022"}}]
    assert trace(controller={"controller": "pi"}, events=later) == law_traces["pi"]
