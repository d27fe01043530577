/* zhao2022_law.c - Zhao 2022's incremental law (Eq. 22/23) and predictive
 * baseline (Eq. 5/6) as current laws (zhao2022_law.h). */
#include "zhao2022_law.h"

CURRENT_LAW_STATE_FITS(zhao2022_incremental_state_t);
CURRENT_LAW_STATE_FITS(zhao2022_predictive_state_t);

/* Zhao 2022 Eq. 22/23: gains from the drive's model; a new model keeps the
 * histories (bumpless), a switch starts from reset. */
static void zhao2022_law_configure_incremental(void *state, const drive_config_t *c, const void *record, int switched)
{
    zhao2022_incremental_state_t *inc = (zhao2022_incremental_state_t *)state;
    (void)record;
    zhao2022_incremental_config_t ic;
    ic.R_hat_ohm = c->R_hat_ohm;
    ic.L_hat_H = c->Lq_hat_H;
    ic.Ts_s = c->Ts_s;
    ic.Vmax_V = c->Vmax_V;
    if (switched) {
        (void)zhao2022_incremental_init(&ic, inc);
        return;
    }
    zhao2022_incremental_state_t g;
    (void)zhao2022_incremental_init(&ic, &g);
    inc->K1_V_A = g.K1_V_A;
    inc->K2_V_A = g.K2_V_A;
    inc->L_hat_H = g.L_hat_H;
    inc->Vmax_V = g.Vmax_V;
}

/* Zhao 2022 Eq. 5/6: a law without memory, rebuilt from the drive's model. */
static void zhao2022_law_configure_predictive(void *state, const drive_config_t *c, const void *record, int switched)
{
    (void)record;
    (void)switched;
    zhao2022_predictive_config_t ec;
    ec.R_hat_ohm = c->R_hat_ohm;
    ec.L_hat_H = c->Lq_hat_H;
    ec.psi_hat_Wb = c->psi_hat_Wb;
    ec.Ts_s = c->Ts_s;
    ec.Vmax_V = c->Vmax_V;
    (void)zhao2022_predictive_init(&ec, (zhao2022_predictive_state_t *)state);
}

/* The dq command of either law as the drive's output: no feed-forward part
 * (each law has its own speed terms), held in the stator frame. */
static void zhao2022_law_output(const drive_config_t *c, const current_law_in_t *in, float vd, float vq,
                                uint8_t limited, current_law_out_t *o)
{
    o->v_d_ff_V = o->v_q_ff_V = 0.0f;
    o->v_limited = limited;
    o->v_d_V = vd;
    o->v_q_V = vq;
    current_law_to_stator(c, in, o);
    o->v_d_star_V = o->v_d_V;
    o->v_q_star_V = o->v_q_V;
}

static void zhao2022_law_step_incremental(void *state, const drive_config_t *c, const void *record,
                                          const current_law_in_t *in, current_law_out_t *o)
{
    zhao2022_incremental_state_t *inc = (zhao2022_incremental_state_t *)state;
    (void)record;
    float vd, vq;
    /* Zhao 2022 Eq. 22/23 */
    zhao2022_incremental_step(inc, in->id_ref_A, in->iq_ref_A, in->i_d_A, in->i_q_A, in->omega_e_rad_s, &vd, &vq);
    zhao2022_law_output(c, in, vd, vq, inc->limited, o);
}

static void zhao2022_law_step_predictive(void *state, const drive_config_t *c, const void *record,
                                         const current_law_in_t *in, current_law_out_t *o)
{
    zhao2022_predictive_state_t *eul = (zhao2022_predictive_state_t *)state;
    (void)record;
    float vd, vq;
    /* Zhao 2022 Eq. 5/6 */
    zhao2022_predictive_step(eul, in->id_ref_A, in->iq_ref_A, in->i_d_A, in->i_q_A, in->omega_e_rad_s, &vd, &vq);
    zhao2022_law_output(c, in, vd, vq, eul->limited, o);
}

static void zhao2022_law_reset_incremental(void *state)
{
    zhao2022_incremental_reset((zhao2022_incremental_state_t *)state);
}

static void zhao2022_law_reset_predictive(void *state)
{
    zhao2022_predictive_reset((zhao2022_predictive_state_t *)state);
}

static void zhao2022_law_status_incremental(const void *state, const drive_config_t *c, void *record)
{
    const zhao2022_incremental_state_t *inc = (const zhao2022_incremental_state_t *)state;
    od_drive_zhao_2022_t *r = (od_drive_zhao_2022_t *)record;
    (void)c;
    r->K1_V_A = inc->K1_V_A;
    r->K2_V_A = inc->K2_V_A;
    r->limited = inc->limited;
}

static void zhao2022_law_status_predictive(const void *state, const drive_config_t *c, void *record)
{
    const zhao2022_predictive_state_t *eul = (const zhao2022_predictive_state_t *)state;
    od_drive_zhao_2022_t *r = (od_drive_zhao_2022_t *)record;
    (void)c;
    r->G_V_A = eul->G_V_A;
    r->limited = eul->limited;
}

const current_law_t current_law_incremental_zhao2022 = {
    .state_bytes = (uint32_t)sizeof(zhao2022_incremental_state_t),
    .single_inductance = 1u,
    .configure = zhao2022_law_configure_incremental,
    .step = zhao2022_law_step_incremental,
    .commit = NULL, /* the law keeps u(k) itself (Zhao 2022 Eq. 22/23) */
    .reset = zhao2022_law_reset_incremental,
    .status = zhao2022_law_status_incremental,
};

const current_law_t current_law_predictive_zhao2022 = {
    .state_bytes = (uint32_t)sizeof(zhao2022_predictive_state_t),
    .single_inductance = 1u,
    .configure = zhao2022_law_configure_predictive,
    .step = zhao2022_law_step_predictive,
    .reset = zhao2022_law_reset_predictive,
    .status = zhao2022_law_status_predictive,
};
