/* drive_app.c - the drive firmware as a CANopen node (see drive_app.h): init, bind, the hooks
 * table and the NMT/SYNC/RPDO/reset hooks, the current step.  The other concerns are in the
 * drive_app_*.c files (drive_app_internal.h lists them).
 * Portable: no OS headers, no allocation, float32. */
#include "drive_app.h"

#include <string.h>

#include "dq_math.h"
#include "drive_app_internal.h"

/* ------------------------------------------------------------------ current step */

/* The core runs for the angle, the dq currents, the speed estimate and its
 * bookkeeping; its controller output is discarded and its memory cleared (no
 * wind-up, clean restart when the loop is closed again).  Returns the trace
 * recorder, detached meanwhile: the caller samples it with its own voltages. */
trace_recorder_t *drive_app_core_step_without_output(drive_app_t *app)
{
    drive_t *d = &app->drv;
    trace_recorder_t *rec = d->trace;
    d->trace = NULL;
    drive_current_step(d, &app->meas, &app->cmd);
    d->trace = rec;
    drive_reset_controller_memory(d);
    return rec;
}

static void open_loop_step(drive_app_t *app, const od_drive_mfr_t *m)
{
    drive_t *d = &app->drv;
    drive_state_t *s = &d->st;
    trace_recorder_t *rec = drive_app_core_step_without_output(app);

    float vd = m->x2202_References.v_d_open_V;
    float vq = m->x2202_References.v_q_open_V;
    if (!is_finite_f(vd)) {
        vd = 0.0f;
        ++app->safe_state.non_finite_rejected;
    }
    if (!is_finite_f(vq)) {
        vq = 0.0f;
        ++app->safe_state.non_finite_rejected;
    }
    s->out.v_limited = dq_limit_voltage(&vd, &vq, d->cfg.Vmax_V, d->cfg.vlimit_radial);
    const float cs = cosf(s->theta_e_rad);
    const float sn = sinf(s->theta_e_rad);
    s->out.v_d_V = s->out.v_d_star_V = vd;
    s->out.v_q_V = s->out.v_q_star_V = vq;
    s->out.v_d_ff_V = s->out.v_q_ff_V = 0.0f;
    dq_inv_park(vd, vq, cs, sn, &s->out.v_alpha_V, &s->out.v_beta_V);
    s->signals[TRACE_SIG_VQ] = vq;
    s->signals[TRACE_SIG_VD] = vd;
    s->signals[TRACE_SIG_VQ_STAR] = vq;
    s->signals[TRACE_SIG_VD_STAR] = vd;
    s->signals[TRACE_SIG_V_ALPHA] = s->out.v_alpha_V;
    s->signals[TRACE_SIG_V_BETA] = s->out.v_beta_V;
    s->signals[TRACE_SIG_V_LIMITED] = (float)s->out.v_limited;
    if (rec != NULL) trace_sample(rec, s->signals);
    app->cmd.v_alpha_V = s->out.v_alpha_V;
    app->cmd.v_beta_V = s->out.v_beta_V;
}

/* ------------------------------------------------------------------ current step (continued) */

/* The measurement of 0x2100 -> app->meas: a non-finite field (PDOs bypass the EDS limits) is
 * replaced by its last finite value. */
static void take_measurement(drive_app_t *app, const od_drive_mfr_t *m)
{
    uint8_t bad = 0u;
#define x (&m->x2100_Measurement)
    if (is_finite_f(x->i_a_A))
        app->meas_good.i_a_A = x->i_a_A;
    else
        bad |= (uint8_t)DRIVE_NON_FINITE_I_A;
    if (is_finite_f(x->i_b_A))
        app->meas_good.i_b_A = x->i_b_A;
    else
        bad |= (uint8_t)DRIVE_NON_FINITE_I_B;
    if (is_finite_f(x->theta_m_rad))
        app->meas_good.theta_m_rad = x->theta_m_rad;
    else
        bad |= (uint8_t)DRIVE_NON_FINITE_THETA;
    app->meas = app->meas_good;
    app->non_finite_mask = bad;
    if (bad == 0u) {
        app->have_good = 1u;
        app->good_sample_index = x->sample_index;
    } else {
        app->safe_state.non_finite_rejected += (uint32_t)((bad & 1u) + ((bad >> 1) & 1u) + ((bad >> 2) & 1u));
    }
#undef x
}

/* The references of 0x2202 -> the core's set-points; returns the mode of 0x2202:01. */
static uint8_t take_references(drive_app_t *app, const od_drive_mfr_t *m)
{
    drive_t *d = &app->drv;
    /* references (SDO or RPDO3 wrote them; PDO writes bypass the EDS limits:
     * non-finite values are ignored, and counted) */
#define r (&m->x2202_References)
    const uint8_t mode = r->mode;
    d->sp.mode = mode <= (uint8_t)DRIVE_MODE_POSITION ? mode : (uint8_t)DRIVE_MODE_CURRENT;
    uint32_t refs_bad = 0u;
    if (is_finite_f(r->iq_ref_A))
        d->sp.iq_ref_A = r->iq_ref_A;
    else
        ++refs_bad;
    if (is_finite_f(r->id_ref_A))
        d->sp.id_ref_A = r->id_ref_A;
    else
        ++refs_bad;
    if (is_finite_f(r->speed_ref_rad_s))
        d->sp.speed_ref_rad_s = r->speed_ref_rad_s;
    else
        ++refs_bad;
    if (is_finite_f(r->position_ref_rad))
        d->sp.position_ref_rad = r->position_ref_rad;
    else
        ++refs_bad;
    app->safe_state.non_finite_rejected += refs_bad;
#undef r
    return mode;
}

void drive_app_step(drive_app_t *app)
{
    co_node_t *node = app->node;
    if (node == NULL) return;
    od_drive_mfr_t *m = mfr_of(node);
    drive_t *d = &app->drv;

    take_measurement(app, m);
    const uint8_t mode = take_references(app, m);
    app->open_loop =
        (uint8_t)(m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP || mode == OD_DRIVE_MODE_OPEN_LOOP);
    if (m->x2200_Controller.controller != app->cost_controller) {
        drive_app_reset_step_cost(app);
        app->cost_controller = m->x2200_Controller.controller;
    }
    /* CiA 402: a quick stop that has ended leaves before this command; then the mode's references */
    drive_app_cia402_check_stopped(app, node);
    const int powered = drive_app_cia402_references(app, m);
    const uint32_t c0 = app->cycles_fn != NULL ? app->cycles_fn(app->cycles_user) : 0u;
    if (app->safe_state.reason != (uint8_t)OD_DRIVE_REASON_NONE || !powered ||
        (app->open_loop && app->cia402.state == (uint8_t)CIA402_QUICK_STOP_ACTIVE)) {
        drive_app_safe_step(app); /* 0 V */
    } else if (app->open_loop) {
        open_loop_step(app, m);
    } else {
        drive_current_step(d, &app->meas, &app->cmd); /* a law's bad command is 0 V (drive_core.h) */
        if (d->st.law_fault != (uint8_t)DRIVE_LAW_FAULT_NONE)
            drive_app_enter_safe_state_in_step(app, node, (uint8_t)OD_DRIVE_REASON_LAW_OUTPUT);
    }
    if (app->cycles_fn != NULL) {
        const uint32_t cycles = app->cycles_fn(app->cycles_user) - c0;
        drive_app_count_step_cost(app, cycles);
        if (app->overrun_check != 0u && (float)cycles > d->cfg.Ts_s * (float)app->cycle_clock_Hz)
            drive_app_enter_safe_state_in_step(app, node, (uint8_t)OD_DRIVE_REASON_OVERRUN);
    }
    ++app->drive_status.current_steps;

    m->x2102_voltage_command.v_alpha_V = app->cmd.v_alpha_V;
    m->x2102_voltage_command.v_beta_V = app->cmd.v_beta_V;
    co_tpdo_request(node, 0); /* event-driven: goes out now */

    if (node->tpdo[1].valid) {
        uint16_t dec = m->x2302_live_trace.decimation;
        if (dec == 0u) dec = 1u;
        if (++app->live_count >= dec) {
            app->live_count = 0u;
            co_tpdo_request(node, 1); /* values refreshed by pre_read */
        }
    }
}

void drive_app_current_step(drive_app_t *app)
{
    if (app->node == NULL) return;
    drive_app_step(app);
    drive_app_report_non_finite(app, mfr_of(app->node)->x2100_Measurement.sample_index);
}

/* ------------------------------------------------------------------ hooks */

static void hk_on_sync(void *user, co_node_t *node, uint8_t counter)
{
    drive_app_t *app = (drive_app_t *)user;
    if (app->rpdo1_fresh) {
        /* the currents of the previous sample never got their RPDO2 */
        app->rpdo1_fresh = 0u;
        drive_app_count_late(app, DRIVE_LATE_RPDO1_WITHOUT_RPDO2, app->drive_status.last_sample_index, counter);
    }
    app->sync_seen = 1u;
    app->last_sync_counter = counter;
    /* measurement timeout: SYNCs since the last measurement */
    if (node->nmt == CO_NMT_OPERATIONAL && app->meas_seen) {
        if (app->syncs_without_meas < 0xFFFFu) ++app->syncs_without_meas;
        const uint16_t n = mfr_of(node)->x2209_safe_state.meas_timeout_periods;
        if (n != 0u && app->syncs_without_meas >= n)
            drive_app_enter_safe_state(app, node, (uint8_t)OD_DRIVE_REASON_MEAS_TIMEOUT);
    }
}

static void hk_on_rpdo(void *user, co_node_t *node, uint8_t pdo)
{
    drive_app_t *app = (drive_app_t *)user;
    app->node = node;
    if (pdo == 0u) {
        if (app->rpdo1_fresh) {
            od_drive_mfr_t *m = mfr_of(node);
            drive_app_count_late(app, DRIVE_LATE_RPDO1_WITHOUT_RPDO2, m->x2100_Measurement.sample_index,
                                 m->x2100_Measurement.sync_counter);
        }
        app->rpdo1_fresh = 1u;
    } else if (pdo == 1u) {
        drive_app_on_measurement(app, node);
    } else if (drive_app_pdo_maps(&node->rpdo[pdo], OD_DRIVE_CONTROLWORD_IDX)) {
        drive_app_cia402_on_controlword(app, node); /* RPDO4 by default; the target torque is read by the next step */
    }
    /* pdo 2 (references): read by the next step */
}

static void hk_on_nmt(void *user, co_node_t *node, co_nmt_state_t state)
{
    drive_app_t *app = (drive_app_t *)user;
    drive_app_reset_sequencing(app);
    /* CiA 402: leaving OPERATIONAL disables the power stage (the "disable voltage" reaction of 0x6007) */
    if (state != CO_NMT_OPERATIONAL) {
        const int was_powered = cia402_device_power_enabled(&app->cia402);
        if (cia402_device_disable_voltage(&app->cia402)) drive_app_cia402_changed(app, node, was_powered);
    }
    /* started while the plant's heartbeat is still lost: not a state to run in */
    if (state == CO_NMT_OPERATIONAL && drive_app_heartbeat_lost(node))
        drive_app_enter_safe_state(app, node, (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST);
    if (state == CO_NMT_OPERATIONAL) drive_app_send_statusword(node);
}

static void hk_on_hb_timeout(void *user, co_node_t *node, uint8_t node_id)
{
    drive_app_t *app = (drive_app_t *)user;
    (void)node_id; /* the stack's EMCY 0x8130 names it */
    if (node->nmt == CO_NMT_OPERATIONAL) drive_app_enter_safe_state(app, node, (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST);
}

static void hk_on_reset(void *user, co_node_t *node, int communication_only)
{
    drive_app_t *app = (drive_app_t *)user;
    od_drive_mfr_t *m = mfr_of(node);
    app->node = node;
    if (!communication_only) {
        /* reset application: OD defaults -> fresh firmware core */
        drive_config_t cfg;
        drive_default_config(&cfg);
        drive_app_law_od_to_config(m, &cfg, cfg.controller);
        drive_init(&app->drv, &cfg);
        if (drive_app_law_sync(app)) drive_apply_config(&app->drv);
        trace_init(&app->trace);
        drive_attach_trace(&app->drv, &app->trace);
        app->drive_status.current_steps = app->drive_status.lost_measurements = app->drive_status.late_measurements =
            app->emcy_raised = 0u;
        app->meas_error_active = 0u;
        app->safe_state.entries = 0u;
        app->safe_state.entered_at_sample = 0u;
        app->have_good = 0u;
        app->good_sample_index = 0u;
        app->safe_state.non_finite_rejected = 0u;
        memset(&app->meas_good, 0, sizeof app->meas_good);
        app->open_loop = 0u;
        app->trace_linear = 0u;
        app->live_count = 0u;
        drive_app_reset_step_cost(app);
        memset(&app->meas, 0, sizeof app->meas);
        memset(&app->cmd, 0, sizeof app->cmd);
    }
    drive_app_reset_sequencing(app);
    /* both resets leave the safe state (the stack has forgotten the active EMCYs), and the
     * CiA 402 state machine starts again in SWITCH ON DISABLED */
    app->safe_state.reason = (uint8_t)OD_DRIVE_REASON_NONE;
    drive_app_cia402_reset(app, node);
    app->non_finite_mask = 0u;
    app->non_finite_active = 0u;
    m->x2301_trace_buffer.data = (uint8_t *)app->trace.buffer;
    m->x2301_trace_buffer.size = 0u;
    m->x2301_trace_buffer.capacity = 0u;
}

static const co_hooks_t g_hooks = {
    .pre_write = drive_app_od_pre_write,
    .post_write = drive_app_od_post_write,
    .pre_read = drive_app_od_pre_read,
    .on_sync = hk_on_sync,
    .on_rpdo = hk_on_rpdo,
    .on_nmt = hk_on_nmt,
    .on_reset = hk_on_reset,
    .on_hb_timeout = hk_on_hb_timeout,
};

const co_hooks_t *drive_app_hooks(void) { return &g_hooks; }

/* ------------------------------------------------------------------ API */

void drive_app_init(drive_app_t *app)
{
    memset(app, 0, sizeof *app);
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&app->drv, &cfg);
    trace_init(&app->trace);
    drive_attach_trace(&app->drv, &app->trace);
}

void drive_app_bind(drive_app_t *app, co_node_t *node) { app->node = node; }

void drive_app_set_cycle_counter(drive_app_t *app, drive_app_cycles_fn fn, void *user, uint32_t clock_Hz)
{
    app->cycles_fn = fn;
    app->cycles_user = user;
    app->cycle_clock_Hz = clock_Hz;
    drive_app_reset_step_cost(app);
}

void drive_app_set_overrun_check(drive_app_t *app, uint8_t on) { app->overrun_check = on; }

void drive_app_load_config(drive_app_t *app)
{
    if (app->node == NULL) return;
    drive_app_law_od_to_config(mfr_of(app->node), &app->drv.cfg, app->drv.cfg.controller);
    (void)drive_app_law_sync(app);
    drive_apply_config(&app->drv);
}
