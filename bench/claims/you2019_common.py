"""You 2019 (seed 000): what every claim of the paper shares: the scenario of its simulations (base) and the
discrete model of You 2019 Eq. 2 with the plant's own parameters (A = exp(-Ts R / L), B = (1 - A) / R, K1 = 1/B,
K2 = A/B), from which the claims derive their expected values (bench/claims/you2019.py lists the claims).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.claims import Run, with_sections

PAPER = "You 2019"
STEP_AT = 20


def base(name: str, periods: int = 120, **sections: dict[str, Any]) -> dict[str, Any]:
    """Locked rotor, ideal sensors and inverter (the paper's simulation: drive losses ignored)."""
    raw: dict[str, Any] = {
        "scenario": {"name": name, "periods": periods},
        "motor": {"preset": "you2019", "mech_mode": "locked"},
        "drive": {"preset": "ideal"},
        "controller": {"controller": "deadbeat_you2019", "Vmax_V": 139.0, "decoupling_enable": 1},
        "events": [{"at_period": STEP_AT, "references": {"iq_ref_A": 1.0}}],
    }
    return with_sections(raw, sections)


def model_gains(run: Run, L_key: str = "Lq_H") -> tuple[float, float]:
    R, L, Ts = run.cap.plant["R_ohm"], run.cap.plant[L_key], run.cap.plant["Ts_s"]
    A = math.exp(-Ts * R / L)
    return A, (1.0 - A) / R


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
