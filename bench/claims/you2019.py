"""You 2019 (seed 000): z-domain deadbeat current control with online gain identification.

Each function runs the loop and judges one claim of the paper (Section 5 and 7). The
expected values are derived from the discrete model of Eq. 2 with the plant's own
parameters (A = exp(-Ts R / L), B = (1 - A) / R, K1 = 1/B, K2 = A/B), never copied
from the paper's sentences; the paper's numbers are reported beside them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.claims import ClaimResult, Run, run_raw, traced
from bench.metrics import step_metrics

PAPER = "You 2019"
STEP_AT = 20


def base(name: str, periods: int = 120, **sections: dict[str, Any]) -> dict[str, Any]:
    """Locked rotor, ideal sensors and inverter (the paper's simulation: drive losses ignored)."""
    raw: dict[str, Any] = {
        "scenario": {"name": name, "periods": periods},
        "motor": {"preset": "you2019", "mech_mode": "locked"},
        "drive": {"t_dead_s": 0.0, "encoder_lines": 0, "adc_noise_std_A": 0.0, "adc_lsb_A": 0.0},
        "controller": {"controller": "deadbeat_you2019", "Vmax_V": 139.0, "decoupling_enable": 1},
        "events": [{"at_period": STEP_AT, "references": {"iq_ref_A": 1.0}}],
    }
    for key, value in sections.items():
        if key == "events":
            raw["events"] = value
        else:
            raw.setdefault(key, {}).update(value)
    return raw


def model_gains(run: Run, L_key: str = "Lq_H") -> tuple[float, float]:
    R, L, Ts = run.cap.plant["R_ohm"], run.cap.plant[L_key], run.cap.plant["Ts_s"]
    A = math.exp(-Ts * R / L)
    return A, (1.0 - A) / R


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
        details={"memory_reading": "unlimited v(k-2) memory (default); see firmware_shim/core/you2019_deadbeat.c"},
    )


def closed_loop_response(A: float, B: float, A_hat: float, B_hat: float, n: int) -> np.ndarray:
    """Step response of T(z) = beta (z - A_hat) / P(z), P(z) = z^3 - A z^2 + (beta - 1) z + (A - beta A_hat),
    beta = B / B_hat: You 2019 Eq. 2 plant with the Eq. 16 controller, written as a difference equation."""
    beta = B / B_hat
    y = np.zeros(n)
    u = np.ones(n)
    # y(k) = A y(k-1) - (beta-1) y(k-2) - (A - beta A_hat) y(k-3) + beta u(k-2) - beta A_hat u(k-3)
    for k in range(n):

        def g(a: np.ndarray, i: int) -> float:
            return float(a[i]) if i >= 0 else 0.0

        y[k] = (
            A * g(y, k - 1)
            - (beta - 1) * g(y, k - 2)
            - (A - beta * A_hat) * g(y, k - 3)
            + beta * g(u, k - 2)
            - beta * A_hat * g(u, k - 3)
        )
    return y


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


def identification_errors(run: Run, threshold_A2: float = 0.2) -> np.ndarray:
    """Relative error of every identified K1 whose |det| passed the threshold (You 2019 Eq. 27)."""
    A, B = model_gains(run)
    det, k1 = run.tr["det_A2"], run.tr["K1_hat_V_A"]
    ok = np.isfinite(det) & (np.abs(det) > threshold_A2) & np.isfinite(k1) & (k1 != 0)
    return np.abs(k1[ok] * B - 1.0)


def _train(ratio: float, tuning: int, noise: bool, name: str) -> dict[str, Any]:
    events = [
        {"at_period": 20, "references": {"iq_ref_A": 1.0}},
        {"at_period": 60, "references": {"iq_ref_A": 2.0}},
        {"at_period": 100, "references": {"iq_ref_A": 0.5}},
        {"at_period": 140, "references": {"iq_ref_A": 1.5}},
    ]
    drive: dict[str, Any] = {}
    if noise:
        drive = {"adc_noise_std_A": 0.01, "adc_lsb_A": 0.002, "encoder_lines": 2500}
    return base(
        name,
        periods=180,
        controller={"Lq_hat_ratio": ratio, "Ld_hat_ratio": ratio, "enable": tuning},
        drive=drive,
        events=events,
    )


def claim_identification_accuracy(bus: str) -> list[ClaimResult]:
    """Fig. 20b-c / 21b-c: K1, K2 identified in one period when |det| is large enough."""
    clean = run_raw(_train(0.5, 1, False, "you2019-ident-clean"), bus)
    noisy = run_raw(_train(0.5, 1, True, "you2019-ident-noisy"), bus)
    e_clean = identification_errors(clean)
    e_noisy = identification_errors(noisy)
    pct = {f"p{q}": float(np.percentile(e_noisy, q)) for q in (50, 90, 100)} if len(e_noisy) else {}
    return [
        ClaimResult(
            PAPER,
            "you2019-4a",
            "Section 6.1, You 2019 Eq. 22-27",
            "the controller gain is identified in one current period whenever |det| is large enough",
            "exact in one period",
            {"identifications": int(len(e_clean)), "max_rel_error_K1": float(e_clean.max()) if len(e_clean) else None},
            "noise-free: every K1 with |det| > 0.2 A^2 within 1 %",
            bool(len(e_clean) > 0 and e_clean.max() < 0.01),
            runs=[clean.name],
        ),
        ClaimResult(
            PAPER,
            "you2019-4b",
            "Section 7, Fig. 20c/21c",
            "on hardware the identified gains were within 16 % of their nominal values",
            {"max_rel_error": 0.16},
            {"identifications": int(len(e_noisy)), **pct},
            "with ADC noise (10 mA rms, 2 mA LSB) and a 2500-line encoder: median error below 16 %",
            bool(len(e_noisy) > 0 and pct.get("p50", 1.0) < 0.16),
            why_differs="The bench's noise is white and the dead time is off; the paper's 16 % includes "
            "inverter non-linearity and saturation.",
            runs=[noisy.name],
        ),
    ]


def step_fraction(tr: dict[str, np.ndarray], p: int, after: int = 2) -> float:
    """Fraction of the reference step at period p that the current made `after` periods later, net of the
    slope the current already had before the step (a slow mode left by an earlier gain switch)."""
    d = float(tr["iq_ref_A"][p] - tr["iq_ref_A"][p - 1])
    slope = float(tr["iq_A"][p] - tr["iq_A"][p - 1])
    return float(tr["iq_A"][p + after] - tr["iq_A"][p] - after * slope) / d


def claim_tuning(bus: str) -> list[ClaimResult]:
    """Fig. 24-25: online tuning brings the response back to two periods within one speed-loop period."""
    out = []
    steps = (20, 60, 100, 140)
    for ratio in (0.5, 1.2):
        off = run_raw(_train(ratio, 0, False, f"you2019-tune-off-{ratio}"), bus)
        on = run_raw(_train(ratio, 1, False, f"you2019-tune-on-{ratio}"), bus)
        f_off = [step_fraction(off.tr, p) for p in steps]
        f_on = [step_fraction(on.tr, p) for p in steps]
        peak_off = [max(step_fraction(off.tr, p, a) for a in range(2, 12)) for p in steps]
        peak_on = [max(step_fraction(on.tr, p, a) for a in range(2, 12)) for p in steps]
        upd = np.nonzero(np.diff(on.tr["K1_active_V_A"]) != 0)[0]
        first_update = int(upd[0]) + 1 if len(upd) else None
        ok = (
            first_update is not None
            and first_update - steps[0] <= 8 + 2
            and all(abs(f - 1.0) < 0.02 for f in f_on[1:])
            and all(p < 1.02 for p in peak_on[1:])
            and all(abs(f - 1.0) > 0.05 for f in f_off)
        )
        out.append(
            ClaimResult(
                PAPER,
                f"you2019-5-L{ratio}",
                "Fig. 24, Fig. 25",
                f"tuning on from L_hat = {ratio} L: the current reaches its reference in two periods again within one "
                "speed-control period after the excitation (nine periods down to two; overshoot 0.4 A down to 0.09 A)",
                {"periods_before": 9, "periods_after": 2, "overshoot_before_A": 0.4, "overshoot_after_A": 0.09},
                {
                    "first_gain_update_period": first_update,
                    "excitation_period": steps[0],
                    "step_fraction_at_k+2_off": [round(f, 4) for f in f_off],
                    "step_fraction_at_k+2_on": [round(f, 4) for f in f_on],
                    "peak_fraction_off": [round(f, 4) for f in peak_off],
                    "peak_fraction_on": [round(f, 4) for f in peak_on],
                },
                "gains updated within 10 periods of the first step; every later step makes 98-102 % of its size in "
                "2 periods and never exceeds 102 % (untuned: off by more than 5 %)",
                bool(ok),
                why_differs="Standstill step train instead of the paper's position profile (Fig. 22). A gain switch in "
                "the middle of a transient leaves the error it had as a mode at the plant pole A, which the "
                "deadbeat zero cancels, so it decays with L/R (~60 periods) while every new step is deadbeat; "
                "the paper updates when the current has settled. Its 0.09 A residual overshoot comes from "
                "magnetic saturation, off here.",
                runs=[on.name, off.name],
            )
        )
    return out


def claim_frequency_response(
    bus: str,
    freqs_Hz: tuple[float, ...] = (200.0, 1000.0, 2500.0, 4545.45, 6000.0),
    periods_per_freq: int = 160,
    amplitude_A: float = 0.5,
) -> ClaimResult:
    """Fig. 10 / 26: flat 0 dB magnitude, phase of a two-period delay, phase margin zero near fs/4."""
    ts = 55e-6
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


def _profile(ratio: float, tuning: int, name: str) -> dict[str, Any]:
    """Fig. 22: positioning move to 11 pi at up to 3000 rpm, accelerating near rated current."""
    return {
        "scenario": {"name": name, "periods": 2600},
        "motor": {"preset": "you2019", "mech_mode": "free"},
        "drive": {"t_dead_s": 0.0, "encoder_lines": 2500, "adc_noise_std_A": 0.0, "adc_lsb_A": 0.0},
        "controller": {
            "controller": "deadbeat_you2019",
            "Vmax_V": 139.0,
            "Lq_hat_ratio": ratio,
            "Ld_hat_ratio": ratio,
            "enable": tuning,
            "iq_limit_A": 4.0,
        },
        "references": {"mode": 2, "profile_speed_rad_s": 314.159, "profile_accel_rad_s2": 30000.0},
        "events": [{"at_period": 20, "references": {"position_ref_rad": 11 * math.pi}}],
    }


PROFILE_PDOS = {
    3: ("Drive status.iq_ref_active_A", "Drive status.speed_rad_s"),
    4: ("Online tuning.K1_active_V_A", "Online tuning.L_hat_H"),
}


def _stair_fractions(tr: dict[str, np.ndarray], start: int, stop: int) -> list[float]:
    """Fraction of each reference stair (speed-loop update) made 2 periods later, net of the prior slope."""
    ref, iq = tr["drive_iq_ref_active_A"], tr["iq_A"]
    out = []
    for p in range(max(start, 2), min(stop, len(ref) - 3)):
        d = float(ref[p] - ref[p - 1])
        if not np.isfinite(d) or abs(d) < 0.05:
            continue
        slope = float(iq[p] - iq[p - 1])
        out.append(float(iq[p + 2] - iq[p] - 2 * slope) / d)
    return out


def claim_tuning_position_profile(bus: str) -> list[ClaimResult]:
    """Fig. 22-25: online tuning during the positioning move, accelerating with high current."""
    with traced(PROFILE_PDOS):
        matched = run_raw(_profile(1.0, 0, "you2019-profile-matched"), bus)
        runs = {
            r: (
                run_raw(_profile(r, 0, f"you2019-profile-off-{r}"), bus),
                run_raw(_profile(r, 1, f"you2019-profile-on-{r}"), bus),
            )
            for r in (0.5, 1.2)
        }
    f_ref = _stair_fractions(matched.tr, 20, 600)
    err_ref = float(np.median(np.abs(np.array(f_ref) - 1)))
    out = []
    for ratio, (off, on) in runs.items():
        upd = np.nonzero(np.diff(on.tr["K1_active_V_A"]) != 0)[0]
        first = int(upd[0]) + 1 if len(upd) else None
        f_off = _stair_fractions(off.tr, 20, 600)
        f_on = _stair_fractions(on.tr, (first or 10**9) + 8, 600)
        err_off = float(np.median(np.abs(np.array(f_off) - 1))) if f_off else None
        err_on = float(np.median(np.abs(np.array(f_on) - 1))) if f_on else None
        peak_speed = float(np.nanmax(on.tr["drive_speed_rad_s"]))
        ok = (
            first is not None
            and first - 20 <= 8 * 4
            and err_on is not None
            and err_off is not None
            and err_on <= err_ref + 0.02
            and err_off > 2 * err_ref
            and peak_speed > 250.0
        )
        out.append(
            ClaimResult(
                PAPER,
                f"you2019-5p-L{ratio}",
                "Fig. 22, Fig. 24, Fig. 25",
                f"positioning move (11 pi, 3000 rpm) with L_hat = {ratio} L: with tuning on, the current follows its "
                "command in two periods again within a speed-loop period after the acceleration starts",
                {"periods_before": 9, "periods_after": 2},
                {
                    "first_gain_update_period": first,
                    "move_start_period": 20,
                    "peak_speed_rad_s": peak_speed,
                    "median_stair_error_matched": err_ref,
                    "median_stair_error_untuned": err_off,
                    "median_stair_error_tuned": err_on,
                    "stairs_tuned": len(f_on),
                },
                "gains updated within 4 speed-loop periods of the start; afterwards the median deviation of the "
                "2-period response to each speed-loop reference stair is within 2 % of the matched controller's "
                "(untuned: more than twice it)",
                bool(ok),
                why_differs="The bench measures the response to each speed-loop reference stair during the "
                "acceleration (iq* changes every 8 periods) against the same move with a matched controller, "
                "not the paper's oscilloscope traces; the matched controller's own deviation (a few %) comes "
                "from the speed changing within the two periods and the 2500-line encoder; saturation is off.",
                runs=[on.name, off.name, matched.name],
            )
        )
    return out


ALL = [
    claim_matched_step,
    claim_saturated_step,
    claim_inductance_mismatch,
    claim_resistance_mismatch,
    claim_identification_accuracy,
    claim_tuning,
    claim_tuning_position_profile,
    claim_frequency_response,
]
