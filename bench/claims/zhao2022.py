"""Zhao 2022 (seed 003): incremental deadbeat control from the bilinear discretisation (Eq. 22/23)
against the conventional forward-Euler predictive law (Eq. 5/6).

Each function runs the real loop (preset zhao2022, 10 kHz) and judges a claim against the closed
loop derived for the exact zero-order-hold plant with the one-period command delay (complex
notation i = id + j iq, derivation in firmware_shim/tests/test_zhao2022_common.h):

    Phi = exp(-(R/L + j w) Ts),  Gam = (1 - Phi)/(R + j w L)
    incremental:  Q(z) = (z - Phi)(z - 1)(z + 1)^2 + Gam K2 z^2 + Gam (K1c - K2),  T(z) = Gam K1c z^2 / Q(z)
                  K1c = R0 + L0/Ts + j w L0,  K2 = 2 L0/Ts
    Euler:        (z^2 - Phi z - Gam a) I = Gam (L0/Ts) R + Gam j w (psi0 - psi),  a = R0 - L0/Ts + j w L0

The paper's Eq. 34 is the Ts -> 0 limit lam (z^2 - 1)^2 + 2 (z^2 - 1) + 1 (lam = L/L0, stable for lam > 3/4).
"""

from __future__ import annotations

import cmath
import math
from typing import Any

import numpy as np

from bench.claims import ClaimResult, run_raw, traced, with_sections
from bench.metrics import error_growth
from bench.scenario import motor_preset

PAPER = "Zhao 2022"
# The motor and the drive: the preset's (plant_rt/core/presets.c: Zhao 2022 Tables 1/2, Ld = Lq, psi from Kt)
MOTOR = motor_preset("zhao2022")
R, L, TS, PP = MOTOR.R_ohm, MOTOR.Lq_H, MOTOR.Ts_s, MOTOR.pole_pairs
PSI = MOTOR.psi_Wb
RATED_DEG_S = 367.72  # Table 2: rated speed, deg/s (the preset's imposed speed, the claims' operating point)
W_RATED = PP * RATED_DEG_S * math.pi / 180  # electrical rad/s
VMAX = MOTOR.Vdc_V / math.sqrt(3.0)


def base(name: str, periods: int, law: str, locked: bool = True, **sections: dict[str, Any]) -> dict[str, Any]:
    raw: dict[str, Any] = {
        "scenario": {"name": name, "periods": periods},
        "motor": {"preset": "zhao2022", "mech_mode": "locked" if locked else "imposed_speed"},
        "drive": {"preset": "ideal"},  # the paper's simulation: no drive losses, exact sensors
        "controller": {"controller": law, "Vmax_V": VMAX},
        "events": [],
    }
    return with_sections(raw, sections)


def plant_terms(Rp: float, Lp: float, w: float) -> tuple[complex, complex]:
    a = Rp / Lp + 1j * w
    phi = cmath.exp(-a * TS)
    return phi, (1 - phi) / (Lp * a)


def q_incremental(Rp: float, Lp: float, R0: float, L0: float, w: float = 0.0) -> np.ndarray:
    phi, gam = plant_terms(Rp, Lp, w)
    k1c, k2 = R0 + L0 / TS + 1j * w * L0, 2 * L0 / TS
    p = np.polymul(np.polymul([1, -phi], [1, -1]), [1, 2, 1]).astype(complex)
    p[2] += gam * k2
    p[4] += gam * (k1c - k2)
    return p


def q_euler(Rp: float, Lp: float, R0: float, L0: float, w: float = 0.0) -> np.ndarray:
    phi, gam = plant_terms(Rp, Lp, w)
    return np.array([1, -phi, -gam * (R0 - L0 / TS + 1j * w * L0)])


def q_paper(lam: float) -> np.ndarray:
    return np.array([lam, 0, -2 * (lam - 1), 0, lam - 1], dtype=complex)


def radius(p: np.ndarray) -> float:
    return float(max(abs(np.roots(p))))


def poly_boundary(poly_of_lam, lo: float = 0.5, hi: float = 1.0) -> float:  # type: ignore[no-untyped-def]
    """Smallest stable lam in [lo, hi] (hi stable, lo unstable), by bisection on the spectral radius."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if radius(poly_of_lam(mid)) < 1:
            hi = mid
        else:
            lo = mid
    return hi


def response_incremental(z: complex, w: float = 0.0) -> complex:
    phi, gam = plant_terms(R, L, w)
    k1c = R + L / TS + 1j * w * L
    return complex(gam * k1c * z * z / np.polyval(q_incremental(R, L, R, L, w), z))


def response_euler(z: complex, w: float = 0.0) -> complex:
    phi, gam = plant_terms(R, L, w)
    return complex(gam * (L / TS) / np.polyval(q_euler(R, L, R, L, w), z))


STEP = 0.05
# The error's envelope (bench/metrics.py error_growth) in a 700-period run whose step comes at period 20: periods
# 200-399 against 500-697, 300 periods apart.
GROWTH_EARLY, GROWTH_LATE = slice(200, 400), slice(500, 698)


def _growth(lam: float, bus: str) -> dict[str, float]:
    """Run the incremental law with L0 = L/lam (locked rotor, 0.05 A step) and measure whether its error decays."""
    raw = base(
        f"zhao2022-stab-{lam:.4f}",
        700,
        "incremental_zhao2022",
        controller={"L_hat_ratio": 1.0 / lam},
        events=[{"at_period": 20, "references": {"iq_ref_A": STEP}}],
    )
    raw["scenario"]["expect"] = ["ok", "diverged"]  # a boundary search runs unstable loops on purpose
    run = run_raw(raw, bus)
    # the error decays (or is down at the loop's float32 floor) and is not a cycle held by the voltage limit
    g = error_growth(run.tr["iq_A"] - run.tr["iq_ref_A"], STEP, GROWTH_EARLY, GROWTH_LATE)
    return {
        "lam": lam,
        "L_hat_ratio": 1.0 / lam,
        "env_early_A": g.early_A,
        "env_late_A": g.late_A,
        "rate_per_period": g.ratio_per_period,
        "stable": g.decays,
        "poly_radius": radius(q_incremental(R, L, R, L / lam)),
        "run_status": run.result.status,
    }


def claim_stability_boundary(bus: str, steps: int = 5) -> ClaimResult:
    """Zhao 2022 Eq. 34-42: stable for L > 3/4 L0; bench: coarse-to-fine bisection of lam = L/L0 over short runs."""
    runs = [_growth(0.8, bus), _growth(0.6, bus)]
    lo, hi = 0.6, 0.8
    if runs[0]["stable"] and not runs[1]["stable"]:
        for _ in range(steps):
            mid = 0.5 * (lo + hi)
            r = _growth(mid, bus)
            runs.append(r)
            if r["stable"]:
                hi = mid
            else:
                lo = mid
    poly = poly_boundary(lambda lam: q_incremental(R, L, R, L / lam))
    poly_tsk = poly_boundary(lambda lam: q_paper(lam))  # Zhao 2022 Eq. 34 (Ts -> 0)
    decided_like_poly = all(r["stable"] == (r["poly_radius"] < 1) for r in runs)
    res = (hi - lo) + 1e-9
    ok_bench = lo - 1e-9 <= poly <= hi + 1e-9 and decided_like_poly
    return ClaimResult(
        PAPER,
        "zhao2022-6",
        "Zhao 2022 Eq. 34-42, Sec. 4.2",
        "the incremental deadbeat loop is stable when L > (3/4) L0",
        {"smallest_stable_L_over_L0": 0.75},
        {
            "bench_boundary_L_over_L0": [lo, hi],
            "polynomial_boundary": poly,
            "eq34_small_Ts_boundary": poly_tsk,
            "runs": runs,
            "R_Ts_over_L": R * TS / L,
        },
        f"bench bisection interval (width {res:.4f}) contains the exact closed-loop polynomial's boundary and every "
        "run's stable/unstable decision agrees with the polynomial's spectral radius; reproduced only if that "
        "boundary is 3/4 within the bisection width",
        bool(ok_bench and abs(poly - 0.75) <= res),
        why_differs=f"With the exact ZOH plant the boundary is L/L0 = {poly:.4f} (bench {lo:.4f}..{hi:.4f}), not "
        "3/4: Zhao 2022 Eq. 34 drops R and R0 (Ts -> 0 with R Ts/L -> 0), but the Table 1 motor has "
        f"R Ts/L = {R * TS / L:.3f}; the paper's polynomial itself gives {poly_tsk:.4f}. So the law is "
        "stable down to L ~ 0.70 L0 on this motor: the paper's 3/4 is conservative here.",
        bench_ok=bool(ok_bench),
        details={"bench_ok": bool(ok_bench)},
    )


def _flux_run(controller: str, ratio: float, bus: str) -> dict[str, np.ndarray]:
    raw = base(
        f"zhao2022-flux-{controller}-{ratio}",
        600,
        controller,
        locked=False,
        controller={"psi_hat_ratio": ratio},
        events=[{"at_period": 300, "references": {"iq_ref_A": 0.04}}],
    )
    return run_raw(raw, bus).tr


def claim_flux_independence(bus: str, wrong: tuple[float, ...] = (0.8, 1.2)) -> ClaimResult:
    """Sec. 4.1: the incremental law has no psi; the conventional law's error follows psi_hat - psi."""
    ratios = (1.0, *wrong)
    inc = {r: _flux_run("incremental_zhao2022", r, bus) for r in ratios}
    eul = {r: _flux_run("predictive_zhao2022", r, bus) for r in wrong}
    inc_dev = max(float(np.max(np.abs(inc[r]["iq_A"] - inc[1.0]["iq_A"]))) for r in wrong)
    out: dict[str, Any] = {"incremental_max_dev_from_matched_A": inc_dev}
    ok = inc_dev < 1e-9
    for r in wrong:
        err = float(np.mean(eul[r]["iq_ref_A"][-50:] - eul[r]["iq_A"][-50:]))
        # derived: i - r = Gam j w (psi0 - psi) / (1 - Phi - Gam a) = j w dpsi Ts / L0 for R0 = R, L0 = L
        pred = -(W_RATED * (r - 1.0) * PSI * TS / L)
        inc_err = float(np.mean(inc[r]["iq_ref_A"][-50:] - inc[r]["iq_A"][-50:]))
        out[f"psi{r}"] = {
            "euler_error_A": err,
            "euler_derived_A": pred,
            "incremental_error_A": inc_err,
            "euler_error_pct_of_step": 100 * err / 0.04,
        }
        ok = ok and abs(err - pred) < 0.02 * abs(pred) and abs(inc_err) < 1e-6
    return ClaimResult(
        PAPER,
        "zhao2022-7",
        "Zhao 2022 Eq. 20-23, Sec. 4.1",
        "the incremental law does not depend on the flux linkage (psi cancels between Zhao 2022 Eq. 20 and "
        "Eq. 21); the conventional law does (Zhao 2022 Eq. 6)",
        {"incremental": "independent of psi_hat", "conventional": "steady-state error with wrong psi_hat"},
        out,
        "incremental: iq identical (< 1e-9 A) for psi_hat = 0.8/1.0/1.2 psi and no steady-state error; Euler: "
        "steady-state error = derived w dpsi Ts/L0 within 2 %",
        bool(ok),
        details={"speed_rad_s_electrical": W_RATED},
    )


def claim_phase_lag(bus: str, f_Hz: float = 95.5, amplitude_A: float = 0.05, cycles: int = 3) -> ClaimResult:
    """Sec. 5.1, Fig. 5/7: sine current reference at 95.5 Hz; phase of iq against iq* for both laws."""
    n_per = 1.0 / (f_Hz * TS)
    n = int(round(cycles * n_per))
    start = 20
    events = [
        {"at_period": start + j, "references": {"iq_ref_A": float(amplitude_A * math.sin(2 * math.pi * f_Hz * j * TS))}}
        for j in range(n)
    ]
    w = 2 * math.pi * f_Hz * TS
    z = cmath.exp(1j * w)
    rows = {}
    ok_model = True
    for ctl, model in (("incremental_zhao2022", response_incremental(z)), ("predictive_zhao2022", response_euler(z))):
        tr = run_raw(base(f"zhao2022-phase-{ctl}", start + n + 2, ctl, events=events), bus).tr
        k = np.arange(n)
        skip = int(round(n_per))  # one cycle of start transient
        sl = slice(start + skip, start + n)
        basis = np.column_stack([np.sin(w * k[skip:]), np.cos(w * k[skip:])])
        cy = np.linalg.lstsq(basis, tr["iq_A"][sl], rcond=None)[0]
        cr = np.linalg.lstsq(basis, tr["iq_ref_A"][sl], rcond=None)[0]
        gain = float(np.hypot(*cy) / np.hypot(*cr))
        lag = -math.degrees(math.atan2(cy[1], cy[0]) - math.atan2(cr[1], cr[0]))
        rows[ctl] = {
            "phase_lag_deg": lag,
            "gain": gain,
            "derived_lag_deg": -math.degrees(cmath.phase(model)),
            "derived_gain": abs(model),
            "two_period_delay_deg": math.degrees(2 * w),
        }
        ok_model = ok_model and abs(lag + math.degrees(cmath.phase(model))) < 0.05 and abs(gain - abs(model)) < 1e-3
    inc, eul = rows["incremental_zhao2022"], rows["predictive_zhao2022"]
    # paper: the improved law follows the reference, the conventional one shows a phase deviation
    paper_like = inc["phase_lag_deg"] < eul["phase_lag_deg"]
    return ClaimResult(
        PAPER,
        "zhao2022-8",
        "Sec. 5.1, Fig. 5, Fig. 7",
        "at 95.5 Hz the incremental law's iq follows the reference, the conventional law's iq shows a phase deviation",
        {"incremental": "follows", "conventional": "phase deviation"},
        rows,
        "both lags = derived T(exp(j w Ts)) within 0.05 deg and gains within 1e-3; reproduced only if the "
        "incremental law lags less than the conventional one",
        bool(ok_model and paper_like),
        why_differs="On the bench both laws lag: the incremental one by exactly the two-period delay it is built "
        f"for ({inc['phase_lag_deg']:.2f} deg, gain {inc['gain']:.4f}), the conventional one by less "
        f"({eul['phase_lag_deg']:.2f} deg, gain {eul['gain']:.4f}) because its uncompensated delay "
        "makes an under-damped loop whose phase at 95.5 Hz partly offsets the delay. The conventional "
        "law's 'deviation' is a deviation from the ideal delayed response (1.6 deg, and gain > 1), not "
        "a larger lag. The paper's figure shows the speed-loop closed system, not the current loop.",
        bench_ok=bool(ok_model),
        details={"model_ok": bool(ok_model)},
    )


SPEED_PDOS = {3: ("Drive status.speed_rad_s", "Drive status.iq_ref_active_A")}
DEG = math.pi / 180.0


def _speed_raw(name: str, law: str, events: list[dict[str, Any]], periods: int) -> dict[str, Any]:
    """Free rotor, speed mode, the same speed PI for both laws (Sec. 5: 'the parameters of the PI
    controller in all experiments are the same')."""
    return base(
        name,
        periods,
        law,
        locked=False,
        motor={"mech_mode": "free"},
        controller={
            "speed_loop_divider": 1,
            "position_bandwidth_Hz": 5.0,
            "speed_bandwidth_Hz": 300.0,
            "iq_limit_A": 0.3,
        },
        references={"mode": 1},
        events=events,
    )


def _speed_lag(tr: dict[str, np.ndarray], ref: np.ndarray, f_Hz: float, start: int) -> tuple[float, float]:
    """(phase lag deg, gain) of the drive's speed estimate against the reference at f, least squares."""
    n = np.arange(len(ref))[start:]
    w = 2 * math.pi * f_Hz * TS
    basis = np.column_stack([np.sin(w * n), np.cos(w * n)])
    y = tr["drive_speed_rad_s"][start:]
    ok = np.isfinite(y)
    cy = np.linalg.lstsq(basis[ok], y[ok], rcond=None)[0]
    cr = np.linalg.lstsq(basis, ref[start:], rcond=None)[0]
    lag = -math.degrees(math.atan2(cy[1], cy[0]) - math.atan2(cr[1], cr[0]))
    return (lag + 180.0) % 360.0 - 180.0, float(np.hypot(*cy) / np.hypot(*cr))


def claim_speed_tracking(bus: str, f_Hz: float = 95.5, amplitude_deg_s: float = 197.72, cycles: int = 4) -> ClaimResult:
    """Fig. 4-11: speed PI + each current law; sine speed reference 95.5 Hz, 197.72 deg/s; then a speed step to
    367.72 deg/s at 0.01 s and the rated load (0.0296 N m) at 0.03 s."""
    per_cycle = 1.0 / (f_Hz * TS)
    start = 50
    periods = start + int(cycles * per_cycle) + 2
    amp = amplitude_deg_s * DEG
    ref = np.zeros(periods)
    events = []
    for k in range(start, periods):
        ref[k] = amp * math.sin(2 * math.pi * f_Hz * (k - start) * TS)
        events.append({"at_period": k, "references": {"speed_ref_rad_s": float(ref[k])}})
    step_events = [
        {"at_period": 100, "references": {"speed_ref_rad_s": RATED_DEG_S * DEG}},
        {"at_period": 300, "motor": {"T_load_Nm": 0.0296}},
    ]
    rows = {}
    with traced(SPEED_PDOS):
        for law in ("incremental_zhao2022", "predictive_zhao2022"):
            sine = run_raw(_speed_raw(f"zhao2022-speed-sine-{law}", law, events, periods), bus)
            lag, gain = _speed_lag(sine.tr, ref, f_Hz, start + int(per_cycle))
            step = run_raw(_speed_raw(f"zhao2022-speed-step-{law}", law, step_events, 500), bus)
            w = step.tr["drive_speed_rad_s"]
            target = RATED_DEG_S * DEG
            before_load = float(np.nanmean(w[280:300]))
            dip = float(target - np.nanmin(w[300:400]))
            after = float(np.nanmean(w[460:499]))
            rows[law] = {
                "sine_lag_deg": lag,
                "sine_gain": gain,
                "speed_before_load_rad_s": before_load,
                "load_dip_rad_s": dip,
                "speed_after_load_rad_s": after,
                "target_rad_s": target,
            }
    inc, eul = rows["incremental_zhao2022"], rows["predictive_zhao2022"]
    tracks = all(abs(r["speed_after_load_rad_s"] - r["target_rad_s"]) < 0.05 * r["target_rad_s"] for r in rows.values())
    return ClaimResult(
        PAPER,
        "zhao2022-8s",
        "Fig. 4-11, Sec. 5.1",
        "with the same speed PI, both current laws track a 95.5 Hz, 197.72 deg/s sine speed reference and reject the "
        "rated load step; the system with the improved (incremental) law tracks better",
        {"incremental": "better tracking", "conventional": "phase deviation"},
        rows,
        "reproduced if both recover the speed after the load (within 5 %) and the incremental law's sine phase lag "
        "is visibly smaller (by 1 deg or more) than the conventional law's; bench check: both track and recover",
        bool(tracks and inc["sine_lag_deg"] <= eul["sine_lag_deg"] - 1.0),
        bench_ok=bool(tracks),
        why_differs=f"Both laws track the sine and reject the load; their speed phase lags differ by "
        f"{abs(inc['sine_lag_deg'] - eul['sine_lag_deg']):.2f} deg only "
        f"({inc['sine_lag_deg']:.2f} vs {eul['sine_lag_deg']:.2f} deg): the speed loop (a 300 Hz PI at "
        "the current rate, the bench's design: the paper gives no gains) hides the difference between "
        "the current loops, whose own lags at 95.5 Hz are 6.88 and 5.28 deg (zhao2022-8). The speed is "
        "the drive's own estimate (angle difference per period).",
    )


ALL = [claim_stability_boundary, claim_flux_independence, claim_phase_lag, claim_speed_tracking]
