#!/usr/bin/env python3
"""Stability of the Zhao 2022 incremental deadbeat law (Machines 2022, Eq. 22/23)
under inductance mismatch L/L0 -- independent cross-check (numpy) of the C
analysis in firmware_shim/tests/test_zhao2022_common.h / test_zhao2022_stability.c.

Closed loop (derived there): exact zero-order-hold RL plant in the rotor frame,
one-period computation delay (command from sample k acts over [k+1, k+2]):

    Q(z) = (z - Phi)(z - 1)(z + 1)^2 + Gam K2 z^2 + Gam (K1c - K2)
    Phi = exp(-(R/L + j w) Ts),  Gam = (1 - Phi) / (R + j w L)
    K1c = R0 + L0/Ts + j w L0,   K2 = 2 L0/Ts,   T(z) = Gam K1c z^2 / Q(z)

Paper's approximation (Eq. 34, Ts -> 0):  lam (z^2-1)^2 + 2 (z^2-1) + 1,
lam = L/L0, stable for lam > 3/4 (Sec. 4.2).  The exact plant gives 3/4 back
only when R Ts / L -> 0; the Table 1 motor has R Ts / L = 0.349.

Usage: .venv/bin/python docs/analysis/zhao2022_stability.py
"""

import numpy as np

R, L, TS = 48.9, 14e-3, 100e-6  # Zhao 2022 Table 1, 10 kHz
W_RATED = 5 * 367.72 * np.pi / 180  # electrical rad/s


def q_exact(Rp, Lp, R0, L0, w=0.0):
    a = Rp / Lp + 1j * w
    phi = np.exp(-a * TS)
    gam = (1 - phi) / (Lp * a)
    k1c, k2 = R0 + L0 / TS + 1j * w * L0, 2 * L0 / TS
    p = np.polymul(np.polymul([1, -phi], [1, -1]), [1, 2, 1]).astype(complex)
    p[2] += gam * k2
    p[4] += gam * (k1c - k2)
    return p


def q_paper(lam):
    return np.array([lam, 0, -2 * (lam - 1), 0, lam - 1], dtype=complex)


def q_euler(Rp, Lp, R0, L0, w=0.0):
    a = Rp / Lp + 1j * w
    phi = np.exp(-a * TS)
    gam = (1 - phi) / (Lp * a)
    return np.array([1, -phi, -gam * (R0 - L0 / TS + 1j * w * L0)])


def radius(p):
    return max(abs(np.roots(p)))


def boundary(poly_of_lam, start=1.0, stop=0.2, step=1e-3):
    """Smallest stable lam connected to `start` (walk, then bisection)."""
    good, lam = start, start
    while (lam - stop) * np.sign(start - stop) >= 0:
        if radius(poly_of_lam(lam)) >= 1:
            bad = lam
            for _ in range(60):
                mid = 0.5 * (good + bad)
                if radius(poly_of_lam(mid)) >= 1:
                    bad = mid
                else:
                    good = mid
            return 0.5 * (good + bad)
        good = lam
        lam += step * np.sign(stop - start)
    return stop


if __name__ == "__main__":
    print(f"R Ts/L = {R * TS / L:.4f}")
    print("paper Eq. 34            :", round(boundary(q_paper, 0.999), 6))
    print("exact, L0 = L/lam       :", round(boundary(lambda lam: q_exact(R, L, R, L / lam)), 6))
    print("exact, L = lam L0       :", round(boundary(lambda lam: q_exact(R, lam * L, R, L)), 6))
    print("exact, rated speed      :", round(boundary(lambda lam: q_exact(R, L, R, L / lam, W_RATED)), 6))
    print("exact, R -> 0           :", round(boundary(lambda lam: q_exact(1e-9, L, 1e-9, L / lam)), 6))
    print("exact upper, L0 = L/lam :", round(boundary(lambda lam: q_exact(R, L, R, L / lam), 1.0, 10.0), 6))
    print("Euler law, L0 = L/lam   :", round(boundary(lambda lam: q_euler(R, L, R, L / lam)), 6))
    print(f"matched radius: incremental {radius(q_exact(R, L, R, L)):.4f}, Euler {radius(q_euler(R, L, R, L)):.4f}")
