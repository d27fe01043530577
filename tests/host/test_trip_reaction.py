"""What the inverter does once tripped (plant.eds Inverter.trip_reaction, scenario key drive.trip_reaction; issue 52
item 4; docs/YOUR_MOTOR.md "When the inverter trips"), through the bench's direct mode, each reaction against a
calculation written here: the active short circuit at a turning rotor against the linear PMSM's closed-form
transient and steady short-circuit current, the pulses off on a locked rotor against the piecewise RL solution with
the diodes' voltages (three phases, then two, then none: the currents reach zero in finite time and stay there), at
a speed whose line back-EMF stays below Vdc (the currents stay at zero) and above it (the diodes rectify); and the
motor folder's check (bench/motor/trip.py): a flux map the short circuit leaves at the run's speed is refused,
naming the file, the speed, the currents, the map's range and what to do; its short circuit on a tabulated linear
map is the closed form's.  The C core's own test: plant_rt/tests/test_plant_trip_reaction.c."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.eds import bits, enum
from bench.motor.fluxmap import FluxMap
from bench.motor.trip import TripNote, describe, short_circuit
from bench.paths import REPO
from bench.pytest_plugin.fixture import HilRunner
from bench.scenario import ScenarioError, parse

# You 2019's motor (the preset you2019: plant_rt/core/presets.c Table A1), as the plant holds it: REAL32 parameters
R_OHM, LD_H, LQ_H, PSI_WB, P, TS_S, VDC_V = (
    float(np.float32(v)) for v in (1.4, 4.46e-3, 4.54e-3, 0.042, 5, 55e-6, 300)
)
NX, NY = np.array([1.0, -0.5, -0.5]), np.array([0.0, math.sqrt(3) / 2, -math.sqrt(3) / 2])
TRIP = bits("plant", "Measurement", "status")["trip"]
EXAMPLES = REPO / "examples" / "motors"
FLOAT32_A = 2e-6  # the samples are REAL32: 1e-6 A spacing at 8 A, and the trip state is read from them


def scenario(mech: dict[str, Any], reaction: str, periods: int, **drive: Any) -> dict[str, Any]:
    """You 2019's deadbeat law driving iq to 8 A at period 20 against a 5 A trip level, the inverter ideal."""
    return {
        "scenario": {"name": f"trip-{reaction}", "periods": periods, "expect": ["tripped", "diverged", "ok"]},
        "motor": {"preset": "you2019", **mech},
        "drive": {"preset": "ideal", "I_trip_A": 5.0, "trip_reaction": reaction, **drive},
        "controller": {"controller": "deadbeat_you2019", "Vmax_V": 139.0},
        "events": [{"at_period": 20, "references": {"iq_ref_A": 8.0}}],
    }


def tripped_at(run: Any) -> int:
    """The first sample whose status carries the trip: the state the reaction starts from."""
    k = np.flatnonzero(run["status"].astype(int) & TRIP)
    assert len(k), "the run did not trip"
    return int(k[0])


def dq(ia: np.ndarray, ib: np.ndarray, th_e: np.ndarray) -> np.ndarray:
    """Park of the phase currents at the electrical angle."""
    al, be = ia, (ia + 2.0 * ib) / math.sqrt(3.0)
    c, s = np.cos(th_e), np.sin(th_e)
    return np.stack([c * al + s * be, -s * al + c * be], axis=-1)


def expm2(A: np.ndarray, t: float) -> np.ndarray:
    """exp(A t) of a 2 x 2 matrix in closed form (e^(m t) (f0 I + f1 (A - m I)))."""
    m = 0.5 * np.trace(A)
    q = 0.25 * (A[0, 0] - A[1, 1]) ** 2 + A[0, 1] * A[1, 0]
    if q < 0:
        mu = math.sqrt(-q)
        f0, f1 = math.cos(mu * t), math.sin(mu * t) / mu
    else:
        mu = math.sqrt(q)
        f0, f1 = (math.cosh(mu * t), math.sinh(mu * t) / mu) if mu > 0 else (1.0, t)
    return math.exp(m * t) * (f0 * np.eye(2) + f1 * (A - m * np.eye(2)))


# ---------------------------------------------------------------- the reactions through the bench
def test_active_short_circuit_at_speed_is_the_closed_form(hil_run: HilRunner) -> None:
    """At 100 rad/s (500 rad/s electrical) the currents after the trip are i_ss + exp(A t)(i_trip - i_ss), A the
    linear PMSM's with 0 V, and end at the steady short-circuit current id = -psi w^2 Lq / (R^2 + w^2 Ld Lq),
    iq = -psi w R / (R^2 + w^2 Ld Lq) (on the sampled phase currents: REAL32)."""
    wm = 100.0
    run = hil_run(scenario({"mech_mode": "imposed_speed", "omega_imposed_rad_s": wm}, "active_short_circuit", 2400))
    k0 = tripped_at(run)
    w = P * wm
    th = w * TS_S * np.arange(len(run.traces))  # the rotor's angle, from rest at 0
    i = dq(run["i_a_A"].astype(float), run["i_b_A"].astype(float), th)
    A = np.array([[-R_OHM / LD_H, w * LQ_H / LD_H], [-w * LD_H / LQ_H, -R_OHM / LQ_H]])
    den = R_OHM**2 + w * w * LD_H * LQ_H
    iss = np.array([-PSI_WB * w * w * LQ_H / den, -PSI_WB * w * R_OHM / den])
    ref = np.array([iss + expm2(A, n * TS_S) @ (i[k0] - iss) for n in range(len(i) - k0)])
    err = float(np.abs(i[k0:] - ref).max())
    end = f"({i[-1][0]:.6f}, {i[-1][1]:.6f}) A"
    print(f"tripped at period {k0}, from ({i[k0][0]:.4f}, {i[k0][1]:.4f}) A: error {err:.3g} A; the end {end}, the "
          f"steady short-circuit current ({iss[0]:.6f}, {iss[1]:.6f}) A")  # fmt: skip
    assert err < FLOAT32_A, f"the short circuit differs from the closed form by {err:.3g} A"
    assert np.abs(i[-1] - iss).max() < FLOAT32_A, "the run does not end at the steady short-circuit current"
    assert np.abs(run["v_alpha_V"][k0:]).max() > 1.0  # the drive still commands: the plant does not apply it


def locked_pulses_off(i0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A locked rotor at theta_e = 0 (d on phase a) with the switches off, from the dq current i0: the phase
    currents at the times t, written from the circuit.  Each conducting phase's terminal sits at -sign(i) Vdc/2:
    with three conducting, each axis is an RL step response toward v/R (v the terminals' amplitude-invariant
    Clarke); when one phase's current reaches zero it is off and the other two carry one current s along their
    line, L_eff s' = -R s - Vdc/sqrt(3) sign(s) (L_eff = Ld or Lq or between: the line's direction in dq), which
    reaches zero at a finite time; then nothing flows (no back-EMF)."""
    out = np.zeros((len(t), 3))
    iab = i0.copy()  # alpha-beta = dq at theta_e = 0
    t0, sig, done = 0.0, np.sign(NX * iab[0] + NY * iab[1]), False
    off = [x for x in range(3) if sig[x] == 0]
    for n, tn in enumerate(t):
        while not done:
            if not off:  # three conduct: v fixed, dq decoupled
                v = (2 / 3) * np.array([np.sum(-sig * VDC_V / 2 * NX), np.sum(-sig * VDC_V / 2 * NY)])
                tau = np.array([LD_H, LQ_H]) / R_OHM

                def cur(
                    tt: float, v: np.ndarray = v, tau: np.ndarray = tau, base: np.ndarray = iab, t0: float = t0
                ) -> Any:
                    return v / R_OHM + (base - v / R_OHM) * np.exp(-(tt - t0) / tau)

                # the first phase current to reach zero (bisection on each)
                first, t_hit = None, math.inf
                for x in range(3):
                    f = lambda tt, x=x: sig[x] * (NX[x] * cur(tt)[0] + NY[x] * cur(tt)[1])  # noqa: E731
                    hi = t0 + 1e-6
                    while f(hi) > 0 and hi < t0 + 1.0:
                        hi = t0 + 2 * (hi - t0)
                    if f(hi) > 0:
                        continue
                    lo = t0
                    for _ in range(200):
                        mid = 0.5 * (lo + hi)
                        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
                    if hi < t_hit:
                        first, t_hit = x, hi
                if tn < t_hit:
                    ia = cur(tn)
                    out[n] = NX * ia[0] + NY * ia[1]
                    break
                iab = cur(t_hit)
                iab = iab - (NX[first] * iab[0] + NY[first] * iab[1]) * np.array([NX[first], NY[first]])
                t0, off = t_hit, [first]
                sig[first] = 0
            else:  # one off (z): the pair's current along d, perpendicular to n_z
                z = off[0]
                d = np.array([-NY[z], NX[z]])
                s0 = float(d @ iab)
                leff = LD_H * d[0] ** 2 + LQ_H * d[1] ** 2
                vline = float(d @ ((2 / 3) * np.array([np.sum(-sig * VDC_V / 2 * NX), np.sum(-sig * VDC_V / 2 * NY)])))
                t_end = t0 + leff / R_OHM * math.log((s0 - vline / R_OHM) / (-vline / R_OHM))
                if tn < t_end:
                    s = vline / R_OHM + (s0 - vline / R_OHM) * math.exp(-(tn - t0) * R_OHM / leff)
                    out[n] = NX * s * d[0] + NY * s * d[1]
                    break
                done = True
        if done:
            out[n] = 0.0
    return out


def test_pulses_off_on_a_locked_rotor_stops_the_currents_in_finite_time(hil_run: HilRunner) -> None:
    """The rotor locked at 0: after the trip each phase's current falls against Vdc/2 through its diode, the
    first to reach zero stops, the other two fall together until they do: the piecewise solution written here,
    to the samples' REAL32 resolution, and exactly zero from there on."""
    run = hil_run(scenario({"mech_mode": "locked"}, "pulses_off", 200))
    k0 = tripped_at(run)
    ia, ib = run["i_a_A"].astype(float), run["i_b_A"].astype(float)
    i0 = dq(ia[k0 : k0 + 1], ib[k0 : k0 + 1], np.zeros(1))[0]
    ref = locked_pulses_off(i0, TS_S * np.arange(len(ia) - k0))
    err = max(np.abs(ia[k0:] - ref[:, 0]).max(), np.abs(ib[k0:] - ref[:, 1]).max())
    zero = k0 + int(np.flatnonzero(np.all(ref == 0.0, axis=1))[0])
    print(f"tripped at period {k0} from ({i0[0]:.4f}, {i0[1]:.4f}) A: error {err:.3g} A; all currents zero from "
          f"period {zero} ({(zero - k0) * TS_S * 1e3:.3f} ms after the trip)")  # fmt: skip
    assert err < FLOAT32_A, f"the diodes' decay differs from the piecewise solution by {err:.3g} A"
    assert zero - k0 < 10 and not np.any(ia[zero:]) and not np.any(ib[zero:]), "the currents do not stay at zero"


def test_pulses_off_at_speed_stays_at_zero_below_vdc_and_rectifies_above(hil_run: HilRunner) -> None:
    """At 100 rad/s the line back-EMF sqrt(3) psi w = 36 V: below 300 V the currents reach zero and stay there;
    with Vdc at 30 V the diodes rectify: a current flows for good, pulsed, below the short-circuit current."""
    mech = {"mech_mode": "imposed_speed", "omega_imposed_rad_s": 100.0}
    emf = math.sqrt(3) * PSI_WB * P * 100.0
    below = hil_run(scenario(mech, "pulses_off", 400), name="below")
    k0 = tripped_at(below)
    ia, ib = below["i_a_A"], below["i_b_A"]
    nz = np.flatnonzero((ia != 0) | (ib != 0))
    print(f"line back-EMF {emf:.1f} V < 300 V: tripped at {k0}, the last current at period {nz[-1]}")
    assert nz[-1] < k0 + 10, "the currents do not reach zero within 10 periods"
    above = hil_run(scenario(mech, "pulses_off", 1200, Vdc_V=30.0, mod_limit="none"), name="above")
    k1 = tripped_at(above)
    i = dq(above["i_a_A"].astype(float), above["i_b_A"].astype(float), P * 100.0 * TS_S * np.arange(len(above.traces)))
    tail = np.hypot(i[-400:, 0], i[-400:, 1])
    w = P * 100.0
    iss = PSI_WB * w / math.sqrt(R_OHM**2 + (w * LD_H) ** 2)  # about the short-circuit current's magnitude
    mean_id = i[-400:, 0].mean()
    print(f"line back-EMF {emf:.1f} V > 30 V: tripped at {k1}; the last 400 periods: |i| {tail.min():.3f} .. "
          f"{tail.max():.3f} A, mean id {mean_id:.3f} A (the short circuit's |i| ~ {iss:.3f} A)")  # fmt: skip
    assert tail.max() > 0.1 and tail.max() < iss, "no rectified current, or more than the short circuit's"
    assert i[-400:, 0].mean() < 0, "the rectified current does not weaken the field (id < 0)"


# ---------------------------------------------------------------- the motor folder's check (bench/motor/trip.py)
def parsed(toml: Path, motor: Path, **keys: Any) -> Any:
    raw = tomllib.loads(toml.read_text())
    raw.setdefault("motor", {})["folder"] = str(motor)
    for key, value in keys.items():
        section, name = key.split("__")
        raw.setdefault(section, {})[name] = value
    return parse(raw, str(toml))


def check(sc: Any) -> Any:
    from bench.motor.settings import check_range
    from bench.scenario.parsing import _trip_level

    return check_range(sc.source, sc.motor_folder, _trip_level(sc), sc)


def test_a_map_the_short_circuit_leaves_at_the_runs_speed_is_refused() -> None:
    """Yao 2020's identification (133 Hz electrical) on the example map (+-16 A): the short circuit after a trip
    leaves the map: refused, naming the file, the speed, the currents, the range and the three ways out; with
    pulses_off (the line back-EMF 174 V < 300 V) it runs; a locked rotor always does."""
    yao = REPO / "scenarios" / "yao2020_identification.toml"
    with pytest.raises(ScenarioError) as e:
        check(parsed(yao, EXAMPLES / "saturating_yao2020"))
    msg = str(e.value)
    print(msg)
    for part in (
        "saturating_yao2020/flux_map.csv covers id_A -16 .. 16 A and iq_A -16 .. 16 A",
        "drive.trip_reaction = active_short_circuit, the default",
        "at 209.4 rad/s (motor.omega_imposed_rad_s; 837.5 rad/s electrical)",
        "the plant would extrapolate the map; extend the map to id_A",
        'choose drive.trip_reaction = "pulses_off" (the diodes stop the currents: the line back-EMF 174.1 V stays '
        "below Vdc 300 V)",
        "or lower the speed to at most",
    ):
        assert part in msg, f"{part!r} not in the refusal"
    assert check(parsed(yao, EXAMPLES / "saturating_yao2020", drive__trip_reaction="pulses_off")) is None
    step = REPO / "scenarios" / "you2019_step.toml"
    assert check(parsed(step, EXAMPLES / "saturating_you2019")) is None  # locked


def test_pulses_off_above_the_back_emf_is_checked_as_the_short_circuit() -> None:
    """At 1000 rad/s the example's line back-EMF (364 V) exceeds 300 V: the diodes rectify, bounded by the short
    circuit, which leaves the map: refused, saying so; a speed change in an event counts; a free rotor is named,
    not refused (its speed is the run's own)."""
    step = REPO / "scenarios" / "you2019_step.toml"
    fast = {"motor__mech_mode": "imposed_speed", "motor__omega_imposed_rad_s": 1000.0}
    with pytest.raises(ScenarioError, match=r"whose diodes rectify: the line back-EMF 363.7 V exceeds Vdc 300 V"):
        check(parsed(step, EXAMPLES / "saturating_you2019", drive__trip_reaction="pulses_off", **fast))
    sc = parsed(step, EXAMPLES / "saturating_you2019", motor__mech_mode="imposed_speed")
    raw = dict(sc.raw)
    raw["events"] = [*raw.get("events", []), {"at_period": 100, "motor": {"omega_imposed_rad_s": 300.0}}]
    with pytest.raises(ScenarioError, match=r"at 300 rad/s \(motor.omega_imposed_rad_s"):
        check(parse(raw, str(step)))
    note = check(parsed(step, EXAMPLES / "saturating_you2019", motor__mech_mode="free"))
    assert isinstance(note, TripNote) and "not refused: a free rotor's speed is the run's own" in note.text
    print(note.text)


def test_the_short_circuit_on_a_linear_map_is_the_closed_form() -> None:
    """short_circuit() integrates the map (RK4 on the interpolant): on a map tabulating the linear machine wide
    enough to hold it, its extremes are those of i_ss + exp(A t)(i0 - i_ss) over the trip circle, and its steady
    state the closed form's."""
    g = np.linspace(-60.0, 60.0, 13)
    idg, iqg = np.meshgrid(g, g, indexing="ij")
    fm = FluxMap(g, g, LD_H * idg + PSI_WB, LQ_H * iqg)
    reach = 12.0 / (math.sqrt(3) / 2)
    for wm in (20.0, 100.0, 400.0):
        w = P * wm
        s = short_circuit(fm, R_OHM, w, reach)
        A = np.array([[-R_OHM / LD_H, w * LQ_H / LD_H], [-w * LD_H / LQ_H, -R_OHM / LQ_H]])
        den = R_OHM**2 + w * w * LD_H * LQ_H
        iss = np.array([-PSI_WB * w * w * LQ_H / den, -PSI_WB * w * R_OHM / den])
        a = 2 * math.pi * np.arange(24) / 24
        i0 = reach * np.stack([np.cos(a), np.sin(a)], axis=1)
        t_end = min(6 * LQ_H / R_OHM, 4 * math.pi / w)
        E = np.array([expm2(A, t) for t in np.linspace(0.0, t_end, 4000)])  # (4000, 2, 2)
        tr = iss + np.einsum("tij,nj->nti", E, i0 - iss)
        ref = (tr[..., 0].min(), tr[..., 0].max(), tr[..., 1].min(), tr[..., 1].max())
        got = (s.id_min, s.id_max, s.iq_min, s.iq_max)
        err = max(abs(x - y) for x, y in zip(got, ref, strict=True))
        print(f"{wm} rad/s: extremes {np.round(got, 4)} vs {np.round(ref, 4)} (error {err:.2g} A), steady state "
              f"({s.id_ss:.6f}, {s.iq_ss:.6f}) vs ({iss[0]:.6f}, {iss[1]:.6f}) A")  # fmt: skip
        # the peak is taken at RK4's steps, 0.05 rad of the turn apart: r (0.025)^2 / 2 = 3e-4 r at most
        assert err < 5e-4 * max(abs(x) for x in ref) and not s.leaves
        assert abs(s.id_ss - iss[0]) < 1e-9 and abs(s.iq_ss - iss[1]) < 1e-9


def test_bench_motor_check_names_the_speeds_and_the_setting_is_the_eds_enumeration() -> None:
    """describe() (for `bench motor check`) names up to which speed each reaction keeps the example's currents in
    its map; the setting is plant.eds Inverter.trip_reaction, active_short_circuit by default."""
    from bench.motor import load

    line = describe(load(EXAMPLES / "saturating_yao2020"))[0]
    print(line)
    assert "active_short_circuit (the default) keeps the currents in the map up to 7" in line
    assert "pulses_off keeps them at zero up to Vdc / 0.8314 V per rad/s" in line
    assert enum("plant", "Inverter", "trip_reaction") == {"active_short_circuit": 0, "pulses_off": 1}
    sc = parse({"scenario": {"name": "x", "periods": 10}, "drive": {"trip_reaction": "pulses_off"}}, "<x>")
    assert [(s.key, s.value) for s in sc.settings if s.key == "drive.trip_reaction"] == [("drive.trip_reaction", 1)]
