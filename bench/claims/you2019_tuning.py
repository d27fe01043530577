"""You 2019 (seed 000), Sections 6-7: the controller gains identified in one period (You 2019 Eq. 22-27,
Fig. 20-21) and the online current-loop tuning, on a step train (Fig. 24-25) and during the positioning move of
Fig. 22, each judged against the discrete model of You 2019 Eq. 2 (bench/claims/you2019_common.py).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.claims import ClaimResult, Run, run_raw, traced
from bench.claims.you2019_common import PAPER, base, model_gains


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


def _profile(ratio: float, tuning: int, name: str) -> dict[str, Any]:
    """Fig. 22: positioning move to 11 pi at up to 3000 rpm, accelerating near rated current."""
    return {
        "scenario": {"name": name, "periods": 2600},
        "motor": {"preset": "you2019", "mech_mode": "free"},
        "drive": {"preset": "ideal", "encoder_lines": 2500},  # the ideal drive with the paper's encoder (Sec. 6)
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
