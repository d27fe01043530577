/* yao2020_law.c - Yao 2020's DPCC, observer, R/L identification and RLS
 * baseline as a current law (yao2020_law.h). */
#include "yao2020_law.h"

#include <string.h>

#include "yao2020_identification.h"

CURRENT_LAW_STATE_FITS(yao2020_law_state_t);

/* The DPCC's configuration: its record's parameters (same names), the drive's
 * Ts_s, model (L = Lq_hat_H) and Vmax_V; a write of the drive's model replaces
 * the identified estimates, other changes keep them (bumpless). */
static void yao2020_law_configure(void *state, const drive_config_t *c, const void *record, int switched)
{
    yao2020_law_state_t *y = (yao2020_law_state_t *)state;
    const od_drive_yao_2020_dpcc_t *rec = (const od_drive_yao_2020_dpcc_t *)record;
    const int model_changed = c->R_hat_ohm != y->R_hat_cache || c->Lq_hat_H != y->Lq_hat_cache;
    yao2020_dpcc_default_config(&y->cfg);
#define COPY(index, sub, rec_name, field, eds_default) y->cfg.field = rec->field;
    OD_DRIVE_YAO_2020_DPCC_PARAMS(COPY)
#undef COPY
    y->cfg.Ts_s = c->Ts_s;
    y->cfg.R_hat_ohm = c->R_hat_ohm;
    y->cfg.L_hat_H = c->Lq_hat_H;
    y->cfg.psi_hat_Wb = c->psi_hat_Wb;
    y->cfg.Vmax_V = c->Vmax_V;
    yao2020_rls_default_config(&y->rls_cfg);
    y->rls_cfg.Ts_s = c->Ts_s;
    y->rls_cfg.psi_hat_Wb = c->psi_hat_Wb;
    y->rls_cfg.lambda = y->cfg.rls_lambda;
    if (switched) {
        yao2020_dpcc_reset(&y->cfg, &y->st);
    } else if (model_changed) {
        /* a write of the mismatch knobs replaces the Yao 2020 estimates */
        yao2020_identification_abort(&y->st);
        y->st.R_hat_ohm = c->R_hat_ohm;
        y->st.L_hat_H = c->Lq_hat_H;
    }
    if (y->cfg.rls_enable != 0u && (y->rls_cache == 0u || switched)) {
        yao2020_rls_init(&y->rls_cfg, &y->rls, c->R_hat_ohm, c->Lq_hat_H);
    }
    y->rls_cache = y->cfg.rls_enable;
    y->R_hat_cache = c->R_hat_ohm;
    y->Lq_hat_cache = c->Lq_hat_H;
}

/* Yao 2020 Eq. 12-18 (+ identification); the returned stator-frame vector
 * already includes the one-period rotation (Eq. 9): no angle advance here.
 * No dq decoupling feed-forward (the law has its own speed terms). */
static void yao2020_law_step(void *state, const drive_config_t *c, const void *record, const current_law_in_t *in,
                             current_law_out_t *o)
{
    yao2020_law_state_t *y = (yao2020_law_state_t *)state;
    (void)c;
    (void)record;
    const float w = in->omega_e_rad_s;
    yao2020_dpcc_step(&y->cfg, &y->st, in->id_ref_A, in->iq_ref_A, in->i_d_A, in->i_q_A, w, in->theta_e_rad, &y->cmd);
    if (y->cfg.rls_enable != 0u) {
        /* Yao 2020 Eq. 46-48: i(k) and v(k) = v*(k-1) (frame theta(k)) */
        yao2020_rls_update(&y->rls_cfg, &y->rls, in->i_d_A, in->i_q_A, y->st.v_app_d_V, y->st.v_app_q_V, w);
    }
    o->v_d_ff_V = o->v_q_ff_V = 0.0f;
    o->v_d_V = y->cmd.v_ref_d_V; /* frame theta(k), like the other laws */
    o->v_q_V = y->cmd.v_ref_q_V;
    o->v_limited = y->cmd.limited;
    o->v_alpha_V = y->cmd.v_alpha_V;
    o->v_beta_V = y->cmd.v_beta_V;
    o->v_d_star_V = o->v_d_V;
    o->v_q_star_V = o->v_q_V;
}

/* The observer restarts from F e(psi_hat); R_hat/L_hat are kept. */
static void yao2020_law_reset(void *state)
{
    yao2020_law_state_t *y = (yao2020_law_state_t *)state;
    yao2020_identification_abort(&y->st);
    y->st.primed = 0u;
    y->st.v_star_d_V = y->st.v_star_q_V = 0.0f;
}

static void yao2020_law_status(const void *state, const drive_config_t *c, void *record)
{
    const yao2020_law_state_t *y = (const yao2020_law_state_t *)state;
    const yao2020_dpcc_state_t *st = &y->st;
    od_drive_yao_2020_dpcc_t *r = (od_drive_yao_2020_dpcc_t *)record;
    r->ident_state = st->id_state;
    r->abort_reason = st->abort_reason;
    r->progress = yao2020_identification_progress(&y->cfg, st);
    r->R_hat_ohm = st->R_hat_ohm;
    r->L_hat_H = st->L_hat_H;
    r->R_id_ohm = st->R_id_ohm;
    r->L_id_H = st->L_id_H;
    r->L_converged = st->L_converged;
    r->R_converged = st->R_converged;
    r->t_L_conv_s = (float)st->t_L_conv_periods * c->Ts_s;
    r->t_R_conv_s = (float)st->t_R_conv_periods * c->Ts_s;
    r->dM_d_V = st->dM_d_V;
    r->dM_q_V = st->dM_q_V;
    r->motor_class = st->motor_class;
    r->gains_high = st->gains_high;
    r->rls_R_hat_ohm = y->rls.R_hat_ohm;
    r->rls_L_hat_H = y->rls.L_hat_H;
    r->p_hat_d_A = st->p_hat_d_A;
    r->p_hat_q_A = st->p_hat_q_A;
}

/* ident_command: 1 starts the identification (Sec. IV-E: the DPCC running with
 * its observer, at least one step run: its speed and iq reference are latched
 * as the steady state), 2 aborts it; it reads back 0. */
static current_law_verdict_t yao2020_law_command(void *state, const drive_config_t *c, void *record, uint8_t subindex,
                                                 int running, int apply)
{
    yao2020_law_state_t *y = (yao2020_law_state_t *)state;
    od_drive_yao_2020_dpcc_t *r = (od_drive_yao_2020_dpcc_t *)record;
    (void)c;
    if (subindex != (uint8_t)OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB) return CURRENT_LAW_NOT_COMMAND;
    const uint8_t cmd = r->ident_command;
    if (!apply) {
        if (cmd != 1u) return CURRENT_LAW_OK;
        if (!running || r->observer_enable == 0u) return CURRENT_LAW_INCOMPATIBLE;
        if (y == NULL || y->st.primed == 0u || yao2020_identification_running(&y->st)) return CURRENT_LAW_NOT_NOW;
        return CURRENT_LAW_OK;
    }
    r->ident_command = 0u; /* a command, not a state */
    if (y == NULL) return CURRENT_LAW_OK;
    if (cmd == 1u && y->cfg.observer_enable != 0u)
        (void)yao2020_identification_start(&y->cfg, &y->st);
    else if (cmd == 2u)
        yao2020_identification_abort(&y->st);
    return CURRENT_LAW_OK;
}

const current_law_t current_law_dpcc_yao2020 = {
    .state_bytes = (uint32_t)sizeof(yao2020_law_state_t),
    .single_inductance = 1u,
    .configure = yao2020_law_configure,
    .step = yao2020_law_step,
    .commit = NULL, /* the DPCC keeps v*(k) itself (Yao 2020 Eq. 9) */
    .speed_step = NULL,
    .reset = yao2020_law_reset,
    .status = yao2020_law_status,
    .check = NULL,
    .command = yao2020_law_command,
};
