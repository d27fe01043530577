"""Yao 2020 (seed 001): DPCC with a sliding-mode disturbance observer and R/L identification.

Each function runs the real loop (plant emulator + drive over the CANopen frames, presets
yao2020_low / yao2020_high, rotor driven at the rated electrical frequency) and judges one
claim of Section V-VI against values derived from the fully discretised model (Eq. 5-7):
x = exp(-R T/L), y = (1 - x)/R, G2 = (x - exp(j w T))/(R + j w L); the paper's numbers are
reported beside them.

The estimator gains are raised above Table III (the factor is reported in every result) so
that an identification sequence fits in a few thousand periods: the convergence time scales
as 1/k (Eq. 44, claim yao2020-3), the converged values are set by the dead zones, not the gains.
"""

from __future__ import annotations

import cmath
import math
from typing import Any

import numpy as np

from bench.claims import ClaimResult, run_raw, traced

PAPER = "Yao 2020"
OBJ = "Yao 2020 DPCC"
COL = "Yao_2020_DPCC_"
T = 100e-6
MOTORS = {  # preset: (electrical frequency Hz, pole pairs, R, L, Vdc, iq operating point)
    "yao2020_low": (133.3, 4, 2.2, 5.5e-3, 300.0, 4.0),
    "yao2020_high": (1330.0, 1, 0.045, 24e-6, 48.0, 10.0),
}
# TPDO3/4 of the drive mapped to the identification (instead of the You 2019 signals)
IDENT_PDOS = {
    3: (f"{OBJ}.R_hat_ohm", f"{OBJ}.L_hat_H"),
    4: (f"{OBJ}.ident_state", f"{OBJ}.progress", f"{OBJ}.L_converged", f"{OBJ}.R_converged", f"{OBJ}.abort_reason"),
}
TIME_PDOS = {3: (f"{OBJ}.R_hat_ohm", f"{OBJ}.L_hat_H"), 4: (f"{OBJ}.t_L_conv_s", f"{OBJ}.t_R_conv_s")}
RLS_PDOS = {3: (f"{OBJ}.R_hat_ohm", f"{OBJ}.L_hat_H"), 4: (f"{OBJ}.rls_R_hat_ohm", f"{OBJ}.rls_L_hat_H")}


def base(name: str, preset: str, periods: int, **sections: dict[str, Any]) -> dict[str, Any]:
    """Ideal sensors and inverter, rotor at the rated electrical frequency, Vmax = Vdc/sqrt(3)."""
    f_e, pp, _, _, vdc, iq0 = MOTORS[preset]
    raw: dict[str, Any] = {
        "scenario": {"name": name, "periods": periods},
        "motor": {"preset": preset, "mech_mode": "imposed_speed", "omega_imposed_rad_s": 2 * math.pi * f_e / pp},
        "drive": {"t_dead_s": 0.0, "encoder_lines": 0, "adc_noise_std_A": 0.0, "adc_lsb_A": 0.0},
        # speed estimate every period: at 1.33 kHz with one pole pair the rotor turns 1.06 times in the
        # default 8-period speed-loop interval (the encoder difference would alias)
        "controller": {"controller": "dpcc_yao2020", "Vmax_V": vdc / math.sqrt(3.0), "speed_loop_divider": 1},
        "references": {"iq_ref_A": iq0},
        "events": [],
    }
    for key, value in sections.items():
        if key == "events":
            raw["events"] = value
        else:
            raw.setdefault(key, {}).update(value)
    return raw


def xy(R: float, L: float) -> tuple[float, float]:
    x = math.exp(-R * T / L)
    return x, (1.0 - x) / R


def g2(R: float, L: float, w: float) -> complex:
    x, _ = xy(R, L)
    return (x - cmath.exp(1j * w * T)) / (R + 1j * w * L)


def steady_state_no_observer(
    R: float, L: float, Rh: float, Lh: float, psi: float, psih: float, w: float, r: complex
) -> complex:
    """Conventional DPCC (observer off, p_hat = F_hat e(psi_hat)) in steady state, derived from Yao 2020 Eq. 7/12:
    i (1 - x e) = (y/y_hat)(r (1 - x_hat e) - p_hat) + p,  e = exp(-j w T), p = e G2 j w psi."""
    x, y = xy(R, L)
    xh, yh = xy(Rh, Lh)
    e = cmath.exp(-1j * w * T)
    p = e * g2(R, L, w) * 1j * w * psi
    ph = e * g2(Rh, Lh, w) * 1j * w * psih
    return ((y / yh) * (r * (1 - xh * e) - ph) + p) / (1 - x * e)


def first_sample_error(R: float, L: float, Rh: float, Lh: float) -> float:
    """e(k0+2)/dr of a reference step with the observer tracking p (Yao 2020 Eq. 20): y/y_hat - 1."""
    return xy(R, L)[1] / xy(Rh, Lh)[1] - 1.0


def dM_gain(R: float, L: float, w: float, did: float, axis: str) -> float:
    """Loop gain of the integral estimators at the fixed point (derived from Yao 2020 Eq. 26-29):
    dM = did (Z_hat/Zd_hat)(Zd - Zd_hat), Zd = (exp(j w T) - x)/y; d(dM_q)/dL_hat or d(dM_d)/dR_hat."""

    def zd(Rx: float, Lx: float) -> complex:
        x, y = xy(Rx, Lx)
        return (cmath.exp(1j * w * T) - x) / y

    def dM(Rh: float, Lh: float) -> complex:
        return did * (Rh + 1j * w * Lh) / zd(Rh, Lh) * (zd(R, L) - zd(Rh, Lh))

    if axis == "L":
        return abs(dM(R, L * (1 + 1e-6)).imag / (L * 1e-6))
    return abs(dM(R * (1 + 1e-6), L).real / (R * 1e-6))


def step_error(tr: dict[str, np.ndarray], col: str, at: int, dr: float, n: int = 60) -> dict[str, float]:
    """e(k0+2)/dr, max |e|/dr from k0+2 and periods to stay within 2 %."""
    ref = tr[col + "_ref_A"] if col + "_ref_A" in tr else None
    i = tr[col + "_A"]
    target = float(ref[at]) if ref is not None else float("nan")
    e = (i[at : at + n] - target) / dr
    out = np.nonzero(np.abs(e[2:]) > 0.02)[0]
    return {
        "e_k2": float(e[2]),
        "max_abs_e": float(np.max(np.abs(e[2:]))),
        "periods_to_2pct": int(out[-1] + 3) if len(out) else 2,
    }


GAIN_X = 10.0  # estimator gains x Table III (low-frequency motor)


def claim_observer(bus: str) -> ClaimResult:
    """Fig. 10(a): L_hat = 1.5 L, R_hat = 1.5 R at 133.3 Hz; steady-state error with the observer off / on."""
    preset = "yao2020_low"
    f_e, pp, R, L, _, iq0 = MOTORS[preset]
    w = 2 * math.pi * f_e
    ss = {}
    for obs in (0, 1):
        raw = base(
            f"yao2020-ss-obs{obs}",
            preset,
            600,
            controller={"R_hat_ratio": 1.5, "L_hat_ratio": 1.5, "observer_enable": obs},
        )
        tr = run_raw(raw, bus).tr
        ss[obs] = complex(float(np.mean(tr["id_A"][-100:])), float(np.mean(tr["iq_A"][-100:])))
    psi = 0.12
    pred_off = steady_state_no_observer(R, L, 1.5 * R, 1.5 * L, psi, psi, w, complex(0, iq0))
    err_off, err_on = abs(ss[0] - 1j * iq0), abs(ss[1] - 1j * iq0)
    return ClaimResult(
        PAPER,
        "yao2020-1a",
        "Fig. 10(a), Yao 2020 Eq. 13-20",
        "with L_hat = 1.5 L and R_hat = 1.5 R the disturbance observer removes the steady-state current error",
        "tracking error gradually eliminated",
        {
            "error_observer_off_A": err_off,
            "derived_error_observer_off_A": abs(pred_off - 1j * iq0),
            "iq_observer_off_A": ss[0].imag,
            "error_observer_on_A": err_on,
        },
        "observer off: error = derived closed form within 1 %; observer on: error < 1 mA",
        bool(abs(err_off - abs(pred_off - 1j * iq0)) < 0.01 * abs(pred_off - 1j * iq0) and err_on < 1e-3),
    )


def claim_low_frequency(bus: str) -> list[ClaimResult]:
    """Fig. 10: L_hat = 1.5 L, R_hat = 1.5 R at 133.3 Hz; identification (-2 A), deadbeat after."""
    preset = "yao2020_low"
    f_e, pp, R, L, _, iq0 = MOTORS[preset]
    w = 2 * math.pi * f_e
    res: list[ClaimResult] = []
    # one run: step before identification, identification, steps after
    kx = {"kL_low_H_Vs": 0.005 * GAIN_X, "kR_low_ohm_Vs": 4.0 * GAIN_X}
    s1, s1b, start, s2, s2b, s3 = 300, 500, 800, 4800, 5000, 5200
    events = [
        {"at_period": s1, "references": {"iq_ref_A": iq0 + 0.5}},
        {"at_period": s1b, "references": {"iq_ref_A": iq0}},
        {"at_period": start, "controller": {"ident_command": 1}},
        {"at_period": s2, "references": {"iq_ref_A": iq0 + 0.5}},
        {"at_period": s2b, "references": {"iq_ref_A": iq0}},
        {"at_period": s3, "references": {"id_ref_A": -1.0}},
    ]
    raw = base("yao2020-fig10", preset, 5500, controller={"R_hat_ratio": 1.5, "L_hat_ratio": 1.5, **kx}, events=events)
    with traced(IDENT_PDOS):
        run = run_raw(raw, bus)
    tr = run.tr
    done_at = np.nonzero(tr[COL + "ident_state"] == 6)[0]
    Lh, Rh = float(tr[COL + "L_hat_H"][s2 - 1]), float(tr[COL + "R_hat_ohm"][s2 - 1])
    eL, eR = Lh / L - 1, Rh / R - 1
    th_L, th_R, inj = 0.1, 0.03, 2.0
    dL_bound = th_L / dM_gain(R, L, w, inj, "L") * 1.2
    dR_bound = th_R / dM_gain(R, L, w, inj, "R") * 1.2
    conv = bool(
        len(done_at)
        and done_at[0] < s2
        and tr[COL + "L_converged"][s2 - 1] == 1
        and tr[COL + "R_converged"][s2 - 1] == 1
    )
    res.append(
        ClaimResult(
            PAPER,
            "yao2020-1b",
            "Fig. 10(b)-(f), Yao 2020 Eq. 30-45",
            "after two -2 A d-axis injections (L first, then R) L_hat and R_hat converge to the motor's L and R",
            {"L_hat": "L", "R_hat": "R"},
            {
                "L_hat_H": Lh,
                "R_hat_ohm": Rh,
                "L_error_pct": 100 * eL,
                "R_error_pct": 100 * eR,
                "dead_zone_bound_L_pct": 100 * dL_bound / L,
                "dead_zone_bound_R_pct": 100 * dR_bound / R,
                "sequence_periods": int(done_at[0] - start) if len(done_at) else None,
                "gains_x_table_III": GAIN_X,
            },
            "sequence done with both estimators inside their dead zones; |L_hat - L| and |R_hat - R| within the "
            "dead-zone bounds TH / loop gain (x1.2)",
            conv and abs(Lh - L) <= dL_bound and abs(Rh - R) <= dR_bound,
            why_differs="The estimates stop where |dM| enters the dead zone TH_L = 0.1 V / TH_R = 0.03 V (Table III), "
            "i.e. about 1 % from the true values, not exactly on them; gains x10 of Table III shorten the "
            "run (the end point does not depend on the gain).",
            details={"first_done_period": int(done_at[0]) if len(done_at) else None},
            runs=[run.name],
        )
    )
    before = step_error(tr, "iq", s1, 0.5)
    after_q = step_error(tr, "iq", s2, 0.5)
    after_d = step_error(tr, "id", s3, -1.0)
    pred_before = first_sample_error(R, L, 1.5 * R, 1.5 * L)
    pred_after = first_sample_error(R, L, Rh, Lh)
    ok = (
        abs(before["e_k2"] - pred_before) < 5e-3
        and before["periods_to_2pct"] > 2
        and abs(after_q["e_k2"] - pred_after) < 5e-3
        and after_q["periods_to_2pct"] <= 2
        and after_d["periods_to_2pct"] <= 2
    )
    res.append(
        ClaimResult(
            PAPER,
            "yao2020-1c",
            "Fig. 10(a)-(b)",
            "with the identified L and R the iq and id step responses become deadbeat",
            "ideal deadbeat response",
            {
                "iq_step_before": before,
                "iq_step_after": after_q,
                "id_step_after": after_d,
                "derived_e_k2_before": pred_before,
                "derived_e_k2_after": pred_after,
            },
            "before: e(k0+2)/dr = y/y_hat - 1 (+-0.005) and > 2 periods to 2 %; after: e(k0+2)/dr = y/y_hat - 1 "
            "(+-0.005) and within 2 % from k0+2 for iq and id",
            bool(ok),
            why_differs="'Deadbeat' within the residual model error of the dead zone: e(k0+2)/dr = y/y_hat - 1 "
            "(about 1 %), not exactly zero.",
            runs=[run.name],
        )
    )
    return res


def claim_high_frequency(bus: str) -> ClaimResult:
    """Fig. 11: 1.33 kHz motor, -5 A injection: L_hat converges; what R_hat does."""
    preset = "yao2020_high"
    f_e, _, R, L, _, iq0 = MOTORS[preset]
    w = 2 * math.pi * f_e
    gx_L, gx_R = 50.0, 100.0
    start = 600
    raw = base(
        "yao2020-fig11",
        preset,
        4000,
        controller={
            "R_hat_ratio": 1.5,
            "L_hat_ratio": 1.5,
            "inj_id_A": -5.0,
            "kL_high_H_Vs": 2e-5 * gx_L,
            "kR_high_ohm_Vs": 0.04 * gx_R,
        },
        events=[{"at_period": start, "controller": {"ident_command": 1}}],
    )
    with traced(IDENT_PDOS):
        tr = run_raw(raw, bus).tr
    last = -2
    state = int(tr[COL + "ident_state"][last])
    Lh, Rh = float(tr[COL + "L_hat_H"][last]), float(tr[COL + "R_hat_ohm"][last])
    kL, kR = dM_gain(R, L, w, 5.0, "L"), dM_gain(R, L, w, 5.0, "R")
    dL_bound, dR_bound = 0.1 / kL * 1.2, 0.03 / kR * 1.2
    ok = state == 6 and int(tr[COL + "L_converged"][last]) == 1 and abs(Lh - L) <= dL_bound
    return ClaimResult(
        PAPER,
        "yao2020-2",
        "Fig. 11",
        "high-frequency motor (1.33 kHz, -5 A injection): L_hat converges to L; R_hat cannot converge to R "
        "(small R: the dM_d caused by the injection is small)",
        {"L_hat": "L", "R_hat": "does not converge to R"},
        {
            "L_hat_H": Lh,
            "L_error_pct": 100 * (Lh / L - 1),
            "dead_zone_bound_L_pct": 100 * dL_bound / L,
            "R_hat_ohm": Rh,
            "R_error_pct": 100 * (Rh / R - 1),
            "dead_zone_bound_R_pct": 100 * dR_bound / R,
            "R_converged": int(tr[COL + "R_converged"][last]),
            "loop_gain_dMq_V_per_H": kL,
            "loop_gain_dMd_V_per_ohm": kR,
            "gains_x_table_III": {"kL": gx_L, "kR": gx_R},
        },
        "sequence done, L converged with |L_hat - L| within TH_L / loop gain (x1.2); R_hat reported",
        bool(ok),
        why_differs="R_hat does stop inside its dead zone, but the dead zone is wide for this motor: dM_d = "
        f"{kR:.2f} V/ohm x dR, so TH_R = 0.03 V allows |dR| up to {dR_bound * 1e3:.1f} mOhm "
        f"({100 * dR_bound / R:.0f} % of R) - the bench's version of 'R_hat cannot converge'. "
        "The bench has no switching non-linearity (the paper's other reason). Gains raised above "
        "Table III to fit the run in 4000 periods.",
    )


def claim_gain_speed(bus: str) -> ClaimResult:
    """Fig. 14: larger k_L, k_R converge faster (L_hat = 3 mH, R_hat = 1 ohm at start)."""
    preset = "yao2020_low"
    f_e, _, R, L, _, _ = MOTORS[preset]
    rows = []
    for gx in (5.0, 10.0, 20.0):
        raw = base(
            f"yao2020-fig14-x{gx:g}",
            preset,
            5200,
            controller={
                "R_hat_ratio": 1.0 / 2.2,
                "L_hat_ratio": 3e-3 / 5.5e-3,
                "kL_low_H_Vs": 0.005 * gx,
                "kR_low_ohm_Vs": 4.0 * gx,
            },
            events=[{"at_period": 500, "controller": {"ident_command": 1}}],
        )
        with traced(TIME_PDOS):
            tr = run_raw(raw, bus).tr
        rows.append(
            {
                "gain_x_table_III": gx,
                "kL_H_Vs": 0.005 * gx,
                "kR_ohm_Vs": 4.0 * gx,
                "t_L_ms": 1e3 * float(tr[COL + "t_L_conv_s"][-2]),
                "t_R_ms": 1e3 * float(tr[COL + "t_R_conv_s"][-2]),
                "L_hat_H": float(tr[COL + "L_hat_H"][-2]),
                "R_hat_ohm": float(tr[COL + "R_hat_ohm"][-2]),
            }
        )
    tL = [r["t_L_ms"] for r in rows]
    tR = [r["t_R_ms"] for r in rows]
    # Yao 2020 Eq. 44: first-order convergence, time constant 1/(k x loop gain): t x k constant
    kt_L = [r["t_L_ms"] * r["gain_x_table_III"] for r in rows]
    kt_R = [r["t_R_ms"] * r["gain_x_table_III"] for r in rows]
    spread = max(max(kt_L) / min(kt_L), max(kt_R) / min(kt_R))
    ok = all(t > 0 for t in tL + tR) and tL[0] > tL[1] > tL[2] and tR[0] > tR[1] > tR[2]
    return ClaimResult(
        PAPER,
        "yao2020-3",
        "Fig. 14",
        "larger k_L, k_R make L_hat and R_hat converge faster (about 26 ms and 22 ms with the largest gains; below "
        "200 T = 20 ms estimation errors appear)",
        {"t_L_ms": 26, "t_R_ms": 22},
        {"runs": rows, "t_times_gain_spread": spread},
        "convergence times of L_hat and R_hat strictly decreasing with the gain (t x k, constant for a pure "
        "first-order loop of Yao 2020 Eq. 44, reported as its spread)",
        bool(ok),
        why_differs="The paper's 26/22 ms are for its (unstated) largest experimental gains; the bench reports the "
        "time per gain (x20 of Table III gives about the paper's 26 ms for L). t x k is not constant "
        "for R: the R loop starts far from R (R_hat = 1 ohm) and the time to enter the dead zone is "
        "logarithmic in the start error, not only 1/k.",
    )


def rls_fixed_point(w: float, psih: float, i: complex, v: complex, R0: float, L0: float) -> tuple[float, float]:
    """Fixed point eps = 0 of Yao 2020 Eq. 46-47 at one operating point (Newton on theta = (x_hat, y_hat)):
    exp(j w T) i - G2(x_hat, y_hat) j w psi_hat = x_hat i + y_hat v."""
    x, y = xy(R0, L0)

    def resid(xh: float, yh: float) -> np.ndarray:
        Rh = (1 - xh) / yh
        Lh = -Rh * T / math.log(xh)
        G = (xh - cmath.exp(1j * w * T)) / (Rh + 1j * w * Lh)
        r = cmath.exp(1j * w * T) * i - G * 1j * w * psih - (xh * i + yh * v)
        return np.array([r.real, r.imag])

    for _ in range(60):
        r = resid(x, y)
        hx, hy = 1e-9, 1e-9 * y
        J = np.column_stack([(resid(x + hx, y) - r) / hx, (resid(x, y + hy) - r) / hy])
        dx, dy = np.linalg.solve(J, r)
        x, y = x - dx, y - dy
    R = (1 - x) / y
    return float(R), float(-R * T / math.log(x))


def claim_rls_flux(bus: str) -> list[ClaimResult]:
    """Fig. 16: RLS with psi_hat = 0.8 psi / 1.2 psi is biased; the proposed identification is not."""
    preset = "yao2020_low"
    f_e, _, R, L, _, iq0 = MOTORS[preset]
    w = 2 * math.pi * f_e
    kx = {"kL_low_H_Vs": 0.005 * GAIN_X, "kR_low_ohm_Vs": 4.0 * GAIN_X}
    out = []
    for ratio in (0.8, 1.2):
        raw = base(
            f"yao2020-rls-psi{ratio}",
            preset,
            5000,
            controller={"R_hat_ratio": 1.5, "L_hat_ratio": 1.5, "psi_hat_ratio": ratio, "rls_enable": 1, **kx},
            events=[{"at_period": 700, "controller": {"ident_command": 1}}],
        )
        with traced(RLS_PDOS):
            run = run_raw(raw, bus)
        tr = run.tr
        k = -2
        rls_R, rls_L = float(tr[COL + "rls_R_hat_ohm"][k]), float(tr[COL + "rls_L_hat_H"][k])
        pr_R, pr_L = float(tr[COL + "R_hat_ohm"][k]), float(tr[COL + "L_hat_H"][k])
        # operating point of the last 300 periods: i(k), v(k) = v*(k-1) in the frame of theta(k)
        sl = slice(-302, -2)
        i_op = complex(float(np.mean(tr["id_A"][sl])), float(np.mean(tr["iq_A"][sl])))
        v_ref = complex(float(np.mean(tr["vd_V"][sl])), float(np.mean(tr["vq_V"][sl])))
        v_op = v_ref * cmath.exp(-1j * w * T)
        fp_R, fp_L = rls_fixed_point(w, ratio * 0.12, i_op, v_op, R, L)
        physical = fp_R > 0 and fp_L > 0
        rls_ok = (
            (abs(rls_R / fp_R - 1) < 0.03 and abs(rls_L / fp_L - 1) < 0.03) if physical else (abs(rls_R / R - 1) > 0.5)
        )
        prop_ok = abs(pr_R / R - 1) < 0.02 and abs(pr_L / L - 1) < 0.02
        out.append(
            ClaimResult(
                PAPER,
                f"yao2020-4-psi{ratio}",
                "Fig. 16-17, Yao 2020 Eq. 46-48",
                f"with psi_hat = {ratio} psi the RLS estimates of R and L converge to biased values; the proposed "
                "identification (no psi) finds R and L",
                {"rls": "biased", "proposed": "R, L"},
                {
                    "rls_R_ohm": rls_R,
                    "rls_L_H": rls_L,
                    "rls_R_error_pct": 100 * (rls_R / R - 1),
                    "rls_L_error_pct": 100 * (rls_L / L - 1),
                    "derived_rls_fixed_point": {"R_ohm": fp_R, "L_H": fp_L},
                    "proposed_R_ohm": pr_R,
                    "proposed_L_H": pr_L,
                    "proposed_R_error_pct": 100 * (pr_R / R - 1),
                    "proposed_L_error_pct": 100 * (pr_L / L - 1),
                },
                "RLS at its derived fixed point within 3 % (or, when that fixed point is unphysical, R_hat off by "
                "> 50 %); proposed R_hat, L_hat within 2 % of the motor",
                bool(rls_ok and prop_ok),
                why_differs=""
                if physical
                else "The fixed point of Yao 2020 Eq. 46-47 has R < 0 here: Yao 2020 Eq. 48 rejects it and the RLS "
                "keeps its last physical estimate, which is far from R (the bias the paper shows).",
                details={"operating_point": {"i_A": str(i_op), "v_V": str(v_op)}},
                runs=[run.name],
            )
        )
    return out


ALL = [claim_observer, claim_low_frequency, claim_high_frequency, claim_gain_speed, claim_rls_flux]
