/* complex_vector_pi.c - the complex vector PI current regulator of
 * F. Briz del Blanco, M. W. Degner, R. D. Lorenz, "Analysis and design of
 * current regulators using complex vectors", IEEE Trans. Ind. Appl. 36(3),
 * 817-825, 2000: an example current law of docs/YOUR_CONTROLLER.md, not one of
 * the three papers the bench reproduces.
 *
 * Equations.  The paper's numbering is not quoted here (it was not checked
 * against the printed text); what follows is derived in this comment and
 * cites the paper's sections by content.
 *
 *  Load (the paper's Fig. 1 and its complex vector model of an RL load with
 *  back-EMF in the synchronous frame, w_e a parameter), with i = i_d + j i_q,
 *  v = v_d + j v_q, the motor of tests/c/motor_model.h for Ld = Lq = L:
 *    L di/dt = v - R i - j w_e L i - j w_e psi            (1)
 *    G(s) = i / v = 1 / (L s + R + j w_e L): one complex pole at
 *    s = -R/L - j w_e (the cross-coupling is this pole's imaginary part).
 *  Synchronous-frame PI (the paper's baseline): C(s) = Kp + Ki/s, real zero
 *  at -Ki/Kp; with Ki/Kp = R/L it cancels the pole at standstill only.
 *  Complex vector PI (the paper's proposed regulator): the zero is placed on
 *  the complex pole,
 *    C(s) = Kp (s + R/L + j w_e) / s = Kp + (Ki + j w_e Kp) / s       (2)
 *  so C(s) G(s) = Kp / (L s) and with Kp = 2 pi f_bw L_hat, Ki = Kp R_hat/L_hat
 *  = 2 pi f_bw R_hat the closed loop is first order with bandwidth f_bw at
 *  every speed (for a matched model).  The j w_e Kp term is the cross-coupling
 *  inside the integrator: its input is (Ki + j w_e Kp) e, e = i* - i.
 *
 * Discretisation (Record.discretisation):
 *  0  forward Euler of (2):  u(k) = Kp e(k) + x(k),
 *                            x(k+1) = x(k) + Ts (Ki + j w_e Kp) e(k);
 *  1  (default) the zero matched to the sampled pole: the load (1) sampled
 *     with the voltage held over a period has the pole a = exp(-(R/L + j w_e) Ts)
 *     (the same Phi as motor_zoh_coeffs), and
 *       C(z) = Kp (z - a) / (z - 1):  x(k+1) = x(k) + Kp (1 - a) e(k),
 *     whose first-order term in Ts is the forward Euler gain above.
 *  With the drive's one-period delay (the command of sample k is held over
 *  [k+1, k+2]) the nominal loop is i(k+1) = i(k) + K (i*(k-1) - i(k-1)),
 *  K = Kp Gamma, Gamma = (1 - a) / (R + j w_e L) (the held voltage's gain),
 *  i.e. z^2 - z + K = 0: real poles for K <= 1/4, stable for K < 1.  At
 *  standstill K = 2 pi f_bw L (1 - exp(-R Ts / L)) / R <= 2 pi f_bw Ts:
 *  check() refuses 2 pi f_bw Ts >= 1.
 *
 * Limit and anti-windup: the command (plus the back-EMF feed-forward
 * j w_e psi_hat, Record.emf_feedforward) is scaled radially onto the circle
 * Vmax_V (direction kept).  In commit, told the decoupled command actually
 * applied: if it is what step() computed, the integrator integrates; if not,
 * it is back-calculated to the value it holds in the unsaturated loop for the
 * present current, (R_hat + j w_e L_hat) i (C(s) G(s) = w_bw / s means
 * u = (R + j w_e L) i + Kp e), bounded by the applied magnitude: no windup,
 * and no L/R tail after de-saturation (the complex form of pi_current.c's
 * back-calculation).
 *
 * Stator frame: the dq command of the frame theta_e(k) is rotated by
 * Controller.angle_advance_periods * w_e * Ts (1.5: the middle of its
 * interval [k+1, k+2]), as the drive does for the PI and Zhao 2022 laws.
 *
 * A surface-mounted law (single_inductance: L_hat = Lq_hat_H).  float32, no
 * allocation, no OS header. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "current_law.h"

#define CVPI_TWO_PI_F 6.28318530717959f

typedef struct {
    float Kp_V_A;  /* 2 pi f_bw L_hat */
    float Ki_V_As; /* 2 pi f_bw R_hat */
    float L_hat_H, R_hat_ohm, psi_hat_Wb;
    float rho;                  /* exp(-R_hat Ts / L_hat), the modulus of the sampled pole */
    float x_d_V, x_q_V;         /* complex integrator x = x_d + j x_q */
    float e_d_A, e_q_A;         /* error of the last step (for commit) */
    float g_d_V_A, g_q_V_A;     /* complex integrator gain of the last step */
    float v_d_raw_V, v_q_raw_V; /* decoupled command before the limit */
    float v_d_out_V, v_q_out_V; /* decoupled command after the limit (out->v_dq_star) */
    uint8_t limited;
} cvpi_state_t;

CURRENT_LAW_STATE_FITS(cvpi_state_t);

typedef od_drive_complex_vector_pi_t cvpi_record_t;

static void cvpi_configure(void *state, const drive_config_t *cfg, const void *record, int switched)
{
    cvpi_state_t *st = state;
    const cvpi_record_t *r = record;
    if (switched) memset(st, 0, sizeof(*st));
    const float w_bw = CVPI_TWO_PI_F * r->bandwidth_Hz;
    st->L_hat_H = cfg->Lq_hat_H;
    st->R_hat_ohm = cfg->R_hat_ohm;
    st->psi_hat_Wb = cfg->psi_hat_Wb;
    st->Kp_V_A = w_bw * st->L_hat_H;
    st->Ki_V_As = w_bw * st->R_hat_ohm;
    st->rho = st->L_hat_H > 0.0f ? expf(-st->R_hat_ohm * cfg->Ts_s / st->L_hat_H) : 0.0f;
}

/* The complex integrator gain g of this step: (2) discretised. */
static void cvpi_gain(const cvpi_state_t *st, const cvpi_record_t *r, float Ts_s, float w, float *g_d, float *g_q)
{
    if (r->discretisation != 0u) {
        /* Kp (1 - a), a = rho (cos(w Ts) - j sin(w Ts)) */
        const float c = cosf(w * Ts_s);
        const float s = sinf(w * Ts_s);
        *g_d = st->Kp_V_A * (1.0f - st->rho * c);
        *g_q = st->Kp_V_A * st->rho * s;
    } else {
        *g_d = Ts_s * st->Ki_V_As;
        *g_q = Ts_s * w * st->Kp_V_A;
    }
}

static void cvpi_step(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                      current_law_out_t *out)
{
    cvpi_state_t *st = state;
    const cvpi_record_t *r = record;
    const float w = in->omega_e_rad_s;
    const float w_cc = r->cross_coupling != 0u ? w : 0.0f; /* 0: the real zero -R/L of the plain PI */
    st->e_d_A = in->id_ref_A - in->i_d_A;
    st->e_q_A = in->iq_ref_A - in->i_q_A;
    cvpi_gain(st, r, cfg->Ts_s, w_cc, &st->g_d_V_A, &st->g_q_V_A);

    /* u(k) = Kp e(k) + x(k) */
    st->v_d_raw_V = st->Kp_V_A * st->e_d_A + st->x_d_V;
    st->v_q_raw_V = st->Kp_V_A * st->e_q_A + st->x_q_V;
    out->v_d_ff_V = 0.0f;
    out->v_q_ff_V = r->emf_feedforward != 0u ? w * st->psi_hat_Wb : 0.0f;

    /* radial limit of the total vector to Vmax_V */
    float vd = st->v_d_raw_V + out->v_d_ff_V;
    float vq = st->v_q_raw_V + out->v_q_ff_V;
    const float mag2 = vd * vd + vq * vq;
    uint8_t limited = 0u;
    if (cfg->Vmax_V > 0.0f && mag2 > cfg->Vmax_V * cfg->Vmax_V) {
        const float k = cfg->Vmax_V / sqrtf(mag2);
        vd *= k;
        vq *= k;
        limited = 1u;
    }
    st->limited = limited;
    out->v_limited = limited;
    out->v_d_V = vd;
    out->v_q_V = vq;
    out->v_d_star_V = vd - out->v_d_ff_V;
    out->v_q_star_V = vq - out->v_q_ff_V;
    st->v_d_out_V = out->v_d_star_V;
    st->v_q_out_V = out->v_q_star_V;

    /* stator frame, rotated to the middle of [k+1, k+2] */
    const float th = in->theta_e_rad + cfg->angle_advance_periods * w * cfg->Ts_s;
    const float c = cosf(th);
    const float s = sinf(th);
    out->v_alpha_V = vd * c - vq * s;
    out->v_beta_V = vd * s + vq * c;
}

static void cvpi_commit(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                        const current_law_out_t *applied)
{
    cvpi_state_t *st = state;
    const cvpi_record_t *r = record;
    (void)cfg;
    /* the command step() gave, unlimited, is the one applied: integrate */
    if (st->limited == 0u && applied->v_d_star_V == st->v_d_out_V && applied->v_q_star_V == st->v_q_out_V) {
        /* x(k+1) = x(k) + g e(k), complex product */
        const float xd = st->x_d_V + st->g_d_V_A * st->e_d_A - st->g_q_V_A * st->e_q_A;
        const float xq = st->x_q_V + st->g_d_V_A * st->e_q_A + st->g_q_V_A * st->e_d_A;
        st->x_d_V = xd;
        st->x_q_V = xq;
        return;
    }
    /* back-calculation: x = (R_hat + j w_e L_hat) i, |x| <= |applied| */
    const float wL = (r->cross_coupling != 0u ? in->omega_e_rad_s : 0.0f) * st->L_hat_H;
    float xd = st->R_hat_ohm * in->i_d_A - wL * in->i_q_A;
    float xq = st->R_hat_ohm * in->i_q_A + wL * in->i_d_A;
    const float bound2 = applied->v_d_star_V * applied->v_d_star_V + applied->v_q_star_V * applied->v_q_star_V;
    const float mag2 = xd * xd + xq * xq;
    if (mag2 > bound2) {
        const float k = mag2 > 0.0f ? sqrtf(bound2 / mag2) : 0.0f;
        xd *= k;
        xq *= k;
    }
    st->x_d_V = xd;
    st->x_q_V = xq;
}

static void cvpi_reset(void *state)
{
    cvpi_state_t *st = state;
    st->x_d_V = st->x_q_V = 0.0f;
    st->e_d_A = st->e_q_A = 0.0f;
    st->v_d_raw_V = st->v_q_raw_V = 0.0f;
    st->v_d_out_V = st->v_q_out_V = 0.0f;
    st->limited = 0u;
}

static void cvpi_status(const void *state, const drive_config_t *cfg, void *record)
{
    const cvpi_state_t *st = state;
    cvpi_record_t *r = record;
    (void)cfg;
    r->Kp_V_A = st->Kp_V_A;
    r->Ki_V_As = st->Ki_V_As;
    r->x_d_V = st->x_d_V;
    r->x_q_V = st->x_q_V;
    r->limited = st->limited;
}

static current_law_verdict_t cvpi_check(const drive_config_t *cfg, const void *record, uint8_t mode, int selected)
{
    const cvpi_record_t *r = record;
    (void)mode;
    if (!(r->bandwidth_Hz > 0.0f) || r->cross_coupling > 1u || r->discretisation > 1u || r->emf_feedforward > 1u)
        return CURRENT_LAW_INVALID;
    if (!selected) return CURRENT_LAW_OK;
    if (!(cfg->Lq_hat_H > 0.0f) || !(cfg->R_hat_ohm >= 0.0f)) return CURRENT_LAW_INCOMPATIBLE;
    /* the nominal loop z^2 - z + K, K <= 2 pi f_bw Ts, is unstable for K >= 1 */
    if (CVPI_TWO_PI_F * r->bandwidth_Hz * cfg->Ts_s >= 1.0f) return CURRENT_LAW_INCOMPATIBLE;
    return CURRENT_LAW_OK;
}

const current_law_t current_law_complex_vector_pi = {
    .state_bytes = (uint32_t)sizeof(cvpi_state_t),
    .single_inductance = 1u,
    .configure = cvpi_configure,
    .step = cvpi_step,
    .commit = cvpi_commit,
    .speed_step = 0,
    .reset = cvpi_reset,
    .status = cvpi_status,
    .check = cvpi_check,
    .command = 0,
};
