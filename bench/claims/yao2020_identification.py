"""Yao 2020 (seed 001): the identification beyond Fig. 10: on the high-frequency motor (1.33 kHz, Fig. 11), its
convergence time against the estimator gains (Fig. 14, Eq. 44), and against the RLS identification with a wrong
flux (Fig. 16-17, Eq. 46-48); judged against the fully discretised model (bench/claims/yao2020_common.py).
"""

from __future__ import annotations

import cmath
import math

import numpy as np

from bench.claims import ClaimResult, run_raw, traced
from bench.claims.yao2020_common import (
    COL,
    GAIN_X,
    IDENT_PDOS,
    MOTORS,
    PAPER,
    RLS_PDOS,
    TIME_PDOS,
    T,
    base,
    dM_gain,
    rls_fixed_point,
)


def claim_high_frequency(bus: str) -> ClaimResult:
    """Fig. 11: 1.33 kHz motor, -5 A injection: L_hat converges; what R_hat does."""
    preset = "yao2020_high"
    m = MOTORS[preset]
    R, L, w = m.R, m.L, 2 * math.pi * m.f_e
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
    m = MOTORS[preset]
    rows = []
    for gx in (5.0, 10.0, 20.0):
        raw = base(
            f"yao2020-fig14-x{gx:g}",
            preset,
            5200,
            controller={
                "R_hat_ratio": 1.0 / m.R,  # R_hat = 1 ohm
                "L_hat_ratio": 3e-3 / m.L,  # L_hat = 3 mH
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


def claim_rls_flux(bus: str) -> list[ClaimResult]:
    """Fig. 16: RLS with psi_hat = 0.8 psi / 1.2 psi is biased; the proposed identification is not."""
    preset = "yao2020_low"
    m = MOTORS[preset]
    R, L, w = m.R, m.L, 2 * math.pi * m.f_e
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
        fp_R, fp_L = rls_fixed_point(w, ratio * m.psi, i_op, v_op, R, L)
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
