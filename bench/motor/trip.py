"""What the inverter's trip does to a motor folder's machine, and the refusal of a run whose currents the trip would
drive out of the flux map (the plant would extrapolate the map's edge cells: docs/YOUR_MOTOR.md "When the inverter
trips").

plant.eds Inverter.trip_reaction (scenario key drive.trip_reaction):

* active_short_circuit (the default): the terminals shorted, 0 V.  At a rotor speed w (electrical) the current goes to
  the short-circuit current (a linear machine: id = -psi w^2 Lq / (R^2 + w^2 Ld Lq), iq = -psi w R / (R^2 + w^2 Ld Lq),
  |i| -> psi / Ld at high speed) through a transient that starts where the trip left the current and turns about it
  at about w while it decays with L/R: its peak is up to |i_ss| + |i_trip - i_ss|.  Computed here on the map itself
  (as the plant interpolates it, edge cells extended): d psi/dt = -R i + w (psi_q, -psi_d) integrated in the currents
  (d i/dt = L_inc^-1 d psi/dt) by RK4 from 24 currents on the circle the trip can leave them on (2/sqrt(3) I_trip, the
  dq reach of a per-phase level), over two turns or six L/R, whichever is shorter (the transient's peak is in its
  first turn).  A locked rotor's currents only decay: it never leaves a map that holds the trip level.
* pulses_off: the diodes drive every current to zero within milliseconds and keep it there while the line-to-line
  back-EMF sqrt(3) |psi(0, 0)| w stays below Vdc; above it they rectify, and what they let through stays below the
  short circuit's current (their voltage opposes every current they carry; plant_rt/tests/test_plant_trip_reaction.c
  checks it over speeds and trip states): checked as the short circuit.  Refused on an FMU plant by the plant itself.

The scenario's speed: the largest motor.omega_imposed_rad_s of the run (its [motor] and its events) where the rotor is
held at a speed; 0 locked.  A free rotor's speed is the run's outcome: bounded by the largest torque the map gives
within the trip level plus the load's over the run's duration (a rotor at rest); a run whose bound leaves the map is
not refused but named (TripNote), since the bound is far above what most runs reach."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.motor.fluxmap import FluxMap
from bench.motor.folder import MotorFolder
from bench.scenario.model import ScenarioError

DQ_PER_PHASE = math.sqrt(3.0) / 2.0  # a per-phase level I lets the dq current reach I / DQ_PER_PHASE
DIRECTIONS = 24  # trip states on the circle
H_REL = 0.05  # RK4's step times (w + R / L_min): 0.05 rad a step at most (the peak, taken at the steps, within 0.1 %)
ASC, PULSES_OFF = "active_short_circuit", "pulses_off"


@dataclass(frozen=True)
class ShortCircuit:
    """The short circuit at one speed: the extremes each axis reaches (A), the steady state, whether it leaves the
    map."""

    w_e: float
    id_min: float
    id_max: float
    iq_min: float
    iq_max: float
    id_ss: float
    iq_ss: float
    leaves: bool


@dataclass(frozen=True)
class TripNote:
    """A free rotor whose speed bound would take the reaction out of the map: what the run's summary should name."""

    text: str


def _derivative(fm: FluxMap, R: float, w: float, i: np.ndarray) -> np.ndarray:
    """d(id, iq)/dt with the terminals shorted, on the plant's interpolant (i: (n, 2)): L_inc^-1 (-R i + w (psi_q,
    -psi_d))."""
    e = fm.eval(i[:, 0], i[:, 1])
    pd, pq, ldd, ldq, lqd, lqq = (e[k] for k in ("psi_d_Wb", "psi_q_Wb", "Ldd_H", "Ldq_H", "Lqd_H", "Lqq_H"))
    fd = -R * i[:, 0] + w * pq
    fq = -R * i[:, 1] - w * pd
    det = ldd * lqq - ldq * lqd
    return np.stack([(lqq * fd - ldq * fq) / det, (ldd * fq - lqd * fd) / det], axis=1)


def _steady(fm: FluxMap, R: float, w: float) -> tuple[float, float]:
    """The steady short-circuit current on the map: -R i + w (psi_q, -psi_d) = 0 by Newton's method."""
    Ld, Lq, psi = fm.small_signal()
    den = R * R + w * w * Ld * Lq
    x = np.array([-psi * w * w * Lq / den, -psi * w * R / den])  # the linear machine's: the start
    for _ in range(60):
        e = fm.eval(x[0], x[1])
        f = np.array([-R * x[0] + w * float(e["psi_q_Wb"]), -R * x[1] - w * float(e["psi_d_Wb"])])
        J = np.array(
            [[-R + w * float(e["Lqd_H"]), w * float(e["Lqq_H"])], [-w * float(e["Ldd_H"]), -R - w * float(e["Ldq_H"])]]
        )
        step = np.linalg.solve(J, f)
        x = x - step
        if float(np.abs(step).max()) < 1e-12:
            break
    return float(x[0]), float(x[1])


def short_circuit(fm: FluxMap, R_ohm: float, w_e: float, reach_A: float) -> ShortCircuit:
    """The short circuit at the electrical speed w_e from the trip states on the circle of radius reach_A."""
    idss, iqss = _steady(fm, R_ohm, w_e) if w_e != 0 else (0.0, 0.0)
    a = 2.0 * math.pi * np.arange(DIRECTIONS) / DIRECTIONS
    i = np.stack([reach_A * np.cos(a), reach_A * np.sin(a)], axis=1)
    lo, hi = i.min(axis=0), i.max(axis=0)
    if w_e != 0.0:
        gd, gq = np.meshgrid(fm.id_A, fm.iq_A, indexing="ij")
        e = fm.eval(gd, gq)
        L_min = float(min(e["Ldd_H"].min(), e["Lqq_H"].min()))
        L_max = float(max(e["Ldd_H"].max(), e["Lqq_H"].max()))
        h = H_REL / (abs(w_e) + R_ohm / L_min)
        t_end = min(6.0 * L_max / R_ohm, 2.0 * 2.0 * math.pi / abs(w_e))
        for _ in range(int(math.ceil(t_end / h))):
            k1 = _derivative(fm, R_ohm, w_e, i)
            k2 = _derivative(fm, R_ohm, w_e, i + 0.5 * h * k1)
            k3 = _derivative(fm, R_ohm, w_e, i + 0.5 * h * k2)
            k4 = _derivative(fm, R_ohm, w_e, i + h * k3)
            i = i + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
            lo, hi = np.minimum(lo, i.min(axis=0)), np.maximum(hi, i.max(axis=0))
    tol = 1e-9 * max(abs(fm.id_A[0]), abs(fm.id_A[-1]), abs(fm.iq_A[0]), abs(fm.iq_A[-1]))
    leaves = bool(lo[0] < fm.id_A[0] - tol or hi[0] > fm.id_A[-1] + tol or lo[1] < fm.iq_A[0] - tol)
    leaves = leaves or bool(hi[1] > fm.iq_A[-1] + tol)
    return ShortCircuit(w_e, float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), idss, iqss, leaves)


def highest_speed(fm: FluxMap, R_ohm: float, reach_A: float, w_hi: float) -> float:
    """The highest electrical speed (up to w_hi) at which the short circuit stays in the map (bisection, 2 %)."""
    if not short_circuit(fm, R_ohm, w_hi, reach_A).leaves:
        return w_hi
    lo, hi = 0.0, w_hi
    while hi - lo > 0.02 * hi:
        mid = 0.5 * (lo + hi)
        if short_circuit(fm, R_ohm, mid, reach_A).leaves:
            hi = mid
        else:
            lo = mid
    return lo


def line_emf_per_rad_s(fm: FluxMap) -> float:
    """The line-to-line back-EMF's peak per rad/s electrical at zero current: sqrt(3) |psi(0, 0)|."""
    e = fm.eval(0.0, 0.0)
    return math.sqrt(3.0) * math.hypot(float(e["psi_d_Wb"]), float(e["psi_q_Wb"]))


W_ANY = 1e5  # rad/s electrical: a short circuit that stays in the map this fast stays in it at any speed


def describe(motor: MotorFolder) -> list[str]:
    """What `bench motor check` says of a trip at the folder's trip level (its I_trip_A, else sqrt(3)/2 of where the
    map ends), the winding at its coldest (T_amb_degC): up to which speed each reaction keeps the currents in the
    map."""
    fm, v = motor.map, motor.values
    edge = min(-float(fm.id_A[0]), float(fm.id_A[-1]), -float(fm.iq_A[0]), float(fm.iq_A[-1]))
    trip = float(v.get("I_trip_A", edge * DQ_PER_PHASE))
    if not trip > 0 or edge <= 0:
        return []
    p = int(v["pole_pairs"])
    R = float(v["R_ohm"]) * (
        1.0 + float(v.get("R_alpha_per_K", 0.0)) * (v.get("T_amb_degC", 20.0) - v.get("T_ref_degC", 20.0))
    )
    w_ok = highest_speed(fm, R, trip / DQ_PER_PHASE, W_ANY) / p
    k = line_emf_per_rad_s(fm) * p
    asc = "at any speed" if w_ok * p >= W_ANY else f"up to {w_ok:.4g} rad/s"
    return [
        f"after a trip at {trip:.4g} A a phase: active_short_circuit (the default) keeps the currents in the map "
        f"{asc}; pulses_off keeps them at zero up to Vdc / {k:.4g} V per rad/s (the line back-EMF: {300.0 / k:.4g} "
        "rad/s at 300 V), above it the diodes rectify (checked as the short circuit)",
    ]


# ---------------------------------------------------------------- the scenario's values
def _values(sc: Any, key: str) -> list[float]:
    """A setting's values over the run: at the start (the scenario's last setting of it, a motor folder's first, else
    the motor preset's value, else the EDS default), then every event's."""
    name = key.split(".", 1)[1]
    start = None
    for s in sc.settings:
        if s.key == key:
            start = float(s.value)
    if start is None and sc.preset is not None:
        from bench.scenario.presets import motor_preset

        preset = motor_preset(sc.preset).values.get(name)
        start = None if preset is None else float(preset)
    if start is None:
        start = _eds_default(key)
    return [start, *(float(s.value) for e in sc.events for s in e.settings if s.key == key)]


def _eds_default(key: str) -> float:
    """A scenario key's EDS default (as bench.scenario.parsing.value_at reads it)."""
    from bench.eds import load as load_od
    from bench.scenario.settings import param_tables

    section, name = key.split(".", 1)
    p = param_tables()[section][name]
    var = load_od(p.node)[p.index]
    return float((var[p.subindex] if p.subindex else var).default or 0)


def _names(key: str) -> dict[int, str]:
    from bench.eds import enum

    obj = {"drive.trip_reaction": "Inverter", "motor.mech_mode": "Motor model"}[key]
    return {v: k for k, v in enum("plant", obj, key.split(".", 1)[1]).items()}


def check_trip(where: str, motor: MotorFolder, sc: Any, trip_A: float) -> TripNote | None:
    """Refuse (ScenarioError) a run whose trip reaction drives the currents out of the motor folder's flux map at the
    run's speed; a free rotor whose speed bound would is named (TripNote), not refused."""
    if trip_A <= 0:  # no trip level: the currents are the controller's (check_range asks nothing either)
        return None
    fm = motor.map
    reactions = {_names("drive.trip_reaction")[int(v)] for v in _values(sc, "drive.trip_reaction")}
    modes = {_names("motor.mech_mode")[int(v)] for v in _values(sc, "motor.mech_mode")}
    p = int(_values(sc, "motor.pole_pairs")[0])
    R = min(_values(sc, "motor.R_ohm"))
    alpha = _values(sc, "motor.R_alpha_per_K")[0]
    t_amb, t_ref = min(_values(sc, "motor.T_amb_degC")), _values(sc, "motor.T_ref_degC")[0]
    R = R * (1.0 + alpha * (t_amb - t_ref))  # the coldest winding, the least damping
    vdc = min(_values(sc, "drive.Vdc_V"))
    reach = trip_A / DQ_PER_PHASE
    w_m, how, free = 0.0, "", False
    if "imposed_speed" in modes:
        w_m, how = max(abs(v) for v in _values(sc, "motor.omega_imposed_rad_s")), "motor.omega_imposed_rad_s"
    if "free" in modes:  # what the map's largest torque within the trip level and the load could reach in the run
        w_m, free = max(w_m, _free_bound(sc, motor, p, reach)), True
    w_e = p * w_m
    if w_e == 0.0:
        return None
    k_emf = line_emf_per_rad_s(fm)
    problems = []
    for reaction in sorted(reactions):
        if reaction == PULSES_OFF and k_emf * w_e <= vdc:
            continue  # the diodes stop the currents and keep them at zero
        s = short_circuit(fm, R, w_e, reach)
        if s.leaves:
            problems.append((reaction, s))
    if not problems:
        return None
    reaction, s = problems[0]
    w_ok = highest_speed(fm, R, reach, w_e) / p
    if reaction == PULSES_OFF:
        w_ok = max(w_ok, vdc / k_emf / p)
    if free:
        return TripNote(_free_note(motor, reaction, trip_A, w_ok, vdc, k_emf * p))
    raise ScenarioError(f"{where}: {_message(motor, reaction, s, trip_A, w_m, how, k_emf * w_e, vdc, w_ok)}")


def _free_note(motor: MotorFolder, reaction: str, trip_A: float, w_ok: float, vdc: float, k_emf_m: float) -> str:
    """What a free rotor's summary should say: up to which speed the trip keeps the currents in the map."""
    fm = motor.map
    emf = (
        f" (pulses_off keeps them at zero up to {vdc / k_emf_m:.4g} rad/s, where the line back-EMF reaches Vdc "
        f"{vdc:.4g} V)"
        if reaction == ASC
        else ""
    )
    return (
        f"free rotor: after a trip at {trip_A:.4g} A a phase with drive.trip_reaction = {reaction}, the currents stay "
        f"in the flux map {motor.map_file} (id_A {fm.id_A[0]:g} .. {fm.id_A[-1]:g} A, iq_A {fm.iq_A[0]:g} .. "
        f"{fm.iq_A[-1]:g} A) up to {w_ok:.4g} rad/s{emf}; a trip of a faster rotor makes the plant extrapolate the "
        "map (not refused: a free rotor's speed is the run's own)"
    )


def _free_bound(sc: Any, motor: MotorFolder, p: int, reach: float) -> float:
    """A free rotor at rest, over the run: (largest |Te| of the map within the trip reach + |T_load|) / J * duration."""
    fm = motor.map
    a = np.linspace(0.0, 2.0 * math.pi, 73)
    r = np.linspace(0.0, reach, 17)
    rr, aa = np.meshgrid(r, a)
    idv, iqv = rr * np.cos(aa), rr * np.sin(aa)
    e = fm.eval(idv, iqv)
    te = float(np.abs(1.5 * p * (e["psi_d_Wb"] * iqv - e["psi_q_Wb"] * idv)).max())
    tl = max(abs(v) for v in _values(sc, "motor.T_load_Nm"))
    J = min(_values(sc, "motor.J_kgm2"))
    ts = min(_values(sc, "drive.Ts_s"))
    return (te + tl) / J * sc.periods * ts if J > 0 else math.inf


def _message(
    motor: MotorFolder, reaction: str, s: ShortCircuit, trip_A: float, w_m: float, how: str, emf: float, vdc: float,
    w_ok: float,
) -> str:  # fmt: skip
    fm = motor.map
    worst = []
    if s.id_min < fm.id_A[0] or s.id_max > fm.id_A[-1]:
        worst.append(f"id_A {s.id_min:.4g} .. {s.id_max:.4g} A")
    if s.iq_min < fm.iq_A[0] or s.iq_max > fm.iq_A[-1]:
        worst.append(f"iq_A {s.iq_min:.4g} .. {s.iq_max:.4g} A")
    what = (
        "the terminals shorted (drive.trip_reaction = active_short_circuit, the default)"
        if reaction == ASC
        else f"the switches off (drive.trip_reaction = pulses_off), whose diodes rectify: the line back-EMF "
        f"{emf:.4g} V exceeds Vdc {vdc:.4g} V, and the short circuit bounds what they let through"
    )
    fixes = [f"extend the map to {' and '.join(worst)}"]
    if reaction == ASC:
        fixes.append(
            'choose drive.trip_reaction = "pulses_off" (the diodes stop the currents: the line back-EMF '
            f"{emf:.4g} V stays below Vdc {vdc:.4g} V)"
            if emf <= vdc
            else f'drive.trip_reaction = "pulses_off" does not help here (the line back-EMF {emf:.4g} V exceeds Vdc '
            f"{vdc:.4g} V: the diodes rectify)"
        )
    fixes.append(f"or lower the speed to at most {w_ok:.4g} rad/s")
    return (
        f"the flux map {motor.map_file} covers id_A {fm.id_A[0]:g} .. {fm.id_A[-1]:g} A and iq_A {fm.iq_A[0]:g} .. "
        f"{fm.iq_A[-1]:g} A, but after a trip at {trip_A:.4g} A a phase (drive.I_trip_A) with {what}, at "
        f"{w_m:.4g} rad/s ({how}; {s.w_e:.4g} rad/s electrical) the short-circuit current reaches {', '.join(worst)} "
        f"(steady state id_A {s.id_ss:.4g} A, iq_A {s.iq_ss:.4g} A): the plant would extrapolate the map; "
        + "; ".join(fixes)
    )
