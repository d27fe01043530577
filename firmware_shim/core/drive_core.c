/* drive_core.c - glue: transforms, controller switch, You 2019 Eq. 4
 * decoupling, Eq. 33-35 limiting, dead-time compensation, Fig. 16 tuning
 * pipeline; the surface-mounted controllers of Yao 2020 and Zhao 2022
 * (drive_step_spm). */
#include "drive_core.h"

#include <math.h>
#include <string.h>

#include "dq_math.h"

/* The EDS defaults (od_drive_fields.h): the drive starts as the node does. */
void drive_default_config(drive_config_t *cfg)
{
    memset(cfg, 0, sizeof(*cfg));
    yao2020_dpcc_default_config(&cfg->yao); /* what the EDS does not set (Yao 2020 Table III) */
#define AT_ROOT(index, sub, record, field, eds_default) cfg->field = eds_default;
#define IN_IDENT(index, sub, record, field, eds_default) cfg->ident.field = eds_default;
#define IN_OUTER(index, sub, record, field, eds_default) cfg->outer.field = eds_default;
#define IN_YAO(index, sub, record, field, eds_default) cfg->yao.field = eds_default;
    OD_DRIVE_CONTROLLER_PARAMS(AT_ROOT)
    OD_DRIVE_ONLINE_TUNING_PARAMS(IN_IDENT)
    OD_DRIVE_OUTER_LOOPS_PARAMS(IN_OUTER)
    OD_DRIVE_YAO_2020_DPCC_PARAMS(IN_YAO)
#undef AT_ROOT
#undef IN_IDENT
#undef IN_OUTER
#undef IN_YAO
    cfg->outer.profile_speed_rad_s = OD_DRIVE_REFERENCES_PROFILE_SPEED_RAD_S_DEFAULT;
    cfg->outer.profile_accel_rad_s2 = OD_DRIVE_REFERENCES_PROFILE_ACCEL_RAD_S2_DEFAULT;
}

drive_config_verdict_t drive_config_check(const drive_config_t *c, uint8_t mode)
{
    const uint8_t ctrl = c->controller;
    const float Ts = c->Ts_s;
    if (ctrl != (uint8_t)OD_DRIVE_CONTROLLER_OPEN_LOOP && !drive_controller_exists(ctrl))
        return DRIVE_CONFIG_NO_SUCH_CONTROLLER;
    if (c->deadtime_comp_enable != 0u && c->estimator_enable == 0u)
        return DRIVE_CONFIG_INCOMPATIBLE; /* dead-time compensation uses the estimated currents */
    if (c->ident.enable != 0u &&
        (ctrl != (uint8_t)DRIVE_CTRL_DEADBEAT_YOU2019 || mode == (uint8_t)OD_DRIVE_MODE_OPEN_LOOP))
        return DRIVE_CONFIG_INCOMPATIBLE; /* You 2019 tuning identifies deadbeat gains in closed loop */
    if (c->pi_bandwidth_Hz * 6.0f * Ts >= 1.0f)
        return DRIVE_CONFIG_INCOMPATIBLE; /* PI phase margin 90 deg - 2 pi f 1.5 Ts <= 0 */
    if (c->estimator_bandwidth_Hz * 2.0f * Ts >= 1.0f) return DRIVE_CONFIG_INCOMPATIBLE; /* above Nyquist */
    if (c->outer.speed_bandwidth_Hz * 2.0f * Ts * (float)c->speed_loop_divider >= 1.0f)
        return DRIVE_CONFIG_INCOMPATIBLE; /* above the speed loop's Nyquist */
    if (c->outer.position_bandwidth_Hz >= c->outer.speed_bandwidth_Hz)
        return DRIVE_CONFIG_INCOMPATIBLE; /* cascade: position loop inside the speed bandwidth */
    return DRIVE_CONFIG_OK;
}

drive_config_verdict_t drive_config_check_selection(const drive_config_t *c)
{
    const float Ld = c->Ld_hat_H, Lq = c->Lq_hat_H;
    if (drive_controller_is_spm(c->controller) && !(fabsf(Ld - Lq) <= 0.05f * Lq)) return DRIVE_CONFIG_INCOMPATIBLE;
    return DRIVE_CONFIG_OK;
}

int drive_controller_exists(uint8_t controller)
{
    return controller >= (uint8_t)DRIVE_CTRL_PI && controller <= (uint8_t)DRIVE_CTRL_PREDICTIVE_ZHAO2022;
}

int drive_controller_is_spm(uint8_t controller)
{
    return controller == (uint8_t)DRIVE_CTRL_DPCC_YAO2020 || controller == (uint8_t)DRIVE_CTRL_INCREMENTAL_ZHAO2022 ||
           controller == (uint8_t)DRIVE_CTRL_PREDICTIVE_ZHAO2022;
}

/* Derived configs of the surface-mounted controllers from the drive's model
 * (L = Lq_hat) and their memories on a switch / a model change. */
static void drive_recompute_spm(drive_t *drv, int switched)
{
    const drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;
    const int model_changed = c->R_hat_ohm != s->R_hat_cache || c->Lq_hat_H != s->Lq_hat_cache;
    drv->yao_cfg = c->yao;
    drv->yao_cfg.Ts_s = c->Ts_s;
    drv->yao_cfg.R_hat_ohm = c->R_hat_ohm;
    drv->yao_cfg.L_hat_H = c->Lq_hat_H;
    drv->yao_cfg.psi_hat_Wb = c->psi_hat_Wb;
    drv->yao_cfg.Vmax_V = c->Vmax_V;
    yao2020_rls_default_config(&drv->rls_cfg);
    drv->rls_cfg.Ts_s = c->Ts_s;
    drv->rls_cfg.psi_hat_Wb = c->psi_hat_Wb;
    drv->rls_cfg.lambda = c->yao.rls_lambda;
    zhao2022_incremental_config_t ic;
    ic.R_hat_ohm = c->R_hat_ohm;
    ic.L_hat_H = c->Lq_hat_H;
    ic.Ts_s = c->Ts_s;
    ic.Vmax_V = c->Vmax_V;
    zhao2022_predictive_config_t ec;
    ec.R_hat_ohm = c->R_hat_ohm;
    ec.L_hat_H = c->Lq_hat_H;
    ec.psi_hat_Wb = c->psi_hat_Wb;
    ec.Ts_s = c->Ts_s;
    ec.Vmax_V = c->Vmax_V;
    (void)zhao2022_predictive_init(&ec, &drv->eul); /* memory-less law */
    if (switched) {
        yao2020_dpcc_reset(&drv->yao_cfg, &drv->yao);
        (void)zhao2022_incremental_init(&ic, &drv->inc);
    } else {
        if (model_changed) {
            /* a write of the mismatch knobs replaces the Yao 2020 estimates */
            yao2020_identification_abort(&drv->yao);
            drv->yao.R_hat_ohm = c->R_hat_ohm;
            drv->yao.L_hat_H = c->Lq_hat_H;
        }
        /* new gains, history kept (bumpless) */
        zhao2022_incremental_state_t g;
        (void)zhao2022_incremental_init(&ic, &g);
        drv->inc.K1_V_A = g.K1_V_A;
        drv->inc.K2_V_A = g.K2_V_A;
        drv->inc.L_hat_H = g.L_hat_H;
        drv->inc.Vmax_V = g.Vmax_V;
    }
    if (c->yao.rls_enable != 0u && (s->rls_cache == 0u || switched)) {
        yao2020_rls_init(&drv->rls_cfg, &drv->rls, c->R_hat_ohm, c->Lq_hat_H);
    }
    s->rls_cache = c->yao.rls_enable;
}

static void drive_recompute(drive_t *drv)
{
    const drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;
    float Aq, Bq, Ad, Bd;
    you2019_deadbeat_model_gains(c->Ts_s, c->R_hat_ohm, c->Lq_hat_H, &Aq, &Bq);
    you2019_deadbeat_model_gains(c->Ts_s, c->R_hat_ohm, c->Ld_hat_H, &Ad, &Bd);
    you2019_deadbeat_controller_gains(Aq, Bq, &drv->db.K1q_V_A, &drv->db.K2q_V_A);
    you2019_deadbeat_controller_gains(Ad, Bd, &drv->db.K1d_V_A, &drv->db.K2d_V_A);
    you2019_estimator_set_model(&drv->est, 0u, Aq, Bq);
    you2019_estimator_set_model(&drv->est, 1u, Ad, Bd);
    you2019_estimator_design_pi(c->estimator_bandwidth_Hz, &drv->est, 0u, c->Ts_s);
    you2019_estimator_design_pi(c->estimator_bandwidth_Hz, &drv->est, 1u, c->Ts_s);
    pi_current_design(c->pi_bandwidth_Hz, &drv->pi, c->R_hat_ohm, c->Ld_hat_H, c->Lq_hat_H);
    outer_loops_design(&c->outer, &drv->outer, c->pole_pairs, c->psi_hat_Wb, c->J_hat_kgm2);
    s->Lq_active_H = c->Lq_hat_H;
    s->Ld_active_H = c->Ld_hat_H;
    drive_recompute_spm(drv, s->controller_cache != c->controller);
    if (s->controller_cache != c->controller) {
        you2019_deadbeat_reset(&drv->db);
        pi_current_reset(&drv->pi);
    }
    s->pending_q = s->pending_d = 0u;
    s->est_pi_countdown = 0u;
    s->R_hat_cache = c->R_hat_ohm;
    s->Lq_hat_cache = c->Lq_hat_H;
    s->controller_cache = c->controller;
    s->dirty = 0u;
}

void drive_init(drive_t *drv, const drive_config_t *cfg)
{
    memset(drv, 0, sizeof(*drv));
    drv->cfg = *cfg;
    you2019_deadbeat_reset(&drv->db);
    pi_current_reset(&drv->pi);
    you2019_estimator_reset(&drv->est);
    you2019_identification_reset(&drv->ident);
    outer_loops_reset(&drv->outer);
    drv->st.controller_cache = 0xFFu; /* every controller starts from reset */
    drive_recompute(drv);
}

void drive_apply_config(drive_t *drv) { drv->st.dirty = 1u; }

void drive_attach_trace(drive_t *drv, trace_recorder_t *rec) { drv->trace = rec; }

/* One config-change path: drive_apply_config() after a change, effective here. */
static void drive_check_config(drive_t *drv)
{
    if (drv->st.dirty != 0u) drive_recompute(drv);
}

/* You 2019 Fig. 16: gains averaged at the speed-loop execution are loaded
 * into the deadbeat controller and the estimator model at the next current
 * period; the estimator PI two current periods after that. */
static void drive_apply_pending_gains(drive_t *drv)
{
    drive_state_t *s = &drv->st;
    if (s->est_pi_countdown != 0u) {
        s->est_pi_countdown--;
        if (s->est_pi_countdown == 0u) {
            /* You 2019 Eq. 8/9 with the identified model gains */
            you2019_estimator_design_pi(drv->cfg.estimator_bandwidth_Hz, &drv->est, 0u, drv->cfg.Ts_s);
            you2019_estimator_design_pi(drv->cfg.estimator_bandwidth_Hz, &drv->est, 1u, drv->cfg.Ts_s);
        }
    }
    if (s->pending_q == 0u && s->pending_d == 0u) {
        return;
    }
    const you2019_identification_axis_state_t *q = &drv->ident.q;
    const you2019_identification_axis_state_t *d = drv->cfg.ident.separate_d_axis != 0u ? &drv->ident.d : &drv->ident.q;
    if (s->pending_q != 0u) {
        drv->db.K1q_V_A = q->K1_bar_V_A;
        drv->db.K2q_V_A = q->K2_bar_V_A;
        you2019_estimator_set_model(&drv->est, 0u, q->A_hat, q->B_hat_A_Vs);
        s->Lq_active_H = q->L_hat_H;
    }
    if (s->pending_d != 0u) {
        /* default (paper): d-axis gains copied from the q axis */
        drv->db.K1d_V_A = d->K1_bar_V_A;
        drv->db.K2d_V_A = d->K2_bar_V_A;
        you2019_estimator_set_model(&drv->est, 1u, d->A_hat, d->B_hat_A_Vs);
        s->Ld_active_H = d->L_hat_H;
    }
    s->pending_q = s->pending_d = 0u;
    s->est_pi_countdown = 2u;
    s->n_gain_updates++;
}

/* Speed/position period: called by drive_current_step every speed_loop_divider steps. */
static void drive_speed_step(drive_t *drv, float theta_m_rad)
{
    drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;
    outer_loops_state_t *o = &drv->outer;
    const float T_sp = c->Ts_s * (float)c->speed_loop_divider;

    outer_loops_measure(o, theta_m_rad, T_sp);
    s->omega_e_rad_s = c->pole_pairs * o->omega_m_rad_s;

    switch ((drive_mode_t)drv->sp.mode) {
    case DRIVE_MODE_POSITION:
        outer_loops_profile(&c->outer, o, drv->sp.position_ref_rad, T_sp);
        (void)outer_loops_speed(&c->outer, o, outer_loops_position(o), T_sp);
        break;
    case DRIVE_MODE_SPEED:
        o->pos_ref_rad = o->theta_unwrapped_rad;
        o->vel_ref_rad_s = 0.0f;
        (void)outer_loops_speed(&c->outer, o, drv->sp.speed_ref_rad_s, T_sp);
        break;
    case DRIVE_MODE_CURRENT:
    default:
        o->pos_ref_rad = o->theta_unwrapped_rad;
        o->vel_ref_rad_s = 0.0f;
        o->integ_A = 0.0f;
        break;
    }

    /* You 2019 Fig. 16: Eq. 28-32 at the speed-loop execution */
    if (c->ident.enable != 0u) {
        if (you2019_identification_average(&c->ident, &drv->ident.q, c->Ts_s, c->R_hat_ohm)) {
            s->pending_q = 1u;
            if (c->ident.separate_d_axis == 0u) {
                s->pending_d = 1u;
            }
        }
        if (c->ident.separate_d_axis != 0u &&
            you2019_identification_average(&c->ident, &drv->ident.d, c->Ts_s, c->R_hat_ohm)) {
            s->pending_d = 1u;
        }
    }
}

static void drive_fill_signals(drive_t *drv, const drive_meas_t *m)
{
    float *g = drv->st.signals;
    const drive_state_t *s = &drv->st;
    g[TRACE_SIG_NONE] = 0.0f;
    g[TRACE_SIG_IQ_REF] = s->iq_ref_A;
    g[TRACE_SIG_IQ] = s->i_q_A;
    g[TRACE_SIG_ID_REF] = s->id_ref_A;
    g[TRACE_SIG_ID] = s->i_d_A;
    g[TRACE_SIG_VQ] = s->v_q_V;
    g[TRACE_SIG_VD] = s->v_d_V;
    g[TRACE_SIG_VQ_STAR] = s->v_q_star_V;
    g[TRACE_SIG_VD_STAR] = s->v_d_star_V;
    g[TRACE_SIG_V_ALPHA] = s->v_alpha_V;
    g[TRACE_SIG_V_BETA] = s->v_beta_V;
    g[TRACE_SIG_DET] = drv->ident.q.det_A2;
    g[TRACE_SIG_K1_HAT] = drv->ident.q.K1_hat_V_A;
    g[TRACE_SIG_K2_HAT] = drv->ident.q.K2_hat_V_A;
    g[TRACE_SIG_K1_BAR] = drv->ident.q.K1_bar_V_A;
    g[TRACE_SIG_K2_BAR] = drv->ident.q.K2_bar_V_A;
    g[TRACE_SIG_L_HAT] = drv->ident.q.L_hat_H;
    g[TRACE_SIG_K1_ACTIVE] = drv->db.K1q_V_A;
    g[TRACE_SIG_K2_ACTIVE] = drv->db.K2q_V_A;
    g[TRACE_SIG_IQ_HAT] = drv->est.i_hat_q_A;
    g[TRACE_SIG_ID_HAT] = drv->est.i_hat_d_A;
    g[TRACE_SIG_OMEGA] = drv->outer.omega_m_rad_s;
    g[TRACE_SIG_OMEGA_REF] = drv->outer.omega_ref_rad_s;
    g[TRACE_SIG_THETA] = m->theta_m_rad;
    g[TRACE_SIG_THETA_E] = s->theta_e_rad;
    g[TRACE_SIG_POS_REF] = drv->outer.pos_ref_rad;
    g[TRACE_SIG_I_A] = m->i_a_A;
    g[TRACE_SIG_I_B] = m->i_b_A;
    g[TRACE_SIG_V_LIMITED] = (float)s->v_limited;
}

static void drive_step_you2019(drive_t *drv);

void drive_reset_controller_memory(drive_t *drv)
{
    you2019_deadbeat_reset(&drv->db);
    pi_current_reset(&drv->pi);
    yao2020_identification_abort(&drv->yao);
    drv->yao.primed = 0u; /* observer restarts from F e(psi_hat); R_hat/L_hat kept */
    drv->yao.v_star_d_V = drv->yao.v_star_q_V = 0.0f;
    zhao2022_incremental_reset(&drv->inc);
    zhao2022_predictive_reset(&drv->eul);
}

bool drive_yao_ident_start(drive_t *drv)
{
    if (drv->cfg.controller != (uint8_t)DRIVE_CTRL_DPCC_YAO2020 || drv->cfg.yao.observer_enable == 0u) {
        return false;
    }
    return yao2020_identification_start(&drv->yao_cfg, &drv->yao);
}

void drive_yao_ident_abort(drive_t *drv) { yao2020_identification_abort(&drv->yao); }

/* Surface-mounted controllers (Yao 2020, Zhao 2022): the paper's law on the
 * measured dq currents with the drive's electrical speed; the law limits its
 * own command to Vmax_V (radially) and keeps the applied voltage in its
 * memory.  No You 2019 Eq. 4 feed-forward (each law has its own speed terms). */
static void drive_step_spm(drive_t *drv)
{
    const drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;
    const float w = s->omega_e_rad_s;
    s->v_q_ff_V = 0.0f;
    s->v_d_ff_V = 0.0f;
    if (c->controller == (uint8_t)DRIVE_CTRL_DPCC_YAO2020) {
        /* Yao 2020 Eq. 12-18 (+ identification); the returned stator-frame
         * vector already includes the one-period rotation (Eq. 9): no angle
         * advance here */
        yao2020_dpcc_step(&drv->yao_cfg, &drv->yao, s->id_ref_A, s->iq_ref_A, s->i_d_A, s->i_q_A, w, s->theta_e_rad,
                          &drv->yao_cmd);
        if (c->yao.rls_enable != 0u) {
            /* Yao 2020 Eq. 46-48: i(k) and v(k) = v*(k-1) (frame theta(k)) */
            yao2020_rls_update(&drv->rls_cfg, &drv->rls, s->i_d_A, s->i_q_A, drv->yao.v_app_d_V, drv->yao.v_app_q_V, w);
        }
        s->v_d_V = drv->yao_cmd.v_ref_d_V; /* frame theta(k), like the other laws */
        s->v_q_V = drv->yao_cmd.v_ref_q_V;
        s->v_limited = drv->yao_cmd.limited;
        s->v_alpha_V = drv->yao_cmd.v_alpha_V;
        s->v_beta_V = drv->yao_cmd.v_beta_V;
    } else {
        float vd, vq;
        if (c->controller == (uint8_t)DRIVE_CTRL_INCREMENTAL_ZHAO2022) {
            /* Zhao 2022 Eq. 22/23 */
            zhao2022_incremental_step(&drv->inc, s->id_ref_A, s->iq_ref_A, s->i_d_A, s->i_q_A, w, &vd, &vq);
            s->v_limited = drv->inc.limited;
        } else {
            /* Zhao 2022 Eq. 5/6 */
            zhao2022_predictive_step(&drv->eul, s->id_ref_A, s->iq_ref_A, s->i_d_A, s->i_q_A, w, &vd, &vq);
            s->v_limited = drv->eul.limited;
        }
        s->v_d_V = vd;
        s->v_q_V = vq;
        /* dq command held in the stator frame: rotated to the middle of its
         * application interval [k+1, k+2] (as for You 2019) */
        const float th_cmd = s->theta_e_rad + c->angle_advance_periods * w * c->Ts_s;
        dq_inv_park(vd, vq, cosf(th_cmd), sinf(th_cmd), &s->v_alpha_V, &s->v_beta_V);
    }
    s->v_d_star_V = s->v_d_V;
    s->v_q_star_V = s->v_q_V;
}

void drive_current_step(drive_t *drv, const drive_meas_t *m, drive_cmd_t *cmd)
{
    drive_check_config(drv);
    drive_apply_pending_gains(drv);

    const drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;

    /* electrical angle and transforms */
    s->theta_e_rad = dq_wrap_pi(c->pole_pairs * m->theta_m_rad);
    const float cs = cosf(s->theta_e_rad);
    const float sn = sinf(s->theta_e_rad);
    float i_al, i_be;
    dq_clarke(m->i_a_A, m->i_b_A, &i_al, &i_be);
    dq_park(i_al, i_be, cs, sn, &s->i_d_A, &s->i_q_A);

    /* references */
    s->id_ref_A = drv->sp.id_ref_A;
    s->iq_ref_A = drv->sp.mode == (uint8_t)DRIVE_MODE_CURRENT ? drv->sp.iq_ref_A : drv->outer.iq_ref_A;

    if (drive_controller_is_spm(c->controller)) {
        drive_step_spm(drv);
    } else {
        drive_step_you2019(drv);
    }

    cmd->v_alpha_V = s->v_alpha_V;
    cmd->v_beta_V = s->v_beta_V;

    /* outer loops every speed_loop_divider current periods */
    s->speed_div_count++;
    if (s->speed_div_count >= c->speed_loop_divider) {
        s->speed_div_count = 0u;
        drive_speed_step(drv, m->theta_m_rad);
    }

    drive_fill_signals(drv, m);
    if (drv->trace != NULL) {
        trace_sample(drv->trace, s->signals);
    }
    s->step_count++;
}

/* PI and You 2019 deadbeat: Eq. 4 decoupling, Eq. 33-35 limiting, angle
 * advance, You 2019 Eq. 5-9 estimator, Eq. 22-27 identification. */
static void drive_step_you2019(drive_t *drv)
{
    const drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;

    /* You 2019 Eq. 4: decoupling voltages with estimated parameters */
    const float w = s->omega_e_rad_s;
    if (c->decoupling_enable != 0u) {
        s->v_q_ff_V = w * s->Ld_active_H * s->i_d_A + w * c->psi_hat_Wb;
        s->v_d_ff_V = -w * s->Lq_active_H * s->i_q_A;
    } else {
        s->v_q_ff_V = 0.0f;
        s->v_d_ff_V = 0.0f;
    }

    /* current controller (decoupled part) */
    float vq_c = 0.0f, vd_c = 0.0f;
    switch ((drive_controller_t)c->controller) {
    case DRIVE_CTRL_PI:
        pi_current_step(&drv->pi, s->id_ref_A, s->iq_ref_A, s->i_d_A, s->i_q_A, c->Ts_s, &vd_c, &vq_c);
        break;
    case DRIVE_CTRL_DEADBEAT_YOU2019:
    default:
        /* You 2019 Eq. 17 / Eq. 19 */
        you2019_deadbeat_step(&drv->db, s->id_ref_A, s->iq_ref_A, s->i_d_A, s->i_q_A, &vd_c, &vq_c);
        break;
    }

    /* You 2019 Eq. 33 (Fig. 7): limit the total stator voltage vector */
    s->v_q_V = vq_c + s->v_q_ff_V;
    s->v_d_V = vd_c + s->v_d_ff_V;
    s->v_limited = dq_limit_voltage(&s->v_d_V, &s->v_q_V, c->Vmax_V, c->vlimit_radial);
    /* You 2019 Eq. 34-35: decoupled command actually applied */
    s->v_q_star_V = s->v_q_V - s->v_q_ff_V;
    s->v_d_star_V = s->v_d_V - s->v_d_ff_V;

    switch ((drive_controller_t)c->controller) {
    case DRIVE_CTRL_PI: pi_current_commit(&drv->pi, s->v_d_star_V, s->v_q_star_V); break;
    case DRIVE_CTRL_DEADBEAT_YOU2019:
    default: you2019_deadbeat_commit(c->limited_memory, &drv->db, s->v_d_star_V, s->v_q_star_V); break;
    }

    /* stator-frame command, rotated to the middle of its application
     * interval [k+1, k+2] */
    const float th_cmd = s->theta_e_rad + c->angle_advance_periods * w * c->Ts_s;
    const float cc = cosf(th_cmd);
    const float sc = sinf(th_cmd);
    dq_inv_park(s->v_d_V, s->v_q_V, cc, sc, &s->v_alpha_V, &s->v_beta_V);

    /* You 2019 Eq. 5-9 estimator, Eq. 7 dead-time compensation */
    if (c->estimator_enable != 0u) {
        you2019_estimator_step(&drv->est, s->i_d_A, s->i_q_A, s->v_d_star_V, s->v_q_star_V, c->Ts_s);
        if (c->deadtime_comp_enable != 0u) {
            you2019_estimator_deadtime(c->deadtime_comp_V, c->deadtime_comp_I_sat_A, &drv->est, cc, sc);
            s->v_alpha_V += drv->est.v_dt_alpha_V;
            s->v_beta_V += drv->est.v_dt_beta_V;
        }
    }

    /* You 2019 Eq. 22-27: identification every current period */
    if (c->ident.enable != 0u) {
        you2019_identification_sample(&c->ident, &drv->ident.q, s->i_q_A, s->v_q_star_V);
        if (c->ident.separate_d_axis != 0u) {
            you2019_identification_sample(&c->ident, &drv->ident.d, s->i_d_A, s->v_d_star_V);
        }
    }
}

float drive_signal(const drive_t *drv, trace_signal_t id)
{
    if ((uint32_t)id >= (uint32_t)TRACE_SIG_COUNT) return 0.0f;
    return drv->st.signals[id];
}
