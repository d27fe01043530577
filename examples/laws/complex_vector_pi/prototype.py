"""The complex vector PI current regulator (Briz del Blanco, Degner, Lorenz 2000) as a Python prototype: the twin of
complex_vector_pi.c in this folder, operation for operation in float32, so that the two agree bit for bit
(`bench port-check`, docs/YOUR_CONTROLLER.md "Prototype in Python first"). complex_vector_pi.c's comment derives the
equations; the names here are its names.

    bench run examples/scenarios/complex_vector_pi_step.toml --bus direct \\
        --law examples/laws/complex_vector_pi --py-law examples/laws/complex_vector_pi/prototype.py:ComplexVectorPI

float32: every quantity is a numpy.float32 scalar (a Python float in an expression would make it float64), and the
trigonometry is the C library's (bench.law_py.cosf ...), as the port calls it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.law_py import cosf, expf, sinf, sqrtf

f32 = np.float32
ZERO = f32(0.0)
ONE = f32(1.0)
TWO_PI = f32(6.28318530717959)  # CVPI_TWO_PI_F


class ComplexVectorPI:
    law = "complex_vector_pi"  # the registered law it stands in for: its record configures it

    def __init__(self) -> None:
        self.reset()
        self.Kp_V_A = self.Ki_V_As = self.L_hat_H = self.R_hat_ohm = self.psi_hat_Wb = self.rho = ZERO
        self.g_d_V_A = self.g_q_V_A = ZERO

    def configure(self, cfg: Any, record: Any, switched: bool) -> None:
        if switched:
            self.__init__()  # type: ignore[misc]
        w_bw = TWO_PI * f32(record.bandwidth_Hz)
        self.L_hat_H = f32(cfg.Lq_hat_H)
        self.R_hat_ohm = f32(cfg.R_hat_ohm)
        self.psi_hat_Wb = f32(cfg.psi_hat_Wb)
        self.Kp_V_A = w_bw * self.L_hat_H
        self.Ki_V_As = w_bw * self.R_hat_ohm
        Ts = f32(cfg.Ts_s)
        self.rho = f32(expf(-self.R_hat_ohm * Ts / self.L_hat_H)) if self.L_hat_H > ZERO else ZERO
        # what step() reads of cfg and the record, as float32 once: the drive configures the law again whenever
        # either changes (and a float32 made once per period costs more than the law's arithmetic)
        self.Ts_s, self.Vmax_V, self.advance = Ts, f32(cfg.Vmax_V), f32(cfg.angle_advance_periods)
        self.discretisation, self.cross_coupling = record.discretisation, record.cross_coupling
        self.emf_feedforward = record.emf_feedforward

    def _gain(self, Ts: np.float32, w: np.float32) -> None:
        if self.discretisation != 0:
            c = f32(cosf(w * Ts))
            s = f32(sinf(w * Ts))
            self.g_d_V_A = self.Kp_V_A * (ONE - self.rho * c)
            self.g_q_V_A = self.Kp_V_A * self.rho * s
        else:
            self.g_d_V_A = Ts * self.Ki_V_As
            self.g_q_V_A = Ts * w * self.Kp_V_A

    def step(self, cfg: Any, record: Any, i: Any, out: Any) -> None:
        Ts = self.Ts_s
        w = f32(i.omega_e_rad_s)
        w_cc = w if self.cross_coupling != 0 else ZERO
        self.e_d_A = f32(i.id_ref_A) - f32(i.i_d_A)
        self.e_q_A = f32(i.iq_ref_A) - f32(i.i_q_A)
        self._gain(Ts, w_cc)
        self.v_d_raw_V = self.Kp_V_A * self.e_d_A + self.x_d_V
        self.v_q_raw_V = self.Kp_V_A * self.e_q_A + self.x_q_V
        ff_d = ZERO
        ff_q = w * self.psi_hat_Wb if self.emf_feedforward != 0 else ZERO
        vd = self.v_d_raw_V + ff_d
        vq = self.v_q_raw_V + ff_q
        mag2 = vd * vd + vq * vq
        vmax = self.Vmax_V
        limited = 0
        if vmax > ZERO and mag2 > vmax * vmax:
            k = vmax / f32(sqrtf(mag2))
            vd = vd * k
            vq = vq * k
            limited = 1
        self.limited = limited
        self.v_d_out_V = vd - ff_d
        self.v_q_out_V = vq - ff_q
        th = f32(i.theta_e_rad) + self.advance * w * Ts
        c = f32(cosf(th))
        s = f32(sinf(th))
        out.v_d_V, out.v_q_V = vd, vq
        out.v_d_ff_V, out.v_q_ff_V = ff_d, ff_q
        out.v_d_star_V, out.v_q_star_V = self.v_d_out_V, self.v_q_out_V
        out.v_limited = limited
        out.v_after_limit_V = ZERO
        out.v_alpha_V = vd * c - vq * s
        out.v_beta_V = vd * s + vq * c

    def commit(self, cfg: Any, record: Any, i: Any, applied: Any) -> None:
        vds, vqs = f32(applied.v_d_star_V), f32(applied.v_q_star_V)
        if self.limited == 0 and vds == self.v_d_out_V and vqs == self.v_q_out_V:
            xd = self.x_d_V + self.g_d_V_A * self.e_d_A - self.g_q_V_A * self.e_q_A
            xq = self.x_q_V + self.g_d_V_A * self.e_q_A + self.g_q_V_A * self.e_d_A
            self.x_d_V, self.x_q_V = xd, xq
            return
        # back-calculation: x = (R_hat + j w_e L_hat) i, |x| <= |applied|
        wL = (f32(i.omega_e_rad_s) if self.cross_coupling != 0 else ZERO) * self.L_hat_H
        i_d, i_q = f32(i.i_d_A), f32(i.i_q_A)
        xd = self.R_hat_ohm * i_d - wL * i_q
        xq = self.R_hat_ohm * i_q + wL * i_d
        bound2 = vds * vds + vqs * vqs
        mag2 = xd * xd + xq * xq
        if mag2 > bound2:
            k = f32(sqrtf(bound2 / mag2)) if mag2 > ZERO else ZERO
            xd = xd * k
            xq = xq * k
        self.x_d_V, self.x_q_V = xd, xq

    def reset(self) -> None:
        self.x_d_V = self.x_q_V = ZERO
        self.e_d_A = self.e_q_A = ZERO
        self.v_d_raw_V = self.v_q_raw_V = ZERO
        self.v_d_out_V = self.v_q_out_V = ZERO
        self.limited = 0

    def status(self, cfg: Any, record: Any) -> None:
        record.Kp_V_A = self.Kp_V_A
        record.Ki_V_As = self.Ki_V_As
        record.x_d_V = self.x_d_V
        record.x_q_V = self.x_q_V
        record.limited = self.limited
