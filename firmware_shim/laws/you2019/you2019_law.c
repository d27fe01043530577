/* you2019_law.c - You 2019's deadbeat law and the PI baseline as current laws
 * (you2019_law.h): Eq. 4 decoupling, Eq. 33-35 limiting, the Sec. 3.2
 * estimator and Eq. 7 dead-time compensation, the Sec. 6 online tuning with
 * the Fig. 16 gain pipeline. */
#include "you2019_law.h"

#include <math.h>
#include <string.h>

#include "dq_math.h"

CURRENT_LAW_STATE_FITS(you2019_law_state_t);

/* Its record (law.eds: 0x2500 Online tuning, the Sec. 6 tuning and the drive pipeline's settings) ->
 * the identification's configuration (same names); the PI tunes nothing. */
static void you2019_law_ident_config(const od_drive_online_tuning_t *rec, int deadbeat,
                                     you2019_identification_config_t *ic)
{
    memset(ic, 0, sizeof *ic);
    if (!deadbeat) return;
    ic->enable = rec->enable;
    ic->det_threshold_A2 = rec->det_threshold_A2;
    ic->average_m = rec->average_m;
    ic->separate_d_axis = rec->separate_d_axis;
}

static void you2019_law_configure(you2019_law_state_t *st, const drive_config_t *c, const od_drive_online_tuning_t *r,
                                  int switched)
{
    if (switched) {
        you2019_deadbeat_reset(&st->db);
        pi_current_reset(&st->pi);
        you2019_estimator_reset(&st->est);
        you2019_identification_reset(&st->ident);
    }
    you2019_law_ident_config(r, st->deadbeat, &st->ident_cfg);
    float Aq, Bq, Ad, Bd;
    /* You 2019 Eq. 2-3, Eq. 17 */
    you2019_deadbeat_model_gains(c->Ts_s, c->R_hat_ohm, c->Lq_hat_H, &Aq, &Bq);
    you2019_deadbeat_model_gains(c->Ts_s, c->R_hat_ohm, c->Ld_hat_H, &Ad, &Bd);
    you2019_deadbeat_controller_gains(Aq, Bq, &st->db.K1q_V_A, &st->db.K2q_V_A);
    you2019_deadbeat_controller_gains(Ad, Bd, &st->db.K1d_V_A, &st->db.K2d_V_A);
    you2019_estimator_set_model(&st->est, 0u, Aq, Bq);
    you2019_estimator_set_model(&st->est, 1u, Ad, Bd);
    you2019_estimator_design_pi(r->estimator_bandwidth_Hz, &st->est, 0u, c->Ts_s);
    you2019_estimator_design_pi(r->estimator_bandwidth_Hz, &st->est, 1u, c->Ts_s);
    pi_current_design(r->pi_bandwidth_Hz, &st->pi, c->R_hat_ohm, c->Ld_hat_H, c->Lq_hat_H);
    st->Lq_active_H = c->Lq_hat_H;
    st->Ld_active_H = c->Ld_hat_H;
    st->pending_q = st->pending_d = 0u;
    st->est_pi_countdown = 0u;
}

static void you2019_law_configure_deadbeat(void *state, const drive_config_t *c, const void *record, int switched)
{
    you2019_law_state_t *st = (you2019_law_state_t *)state;
    st->deadbeat = 1u;
    you2019_law_configure(st, c, (const od_drive_online_tuning_t *)record, switched);
}

static void you2019_law_configure_pi(void *state, const drive_config_t *c, const void *record, int switched)
{
    you2019_law_state_t *st = (you2019_law_state_t *)state;
    st->deadbeat = 0u;
    you2019_law_configure(st, c, (const od_drive_online_tuning_t *)record, switched);
}

/* You 2019 Fig. 16: gains averaged at the speed-loop execution are loaded
 * into the deadbeat controller and the estimator model at the next current
 * period; the estimator PI two current periods after that. */
static void you2019_law_apply_pending_gains(you2019_law_state_t *st, const drive_config_t *c,
                                            const od_drive_online_tuning_t *r)
{
    if (st->est_pi_countdown != 0u) {
        st->est_pi_countdown--;
        if (st->est_pi_countdown == 0u) {
            /* You 2019 Eq. 8/9 with the identified model gains */
            you2019_estimator_design_pi(r->estimator_bandwidth_Hz, &st->est, 0u, c->Ts_s);
            you2019_estimator_design_pi(r->estimator_bandwidth_Hz, &st->est, 1u, c->Ts_s);
        }
    }
    if (st->pending_q == 0u && st->pending_d == 0u) {
        return;
    }
    const you2019_identification_axis_state_t *q = &st->ident.q;
    const you2019_identification_axis_state_t *d = st->ident_cfg.separate_d_axis != 0u ? &st->ident.d : &st->ident.q;
    if (st->pending_q != 0u) {
        st->db.K1q_V_A = q->K1_bar_V_A;
        st->db.K2q_V_A = q->K2_bar_V_A;
        you2019_estimator_set_model(&st->est, 0u, q->A_hat, q->B_hat_A_Vs);
        st->Lq_active_H = q->L_hat_H;
    }
    if (st->pending_d != 0u) {
        /* default (paper): d-axis gains copied from the q axis */
        st->db.K1d_V_A = d->K1_bar_V_A;
        st->db.K2d_V_A = d->K2_bar_V_A;
        you2019_estimator_set_model(&st->est, 1u, d->A_hat, d->B_hat_A_Vs);
        st->Ld_active_H = d->L_hat_H;
    }
    st->pending_q = st->pending_d = 0u;
    st->est_pi_countdown = 2u;
    st->n_gain_updates++;
}

/* The output: You 2019 Eq. 4 decoupling, the law (You 2019 Eq. 17/19 or the
 * PI), You 2019 Eq. 33-35 limiting, the stator-frame command, You 2019's
 * Eq. 5-9 estimator and You 2019 Eq. 7 dead-time compensation. */
static void you2019_law_step(void *state, const drive_config_t *c, const void *record, const current_law_in_t *in,
                             current_law_out_t *o)
{
    you2019_law_state_t *st = (you2019_law_state_t *)state;
    const od_drive_online_tuning_t *r = (const od_drive_online_tuning_t *)record;
    you2019_law_apply_pending_gains(st, c, r);

    /* You 2019 Eq. 4: decoupling voltages with estimated parameters */
    const float w = in->omega_e_rad_s;
    if (r->decoupling_enable != 0u) {
        o->v_q_ff_V = w * st->Ld_active_H * in->i_d_A + w * c->psi_hat_Wb;
        o->v_d_ff_V = -w * st->Lq_active_H * in->i_q_A;
    } else {
        o->v_q_ff_V = 0.0f;
        o->v_d_ff_V = 0.0f;
    }

    /* current controller (decoupled part) */
    float vq_c = 0.0f, vd_c = 0.0f;
    if (st->deadbeat != 0u) {
        /* You 2019 Eq. 17 / Eq. 19 */
        you2019_deadbeat_step(&st->db, in->id_ref_A, in->iq_ref_A, in->i_d_A, in->i_q_A, &vd_c, &vq_c);
    } else {
        pi_current_step(&st->pi, in->id_ref_A, in->iq_ref_A, in->i_d_A, in->i_q_A, c->Ts_s, &vd_c, &vq_c);
    }

    /* You 2019 Eq. 33 (Fig. 7): limit the total stator voltage vector */
    o->v_q_V = vq_c + o->v_q_ff_V;
    o->v_d_V = vd_c + o->v_d_ff_V;
    o->v_limited = dq_limit_voltage(&o->v_d_V, &o->v_q_V, c->Vmax_V, c->vlimit_radial);
    /* You 2019 Eq. 34-35: decoupled command actually applied */
    o->v_q_star_V = o->v_q_V - o->v_q_ff_V;
    o->v_d_star_V = o->v_d_V - o->v_d_ff_V;

    /* stator-frame command, rotated to the middle of its application
     * interval [k+1, k+2] (You 2019 Fig. 1) */
    const float th_cmd = in->theta_e_rad + c->angle_advance_periods * w * c->Ts_s;
    st->cos_cmd = cosf(th_cmd);
    st->sin_cmd = sinf(th_cmd);
    dq_inv_park(o->v_d_V, o->v_q_V, st->cos_cmd, st->sin_cmd, &o->v_alpha_V, &o->v_beta_V);

    /* You 2019 Eq. 5-9 estimator, Eq. 7 dead-time compensation */
    if (r->estimator_enable != 0u) {
        you2019_estimator_step(&st->est, in->i_d_A, in->i_q_A, o->v_d_star_V, o->v_q_star_V, c->Ts_s);
        if (r->deadtime_comp_enable != 0u) {
            you2019_estimator_deadtime(r->deadtime_comp_V, r->deadtime_comp_I_sat_A, &st->est, st->cos_cmd,
                                       st->sin_cmd);
            o->v_alpha_V += st->est.v_dt_alpha_V;
            o->v_beta_V += st->est.v_dt_beta_V;
            o->v_after_limit_V = r->deadtime_comp_V; /* added per phase after the limit */
        }
    }
}

/* The update with the decoupled command applied: the law's memory (You 2019
 * Eq. 35; the PI's anti-windup), You 2019 Eq. 22-27 identification sample. */
static void you2019_law_commit(void *state, const drive_config_t *c, const void *record, const current_law_in_t *in,
                               const current_law_out_t *applied)
{
    you2019_law_state_t *st = (you2019_law_state_t *)state;
    const od_drive_online_tuning_t *r = (const od_drive_online_tuning_t *)record;
    (void)c;
    if (st->deadbeat != 0u) {
        you2019_deadbeat_commit(r->limited_memory, &st->db, applied->v_d_star_V, applied->v_q_star_V);
    } else {
        pi_current_commit(&st->pi, applied->v_d_star_V, applied->v_q_star_V);
    }
    /* You 2019 Eq. 22-27: identification every current period */
    if (st->ident_cfg.enable != 0u) {
        you2019_identification_sample(&st->ident_cfg, &st->ident.q, in->i_q_A, applied->v_q_star_V);
        if (st->ident_cfg.separate_d_axis != 0u) {
            you2019_identification_sample(&st->ident_cfg, &st->ident.d, in->i_d_A, applied->v_d_star_V);
        }
    }
}

/* You 2019 Fig. 16: Eq. 28-32 at the speed-loop execution */
static void you2019_law_speed_step(void *state, const drive_config_t *c, const void *record)
{
    you2019_law_state_t *st = (you2019_law_state_t *)state;
    const you2019_identification_config_t *ic = &st->ident_cfg;
    (void)record;
    if (ic->enable == 0u) return;
    if (you2019_identification_average(ic, &st->ident.q, c->Ts_s, c->R_hat_ohm)) {
        st->pending_q = 1u;
        if (ic->separate_d_axis == 0u) {
            st->pending_d = 1u;
        }
    }
    if (ic->separate_d_axis != 0u && you2019_identification_average(ic, &st->ident.d, c->Ts_s, c->R_hat_ohm)) {
        st->pending_d = 1u;
    }
}

static void you2019_law_reset(void *state)
{
    you2019_law_state_t *st = (you2019_law_state_t *)state;
    you2019_deadbeat_reset(&st->db);
    pi_current_reset(&st->pi);
}

/* Its record's status entries (q axis); the PI: the estimator's prediction only (it tunes nothing) */
static void you2019_law_status_pi(const void *state, const drive_config_t *c, void *record)
{
    const you2019_law_state_t *st = (const you2019_law_state_t *)state;
    od_drive_online_tuning_t *t = (od_drive_online_tuning_t *)record;
    (void)c;
    t->i_hat_q_A = st->est.i_hat_q_A;
    t->i_hat_d_A = st->est.i_hat_d_A;
}

static void you2019_law_status(const void *state, const drive_config_t *c, void *record)
{
    const you2019_law_state_t *st = (const you2019_law_state_t *)state;
    od_drive_online_tuning_t *t = (od_drive_online_tuning_t *)record;
    (void)c;
    t->det_A2 = st->ident.q.det_A2;
    t->K1_hat_V_A = st->ident.q.K1_hat_V_A;
    t->K2_hat_V_A = st->ident.q.K2_hat_V_A;
    t->K1_bar_V_A = st->ident.q.K1_bar_V_A;
    t->K2_bar_V_A = st->ident.q.K2_bar_V_A;
    t->L_hat_H = st->ident.q.L_hat_H;
    t->identifications = st->ident.q.n_identified;
    t->K1_active_V_A = st->db.K1q_V_A;
    t->K2_active_V_A = st->db.K2q_V_A;
    t->gain_updates = st->n_gain_updates;
    t->i_hat_q_A = st->est.i_hat_q_A;
    t->i_hat_d_A = st->est.i_hat_d_A;
}

/* The pipeline's rules, whichever law is selected (its record's settings against the drive's period) */
static current_law_verdict_t you2019_law_check_pipeline(const drive_config_t *c, const od_drive_online_tuning_t *r)
{
    if (r->deadtime_comp_enable != 0u && r->estimator_enable == 0u)
        return CURRENT_LAW_INCOMPATIBLE; /* You 2019 Eq. 7 compensation uses the estimated currents */
    if (r->estimator_bandwidth_Hz * 2.0f * c->Ts_s >= 1.0f) return CURRENT_LAW_INCOMPATIBLE; /* above Nyquist */
    return CURRENT_LAW_OK;
}

static current_law_verdict_t you2019_law_check_deadbeat(const drive_config_t *c, const void *record, uint8_t mode,
                                                        int selected)
{
    const od_drive_online_tuning_t *t = (const od_drive_online_tuning_t *)record;
    if (t->enable != 0u && (!selected || mode == (uint8_t)OD_DRIVE_MODE_OPEN_LOOP))
        return CURRENT_LAW_INCOMPATIBLE; /* the tuning identifies deadbeat gains in closed loop */
    return you2019_law_check_pipeline(c, t);
}

static current_law_verdict_t you2019_law_check_pi(const drive_config_t *c, const void *record, uint8_t mode,
                                                  int selected)
{
    const od_drive_online_tuning_t *r = (const od_drive_online_tuning_t *)record;
    (void)mode;
    (void)selected;
    if (r->pi_bandwidth_Hz * 6.0f * c->Ts_s >= 1.0f)
        return CURRENT_LAW_INCOMPATIBLE; /* PI phase margin 90 deg - 2 pi f 1.5 Ts <= 0 */
    return CURRENT_LAW_OK;
}

const current_law_t current_law_deadbeat_you2019 = {
    .state_bytes = (uint32_t)sizeof(you2019_law_state_t),
    .single_inductance = 0u,
    .configure = you2019_law_configure_deadbeat,
    .step = you2019_law_step,
    .commit = you2019_law_commit,
    .speed_step = you2019_law_speed_step,
    .reset = you2019_law_reset,
    .status = you2019_law_status,
    .check = you2019_law_check_deadbeat,
    .command = NULL,
};

const current_law_t current_law_pi = {
    .state_bytes = (uint32_t)sizeof(you2019_law_state_t),
    .single_inductance = 0u,
    .configure = you2019_law_configure_pi,
    .step = you2019_law_step,
    .commit = you2019_law_commit,
    .speed_step = NULL,
    .reset = you2019_law_reset,
    .status = you2019_law_status_pi,
    .check = you2019_law_check_pi,
    .command = NULL,
};
