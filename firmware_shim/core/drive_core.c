/* drive_core.c - glue: transforms, outer loops, the selected current law
 * (current_law.h), the trace.  It names no law: the registry does. */
#include "drive_core.h"

#include <math.h>
#include <string.h>

#include "dq_math.h"

/* The EDS defaults (od_drive_fields.h): the drive starts as the node does. */
void drive_default_config(drive_config_t *cfg)
{
    memset(cfg, 0, sizeof(*cfg));
#define AT_ROOT(index, sub, record, field, eds_default) cfg->field = eds_default;
#define IN_OUTER(index, sub, record, field, eds_default) cfg->outer.field = eds_default;
    OD_DRIVE_CONTROLLER_PARAMS(AT_ROOT)
    OD_DRIVE_OUTER_LOOPS_PARAMS(IN_OUTER)
#undef AT_ROOT
#undef IN_OUTER
    cfg->outer.profile_speed_rad_s = OD_DRIVE_REFERENCES_PROFILE_SPEED_RAD_S_DEFAULT;
    cfg->outer.profile_accel_rad_s2 = OD_DRIVE_REFERENCES_PROFILE_ACCEL_RAD_S2_DEFAULT;
}

drive_config_verdict_t drive_config_check(const drive_config_t *c, uint8_t mode, drive_record_of_fn record_of,
                                          void *user)
{
    const uint8_t ctrl = c->controller;
    const float Ts = c->Ts_s;
    if (ctrl != (uint8_t)OD_DRIVE_CONTROLLER_OPEN_LOOP && current_law_find(ctrl) == NULL)
        return DRIVE_CONFIG_NO_SUCH_CONTROLLER;
    if (c->outer.speed_bandwidth_Hz * 2.0f * Ts * (float)c->speed_loop_divider >= 1.0f)
        return DRIVE_CONFIG_INCOMPATIBLE; /* above the speed loop's Nyquist */
    if (c->outer.position_bandwidth_Hz >= c->outer.speed_bandwidth_Hz)
        return DRIVE_CONFIG_INCOMPATIBLE; /* cascade: position loop inside the speed bandwidth */
    for (uint8_t i = 0u; i < current_law_count; ++i) {
        const current_law_entry_t *e = &current_law_table[i];
        if (e->law->check == NULL) continue;
        const void *rec = e->record_default;
        const void *held = e->record_index != 0u && record_of != NULL ? record_of(e->record_index, user) : NULL;
        if (held != NULL) rec = held; /* none held: its EDS defaults */
        if (e->law->check(c, rec, mode, ctrl == e->value) != CURRENT_LAW_OK) return DRIVE_CONFIG_INCOMPATIBLE;
    }
    return DRIVE_CONFIG_OK;
}

drive_config_verdict_t drive_config_check_selection(const drive_config_t *c)
{
    const float Ld = c->Ld_hat_H, Lq = c->Lq_hat_H;
    const current_law_entry_t *e = current_law_find(c->controller);
    if (e != NULL && e->law->single_inductance != 0u && !(fabsf(Ld - Lq) <= 0.05f * Lq))
        return DRIVE_CONFIG_INCOMPATIBLE;
    return DRIVE_CONFIG_OK;
}

void *drive_law_record(drive_t *drv) { return drv->law_record_index != 0u ? drv->law_record : NULL; }

void drive_set_law_record(drive_t *drv, const void *record, uint32_t bytes)
{
    const current_law_entry_t *e = current_law_find(drv->cfg.controller);
    if (e == NULL || e->record_index == 0u || bytes != e->record_bytes || bytes > CURRENT_LAW_RECORD_BYTES) return;
    memcpy(drv->law_record, record, bytes);
    drv->law_record_index = e->record_index;
}

void drive_law_status(const drive_t *drv, void *record)
{
    if (drv->law != NULL && drv->law->law->status != NULL) drv->law->law->status(drv->law_state, &drv->cfg, record);
}

current_law_verdict_t drive_law_command(drive_t *drv, const current_law_entry_t *e, void *record, uint8_t subindex,
                                        int open_loop, int apply)
{
    if (e->law->command == NULL) return CURRENT_LAW_NOT_COMMAND;
    /* selected (its state: once the drive has configured it, at the next step) */
    const int running = drv->cfg.controller == e->value && !open_loop;
    void *state = running && drv->law == e ? (void *)drv->law_state : NULL;
    return e->law->command(state, &drv->cfg, record, subindex, running, apply);
}

const current_law_entry_t *current_law_override = NULL;

/* The selected law's record: the one the drive holds, or its EDS defaults
 * when the drive holds another (a law selected without its record written). */
static const void *law_record_of(const drive_t *drv, const current_law_entry_t *e)
{
    if (e->record_index == 0u) return NULL;
    return drv->law_record_index == e->record_index ? (const void *)drv->law_record : e->record_default;
}

static void drive_recompute(drive_t *drv)
{
    const drive_config_t *c = &drv->cfg;
    drive_state_t *s = &drv->st;
    outer_loops_design(&c->outer, &drv->outer, c->pole_pairs, c->psi_hat_Wb, c->J_hat_kgm2);
    const int switched = s->controller_cache != c->controller;
    drv->law = current_law_find(c->controller);
    if (drv->law != NULL) {
        const current_law_entry_t *e = drv->law;
        if (e->record_index != drv->law_record_index) {
            /* its record as the EDS writes it, until the node writes its own */
            drv->law_record_index = e->record_index;
            if (e->record_index != 0u) memcpy(drv->law_record, e->record_default, e->record_bytes);
        }
        if (switched) memset(drv->law_state, 0, sizeof drv->law_state); /* a law starts from reset */
        e->law->configure(drv->law_state, c, law_record_of(drv, e), switched);
        s->controller_cache = c->controller;
    }
    s->dirty = 0u;
}

void drive_init(drive_t *drv, const drive_config_t *cfg)
{
    memset(drv, 0, sizeof(*drv));
    drv->cfg = *cfg;
    outer_loops_reset(&drv->outer);
    drv->st.controller_cache = 0xFFu; /* every law starts from reset */
    drive_recompute(drv);
}

void drive_apply_config(drive_t *drv) { drv->st.dirty = 1u; }

void drive_update_config(drive_t *drv)
{
    if (drv->st.dirty != 0u) drive_recompute(drv);
}

void drive_attach_trace(drive_t *drv, trace_recorder_t *rec) { drv->trace = rec; }

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
    const current_law_entry_t *e = drv->law;
    if (e != NULL && e->law->speed_step != NULL) e->law->speed_step(drv->law_state, c, law_record_of(drv, e));
}

static void drive_fill_signals(drive_t *drv, const drive_meas_t *m)
{
    float *g = drv->st.signals;
    const drive_state_t *s = &drv->st;
    g[TRACE_SIG_IQ_REF] = s->iq_ref_A;
    g[TRACE_SIG_IQ] = s->i_q_A;
    g[TRACE_SIG_ID_REF] = s->id_ref_A;
    g[TRACE_SIG_ID] = s->i_d_A;
    g[TRACE_SIG_VQ] = s->out.v_q_V;
    g[TRACE_SIG_VD] = s->out.v_d_V;
    g[TRACE_SIG_VQ_STAR] = s->out.v_q_star_V;
    g[TRACE_SIG_VD_STAR] = s->out.v_d_star_V;
    g[TRACE_SIG_V_ALPHA] = s->out.v_alpha_V;
    g[TRACE_SIG_V_BETA] = s->out.v_beta_V;
    g[TRACE_SIG_OMEGA] = drv->outer.omega_m_rad_s;
    g[TRACE_SIG_OMEGA_REF] = drv->outer.omega_ref_rad_s;
    g[TRACE_SIG_THETA] = m->theta_m_rad;
    g[TRACE_SIG_THETA_E] = s->theta_e_rad;
    g[TRACE_SIG_POS_REF] = drv->outer.pos_ref_rad;
    g[TRACE_SIG_I_A] = m->i_a_A;
    g[TRACE_SIG_I_B] = m->i_b_A;
    g[TRACE_SIG_V_LIMITED] = (float)s->out.v_limited;
}

void drive_reset_controller_memory(drive_t *drv)
{
    if (drv->law != NULL && drv->law->law->reset != NULL) drv->law->law->reset(drv->law_state);
}

/* A law's command is a voltage the inverter can make: finite, and inside the
 * circle of radius Vmax_V (0: no limit) plus what the law says it adds after
 * its limit (a dead-time compensation: at most its amplitude on each phase,
 * itself finite, not negative and not above Vmax_V). */
static uint8_t drive_law_fault(const drive_config_t *c, const current_law_out_t *o)
{
    const float va = o->v_alpha_V, vb = o->v_beta_V, extra = o->v_after_limit_V;
    if (!((va - va) == 0.0f) || !((vb - vb) == 0.0f)) return (uint8_t)DRIVE_LAW_FAULT_NON_FINITE;
    if (!(extra >= 0.0f) || !((extra - extra) == 0.0f)) return (uint8_t)DRIVE_LAW_FAULT_NON_FINITE;
    if (c->Vmax_V > 0.0f) {
        if (extra > c->Vmax_V) return (uint8_t)DRIVE_LAW_FAULT_OUT_OF_LIMIT;
        const float bound = c->Vmax_V * 1.001f + 2.0f * extra;
        if (va * va + vb * vb > bound * bound) return (uint8_t)DRIVE_LAW_FAULT_OUT_OF_LIMIT;
    }
    return (uint8_t)DRIVE_LAW_FAULT_NONE;
}

void drive_current_step(drive_t *drv, const drive_meas_t *m, drive_cmd_t *cmd)
{
    drive_update_config(drv); /* the one config-change path */

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

    /* the law: output, then update with what is applied */
    const current_law_in_t in = {s->i_d_A, s->i_q_A, s->id_ref_A, s->iq_ref_A, s->theta_e_rad, s->omega_e_rad_s};
    memset(&s->out, 0, sizeof s->out);
    const current_law_entry_t *e = drv->law;
    if (e != NULL) {
        const void *rec = law_record_of(drv, e);
        e->law->step(drv->law_state, c, rec, &in, &s->out);
        s->law_fault = drive_law_fault(c, &s->out);
        if (s->law_fault != (uint8_t)DRIVE_LAW_FAULT_NONE) memset(&s->out, 0, sizeof s->out); /* 0 V instead */
        if (e->law->commit != NULL) e->law->commit(drv->law_state, c, rec, &in, &s->out);
    }
    cmd->v_alpha_V = s->out.v_alpha_V;
    cmd->v_beta_V = s->out.v_beta_V;

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

float drive_signal(const drive_t *drv, trace_signal_t id)
{
    if ((uint32_t)id >= (uint32_t)TRACE_SIG_COUNT) return 0.0f;
    return drv->st.signals[id];
}
