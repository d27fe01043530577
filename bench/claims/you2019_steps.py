"""You 2019 (seed 000), Section 5 and its experiments: the current steps with matched parameters (Fig. 8-9, 18-19;
You 2019 Eq. 20-21), with a mismatched inductance or resistance (Fig. 11-14, 20-21) and the closed loop's frequency
response (Fig. 10, 26), each judged against the discrete model of You 2019 Eq. 2 (bench/claims/you2019_common.py).
"""

from __future__ import annotations

import math

import numpy as np

from bench.claims import ClaimResult, run_raw
from bench.claims.you2019_common import PAPER, STEP_AT, base, closed_loop_response, model_gains
from bench.metrics import step_metrics
from bench.scenario import motor_preset


def claim_matched_step(bus: str) -> list[ClaimResult]:
    """Fig. 8 / 18a and You 2019 Eq. 20-21: 0 -> 1 A, matched parameters."""
    run = run_raw(base("you2019-matched-1A"), bus)
    tr = run.tr
    A, B = model_gains(run)
    m = step_metrics(tr["iq_A"], tr["iq_ref_A"], "iq")[0]
    err_after = np.abs(tr["iq_A"][STEP_AT + 2 :] - 1.0)
    v0, v1 = float(tr["vq_V"][STEP_AT]), float(tr["vq_V"][STEP_AT + 1])
    R = run.cap.plant["R_ohm"]
    res = [
        ClaimResult(
            PAPER,
            "you2019-1a",
            "Fig. 8, Fig. 18a",
            "matched parameters, standstill, 0 -> 1 A: the current equals the command two periods after the step, "
            "without overshoot or steady-state error",
            {"periods": 2, "overshoot_A": 0.0},
            {"periods": m.periods_to_settle, "overshoot_A": m.overshoot_A, "max_error_after_A": float(err_after.max())},
            "periods == 2, |i - i*| < 1e-5 A from k+2 on",
            m.periods_to_settle == 2 and float(err_after.max()) < 1e-5,
            runs=[run.name],
        )
    ]
    res.append(
        ClaimResult(
            PAPER,
            "you2019-1b",
            "You 2019 Eq. 20-21",
            "the first two voltage commands after the step are about 84.14 V and 2.1 V",
            {"v_k_V": 84.14, "v_k1_V": 2.1},
            {"v_k_V": v0, "v_k1_V": v1, "K1_V_A": 1.0 / B, "R_ohm": R},
            "paper's values within 1 %; bench check: v(k) = K1 * 1 A and v(k+1) = (K1 - K2) * 1 A = R * 1 A "
            "within 0.1 %",
            abs(v0 - 84.14) < 0.8414 and abs(v1 - 2.1) < 0.021,
            bench_ok=abs(v0 - 1.0 / B) < 1e-3 * (1.0 / B) and abs(v1 - R) < 1e-3 * max(R, 1.0) + 2e-3,
            why_differs="The bench reproduces the exact-gain law: v(k) = K1 = 1/B = 83.25 V and v(k+1) = K1 - K2 = R = "
            "1.4 V. The paper's You 2019 Eq. 20 approximates L di/dt over one period (its 84.14 V implies a "
            "larger L), and You 2019 Eq. 21's own formula r_s * 1 A gives 1.4 V with Table A2's 1.4 ohm, "
            "not 2.1 V.",
            runs=[run.name],
        )
    )
    return res


def claim_saturated_step(bus: str) -> ClaimResult:
    """Fig. 9 / 18b: 0 -> 4 A with Vmax = 139 V."""
    raw = base("you2019-saturated-4A", events=[{"at_period": STEP_AT, "references": {"iq_ref_A": 4.0}}])
    run = run_raw(raw, bus)
    tr = run.tr
    m = step_metrics(tr["iq_A"], tr["iq_ref_A"], "iq")[0]
    vmag = np.hypot(tr["vd_V"], tr["vq_V"])
    saturated = int((vmag[STEP_AT : STEP_AT + 10] > 139.0 - 0.01).sum())
    bounded = float(np.nanmax(np.abs(tr["iq_A"]))) < 5.0
    # periods to reach 98 % of the step (the paper's "needs about six/seven periods")
    reach = int(np.argmax(tr["iq_A"][STEP_AT:] >= 0.98 * 4.0))
    return ClaimResult(
        PAPER,
        "you2019-2",
        "Fig. 9, Fig. 18b, Fig. 19",
        "0 -> 4 A with Vmax = 139 V: the command saturates and the current needs about 6-7 periods, no runaway",
        {"periods": "6-7"},
        {
            "periods_to_98pct": reach,
            "periods_to_settle_2pct": m.periods_to_settle,
            "saturated_periods": saturated,
            "overshoot_A": m.overshoot_A,
            "peak_A": float(np.nanmax(tr["iq_A"])),
        },
        "5 <= periods to 98 % <= 8, at least one saturated command, |iq| < 5 A",
        5 <= reach <= 8 and saturated >= 1 and bounded,
        details={
            "memory_reading": "unlimited v(k-2) memory (default); see firmware_shim/laws/you2019/you2019_deadbeat.c"
        },
    )


def claim_inductance_mismatch(bus: str) -> list[ClaimResult]:
    """Fig. 13-14 / 20-21: L_hat = 0.5 L overdamped, 1.2 L overshoot; poles agree with the response."""
    out = []
    for ratio, fig, statement in (
        (0.5, "Fig. 13, Fig. 20a", "L_hat = 0.5 L: the response becomes overdamped (about 7 periods)"),
        (1.2, "Fig. 14, Fig. 21a", "L_hat = 1.2 L: the response becomes underdamped with visible overshoot"),
    ):
        run = run_raw(base(f"you2019-Lhat-{ratio}", controller={"Lq_hat_ratio": ratio, "Ld_hat_ratio": ratio}), bus)
        tr = run.tr
        A, B = model_gains(run)
        R, L, Ts = run.cap.plant["R_ohm"], run.cap.plant["Lq_H"], run.cap.plant["Ts_s"]
        A_hat = math.exp(-Ts * R / (ratio * L))
        B_hat = (1 - A_hat) / R
        n = len(tr["iq_A"]) - STEP_AT
        model = closed_loop_response(A, B, A_hat, B_hat, n)
        dev = float(np.max(np.abs(tr["iq_A"][STEP_AT:] - model)))
        beta = B / B_hat
        poles = np.roots([1.0, -A, beta - 1.0, A - beta * A_hat])
        m = step_metrics(tr["iq_A"], tr["iq_ref_A"], "iq")[0]
        reach = int(np.argmax(tr["iq_A"][STEP_AT:] >= 0.98))
        bench_ok = None
        if ratio < 1:
            ok = 5 <= reach <= 9 and m.overshoot_pct < 0.5 and dev < 1e-4
            bench_ok = bool(reach >= 5 and np.all(np.isreal(poles)) and dev < 1e-4)
            tol = (
                "overdamped: 5-9 periods to 98 % and no overshoot (< 0.5 %); bench check: all closed-loop poles "
                "real, >= 5 periods, simulation = analytic response within 1e-4 A"
            )
        else:
            ok = m.overshoot_pct > 5.0 and np.any(np.abs(np.imag(poles)) > 1e-3) and dev < 1e-4
            tol = "complex pole pair, overshoot > 5 %, simulation = analytic response within 1e-4 A"
        out.append(
            ClaimResult(
                PAPER,
                f"you2019-3-L{ratio}",
                fig,
                statement,
                {"periods": 7} if ratio < 1 else {"overshoot": "visible"},
                {
                    "periods_to_98pct": reach,
                    "periods_to_settle_2pct": m.periods_to_settle,
                    "overshoot_pct": m.overshoot_pct,
                    "poles": [complex(p) for p in poles],
                    "max_dev_from_analytic_A": dev,
                },
                tol,
                bool(ok),
                bench_ok=bench_ok,
                why_differs=""
                if ratio > 1
                else "With L_hat = 0.5 L the controller's zero no longer cancels the plant "
                "pole: the poles are real (0.96, 0.73, -0.71) but the slow one at 0.96 leaves a small overshoot (about "
                "4.6 %) that decays over ~40 periods. 98 % is reached in 8 periods (paper: about 7).",
                details={"poles_str": ", ".join(f"{p.real:.4f}{p.imag:+.4f}j" for p in poles)},
                runs=[run.name],
            )
        )
    return out


def claim_resistance_mismatch(bus: str) -> ClaimResult:
    """Fig. 11-12: R_hat = 0.5 R / 1.5 R: small effect, current slightly below / above the command."""
    offsets = {}
    for ratio in (0.5, 1.5):
        run = run_raw(base(f"you2019-Rhat-{ratio}", controller={"R_hat_ratio": ratio}), bus)
        offsets[ratio] = float(np.mean(run.tr["iq_A"][STEP_AT + 2 : STEP_AT + 10]) - 1.0)
    ok = offsets[0.5] < 0 < offsets[1.5] and max(abs(v) for v in offsets.values()) < 0.05
    return ClaimResult(
        PAPER,
        "you2019-3-R",
        "Fig. 11, Fig. 12",
        "R_hat = 0.5 R: current marginally below the command; 1.5 R: marginally above; trivial effect otherwise",
        {"sign_0.5R": "-", "sign_1.5R": "+"},
        {"offset_0.5R_A": offsets[0.5], "offset_1.5R_A": offsets[1.5]},
        "offset over periods k+2..k+9: negative for 0.5 R, positive for 1.5 R, both below 5 % of the step",
        bool(ok),
        why_differs="The offset is not a true steady-state error: the controller's pole at z = 1 "
        "integrates it away with the L/R time constant (about 60 periods).",
    )


def claim_frequency_response(
    bus: str,
    freqs_Hz: tuple[float, ...] = (200.0, 1000.0, 2500.0, 4545.45, 6000.0),
    periods_per_freq: int = 160,
    amplitude_A: float = 0.5,
) -> ClaimResult:
    """Fig. 10 / 26: flat 0 dB magnitude, phase of a two-period delay, phase margin zero near fs/4."""
    ts = motor_preset("you2019").Ts_s  # Table A1: Ts = 55 us
    events = []
    k = 0
    spans = []
    for f in freqs_Hz:
        start = k + 20
        for j in range(periods_per_freq):
            events.append(
                {
                    "at_period": start + j,
                    "references": {"iq_ref_A": float(amplitude_A * math.sin(2 * math.pi * f * j * ts))},
                }
            )
        spans.append((f, start, start + periods_per_freq))
        k = start + periods_per_freq
    raw = base("you2019-freqresp", periods=k + 5, events=events)
    run = run_raw(raw, bus)
    rows = []
    worst_mag, worst_phase = 0.0, 0.0
    for f, a, b in spans:
        n = np.arange(b - a)
        sl = slice(a + 40, b)  # skip the start transient
        w = 2 * math.pi * f * ts
        basis = np.column_stack([np.sin(w * n[40:]), np.cos(w * n[40:])])
        cy = np.linalg.lstsq(basis, run.tr["iq_A"][sl], rcond=None)[0]
        cr = np.linalg.lstsq(basis, run.tr["iq_ref_A"][sl], rcond=None)[0]
        gain = float(np.hypot(*cy) / np.hypot(*cr))
        phase = float(math.degrees(math.atan2(cy[1], cy[0]) - math.atan2(cr[1], cr[0])))
        expect = -math.degrees(2 * w)
        dphi = (phase - expect + 180.0) % 360.0 - 180.0
        worst_mag = max(worst_mag, abs(20 * math.log10(gain)))
        worst_phase = max(worst_phase, abs(dphi))
        rows.append({"f_Hz": f, "gain_dB": 20 * math.log10(gain), "phase_deg": phase, "two_period_delay_deg": expect})
    return ClaimResult(
        PAPER,
        "you2019-6",
        "Fig. 10, Fig. 26",
        "closed-loop magnitude flat at 0 dB up to Nyquist; phase of a two-period delay; phase margin 0 at 4.575 kHz "
        "(fs/4)",
        {"gain_dB": 0.0, "zero_phase_margin_Hz": 4575.0},
        {"points": rows, "fs_over_4_Hz": 1.0 / ts / 4},
        "|gain| < 0.05 dB and phase within 1 deg of -2 w Ts at every frequency (=> -180 deg at fs/4 = 4545 Hz)",
        worst_mag < 0.05 and worst_phase < 1.0,
        why_differs="fs/4 with Ts = 55 us is 4545 Hz; the paper's 4.575 kHz is the same point read off a plot.",
    )
