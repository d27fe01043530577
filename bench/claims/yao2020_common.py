"""Yao 2020 (seed 001): what every claim of the paper shares: the scenario (base: presets yao2020_low /
yao2020_high, rotor driven at the rated electrical frequency), the drive's traced entries, and the values derived
from the fully discretised model (Eq. 5-7): x = exp(-R T/L), y = (1 - x)/R, G2 = (x - exp(j w T))/(R + j w L)
(bench/claims/yao2020.py lists the claims).

The estimator gains are raised above Table III (GAIN_X, reported in every result) so that an identification
sequence fits in a few thousand periods: the convergence time scales as 1/k (Eq. 44, claim yao2020-3), the
converged values are set by the dead zones, not the gains.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.claims import with_sections
from bench.scenario import motor_preset

PAPER = "Yao 2020"
OBJ = "Yao 2020 DPCC"
COL = "Yao_2020_DPCC_"


@dataclass(frozen=True)
class Motor:
    """A motor of the paper as the claims use it: the preset's parameters (bench.scenario.motor_preset, from
    plant_rt/core/presets.c: Yao 2020 Tables I/II, psi ASSUMED) and the operating point of the experiments."""

    f_e: float  # Hz: the rated electrical frequency (Tables I/II), at which the rotor is driven
    pp: int  # pole pairs
    R: float  # ohm
    L: float  # H: Ls (surface mounted, Ld = Lq)
    vdc: float  # V
    iq0: float  # A: the q current the experiments run at
    psi: float  # Wb


def _motor(preset: str, f_e: float, iq0: float) -> Motor:
    m = motor_preset(preset)
    return Motor(f_e, m.pole_pairs, m.R_ohm, m.Lq_H, m.Vdc_V, iq0, m.psi_Wb)


# preset: the motor at its operating point (rated electrical frequency of Table I / Table II, iq of the experiments)
MOTORS = {"yao2020_low": _motor("yao2020_low", 133.3, 4.0), "yao2020_high": _motor("yao2020_high", 1330.0, 10.0)}
T = motor_preset("yao2020_low").Ts_s  # Table III: T = 100 us (both motors)
# TPDO3/4 of the drive mapped to the identification (instead of the You 2019 signals)
IDENT_PDOS = {
    3: (f"{OBJ}.R_hat_ohm", f"{OBJ}.L_hat_H"),
    4: (f"{OBJ}.ident_state", f"{OBJ}.progress", f"{OBJ}.L_converged", f"{OBJ}.R_converged", f"{OBJ}.abort_reason"),
}
TIME_PDOS = {3: (f"{OBJ}.R_hat_ohm", f"{OBJ}.L_hat_H"), 4: (f"{OBJ}.t_L_conv_s", f"{OBJ}.t_R_conv_s")}
RLS_PDOS = {3: (f"{OBJ}.R_hat_ohm", f"{OBJ}.L_hat_H"), 4: (f"{OBJ}.rls_R_hat_ohm", f"{OBJ}.rls_L_hat_H")}


def base(name: str, preset: str, periods: int, **sections: dict[str, Any]) -> dict[str, Any]:
    """Ideal sensors and inverter, rotor at the rated electrical frequency, Vmax = Vdc/sqrt(3)."""
    m = MOTORS[preset]
    raw: dict[str, Any] = {
        "scenario": {"name": name, "periods": periods},
        "motor": {"preset": preset, "mech_mode": "imposed_speed", "omega_imposed_rad_s": 2 * math.pi * m.f_e / m.pp},
        "drive": {"preset": "ideal"},
        # speed estimate every period: at 1.33 kHz with one pole pair the rotor turns 1.06 times in the
        # default 8-period speed-loop interval (the encoder difference would alias)
        "controller": {"controller": "dpcc_yao2020", "Vmax_V": m.vdc / math.sqrt(3.0), "speed_loop_divider": 1},
        "references": {"iq_ref_A": m.iq0},
        "events": [],
    }
    return with_sections(raw, sections)


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
