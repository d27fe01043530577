/* drive_app_law.c - the current laws' records of the drive app (drive_app.h): the parameter records
 * 0x2200-0x2203 -> drive_config_t and their checks, the Yao 2020 identification command (0x2206:15),
 * and the status of 0x2201 Online tuning, 0x2206 Yao 2020 DPCC, 0x2207 Zhao 2022.  The one file of
 * the app that knows the laws: the OD hooks (drive_app_od.c) call it.
 * Portable: no OS headers, no allocation, float32. */
#include <string.h>

#include "co_field_map.h"
#include "drive_app_internal.h"

/* The drive's parameter records -> drive_config_t, one row per EDS entry (the
 * lists od_drive_fields.h generates; the config's fields carry the EDS names). */
#define AT_ROOT(index, sub, record, field, eds_default) CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_config_t, record, field),
#define IN_IDENT(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, ident, record, field),
#define IN_OUTER(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, record, field),
#define IN_YAO(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, yao, record, field),
/* one list a line (clang-format would run the macro lists together) */
/* clang-format off */
static const co_field_map_t config_rows[] = {
    OD_DRIVE_CONTROLLER_PARAMS(AT_ROOT)
    OD_DRIVE_ONLINE_TUNING_PARAMS(IN_IDENT)
    OD_DRIVE_OUTER_LOOPS_PARAMS(IN_OUTER)
    OD_DRIVE_YAO_2020_DPCC_PARAMS(IN_YAO)
    /* the profile of References belongs to the outer loops */
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, x2202_References, profile_speed_rad_s),
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, x2202_References, profile_accel_rad_s2)};
/* clang-format on */
#undef AT_ROOT
#undef IN_IDENT
#undef IN_OUTER
#undef IN_YAO

/* OD -> drive_config_t.  core_ctrl: controller to keep when the OD selects the
 * open loop (the core has no open-loop controller). */
void drive_app_law_od_to_config(const od_drive_mfr_t *m, drive_config_t *c, uint8_t core_ctrl)
{
    co_field_map_to_core(config_rows, sizeof config_rows / sizeof config_rows[0], m, c);
    if (c->controller == (uint8_t)OD_DRIVE_CONTROLLER_OPEN_LOOP) c->controller = core_ctrl;
}

/* Would the core accept the parameter records of m?  (Its rules: drive_config_check.) */
static uint32_t check_config(const drive_t *d, const od_drive_mfr_t *m, int controller_written)
{
    drive_config_t c = d->cfg;
    co_field_map_to_core(config_rows, sizeof config_rows / sizeof config_rows[0], m, &c); /* 0 = open loop */
    if (controller_written && drive_config_check_selection(&c) != DRIVE_CONFIG_OK)
        return CO_ABORT_INVALID_VALUE; /* a surface-mounted law with a salient model */
    switch (drive_config_check(&c, m->x2202_References.mode)) {
    case DRIVE_CONFIG_OK: return 0;
    case DRIVE_CONFIG_NO_SUCH_CONTROLLER: return CO_ABORT_INVALID_VALUE;
    default: return CO_ABORT_PARAM_INCOMPAT;
    }
}

int drive_app_law_pre_write(const drive_app_t *app, const od_drive_mfr_t *m, const od_drive_mfr_t *cand,
                            const co_od_entry_t *e, const uint8_t *data, uint32_t *abort)
{
    const uint16_t idx = e->index;
    if (idx >= OD_DRIVE_CONTROLLER_IDX && idx <= OD_DRIVE_OUTER_LOOPS_IDX) {
        *abort = check_config(&app->drv, cand,
                              idx == OD_DRIVE_CONTROLLER_IDX && e->subindex == OD_DRIVE_CONTROLLER_CONTROLLER_SUB);
        return 1;
    }
    *abort = 0u;
    if (idx == OD_DRIVE_YAO_2020_DPCC_IDX && e->subindex == OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB) {
        const drive_t *d = &app->drv;
        if (data[0] == 1u) {
            if (d->cfg.controller != (uint8_t)DRIVE_CTRL_DPCC_YAO2020 ||
                m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP || d->cfg.yao.observer_enable == 0u)
                *abort = CO_ABORT_PARAM_INCOMPAT; /* the identification needs the DPCC with its observer */
            else if (d->yao.primed == 0u || yao2020_identification_running(&d->yao))
                *abort = CO_ABORT_DATA_STATE; /* not run yet / already running */
        }
        return 1;
    }
    return 0;
}

int drive_app_law_post_write(drive_app_t *app, od_drive_mfr_t *m, const co_od_entry_t *e)
{
    const uint16_t idx = e->index;
    if (idx == OD_DRIVE_YAO_2020_DPCC_IDX && e->subindex == OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB) {
        const uint8_t cmd = m->x2206_yao_2020_dpcc.ident_command;
        m->x2206_yao_2020_dpcc.ident_command = 0u; /* a command, not a state */
        if (cmd == 1u)
            (void)drive_yao_ident_start(&app->drv);
        else if (cmd == 2u)
            drive_yao_ident_abort(&app->drv);
        return 1;
    }
    const int is_config =
        idx == OD_DRIVE_CONTROLLER_IDX || idx == OD_DRIVE_ONLINE_TUNING_IDX || idx == OD_DRIVE_OUTER_LOOPS_IDX ||
        idx == OD_DRIVE_YAO_2020_DPCC_IDX ||
        (idx == OD_DRIVE_REFERENCES_IDX && (e->subindex == OD_DRIVE_REFERENCES_PROFILE_SPEED_RAD_S_SUB ||
                                            e->subindex == OD_DRIVE_REFERENCES_PROFILE_ACCEL_RAD_S2_SUB));
    if (is_config) { /* the one config-change path: copy, and recompute at the next step if it changed */
        drive_config_t c = app->drv.cfg;
        drive_app_law_od_to_config(m, &c, c.controller);
        if (memcmp(&c, &app->drv.cfg, sizeof c) != 0) {
            app->drv.cfg = c;
            drive_apply_config(&app->drv);
        }
        return 1;
    }
    return 0;
}

/* ------------------------------------------------------------------ refresh (pre_read) */

int drive_app_law_refresh(const drive_app_t *app, od_drive_mfr_t *m, uint16_t index)
{
    const drive_t *d = &app->drv;
    switch (index) {
    case OD_DRIVE_ONLINE_TUNING_IDX: {
#define t (&m->x2201_online_tuning)
        t->det_A2 = d->ident.q.det_A2;
        t->K1_hat_V_A = d->ident.q.K1_hat_V_A;
        t->K2_hat_V_A = d->ident.q.K2_hat_V_A;
        t->K1_bar_V_A = d->ident.q.K1_bar_V_A;
        t->K2_bar_V_A = d->ident.q.K2_bar_V_A;
        t->L_hat_H = d->ident.q.L_hat_H;
        t->identifications = d->ident.q.n_identified;
        t->K1_active_V_A = d->db.K1q_V_A;
        t->K2_active_V_A = d->db.K2q_V_A;
        t->gain_updates = d->st.n_gain_updates;
#undef t
        return 1;
    }
    case OD_DRIVE_YAO_2020_DPCC_IDX: {
#define y (&m->x2206_yao_2020_dpcc)
        const yao2020_dpcc_state_t *st = &d->yao;
        y->ident_state = st->id_state;
        y->abort_reason = st->abort_reason;
        y->progress = yao2020_identification_progress(&d->yao_cfg, st);
        y->R_hat_ohm = st->R_hat_ohm;
        y->L_hat_H = st->L_hat_H;
        y->R_id_ohm = st->R_id_ohm;
        y->L_id_H = st->L_id_H;
        y->L_converged = st->L_converged;
        y->R_converged = st->R_converged;
        y->t_L_conv_s = (float)st->t_L_conv_periods * d->cfg.Ts_s;
        y->t_R_conv_s = (float)st->t_R_conv_periods * d->cfg.Ts_s;
        y->dM_d_V = st->dM_d_V;
        y->dM_q_V = st->dM_q_V;
        y->motor_class = st->motor_class;
        y->gains_high = st->gains_high;
        y->rls_R_hat_ohm = d->rls.R_hat_ohm;
        y->rls_L_hat_H = d->rls.L_hat_H;
        y->p_hat_d_A = st->p_hat_d_A;
        y->p_hat_q_A = st->p_hat_q_A;
#undef y
        return 1;
    }
    case OD_DRIVE_ZHAO_2022_IDX:
        m->x2207_zhao_2022.K1_V_A = d->inc.K1_V_A;
        m->x2207_zhao_2022.K2_V_A = d->inc.K2_V_A;
        m->x2207_zhao_2022.G_V_A = d->eul.G_V_A;
        m->x2207_zhao_2022.limited =
            d->cfg.controller == (uint8_t)DRIVE_CTRL_INCREMENTAL_ZHAO2022 ? d->inc.limited : d->eul.limited;
        return 1;
    default: return 0;
    }
}
