/* drive_app.c - the drive firmware as a CANopen node (see drive_app.h): the root of its components.  It holds
 * the core and the components (supervision, CiA 402, the law slot, the recorders), binds them at init, and runs
 * one period top to bottom (drive_app_period); the components return verdicts and act through the root.
 * Portable: no OS headers, no allocation, float32. */
#include "drive_app.h"

#include <string.h>

#include "dq_math.h"
#include "drive_od.h"
#include "drive_output.h"

/* ------------------------------------------------------------------ what crosses components */

/* 0 V now: the control's memory forgotten, the command and 0x2102 zero, sent at once (send_now) or by the step
 * the call is made from (one command a period on the bus). */
static void zero_command(drive_app_t *app, int send_now)
{
    od_drive_mfr_t *m = mfr_of(app->node);
    drive_output_clear_memory(&app->drv);
    drive_output_zero(&app->drv);
    app->cmd.v_alpha_V = 0.0f;
    app->cmd.v_beta_V = 0.0f;
    m->x2102_voltage_command.v_alpha_V = 0.0f;
    m->x2102_voltage_command.v_beta_V = 0.0f;
    if (send_now) co_tpdo_request(app->node, 0);
}

/* The power stage's state changed: the statusword follows; a power stage switched off commands 0 V at once. */
static void power_changed(drive_app_t *app, int was_powered)
{
    drive_cia402_latch_statusword(&app->cia);
    if (was_powered && !drive_cia402_powered(&app->cia)) zero_command(app, 1);
    drive_cia402_send_statusword(&app->cia);
}

/* The safe state (drive_app.h): latched by supervision, 0 V now (sent at once, or by the step it is entered
 * in: one command a period on the bus), its EMCY, then CiA 402's FAULT with the EMCY code as the error code. */
static void enter_safe_state(drive_app_t *app, uint8_t reason, int send_now)
{
    if (!drive_sup_latch(&app->sup, reason)) return;
    zero_command(app, send_now);
    drive_sup_safe_emcy(&app->sup);
    if (drive_cia402_fault(&app->cia, drive_sup_safe_code(reason))) power_changed(app, 0);
}

static void leave_safe_state(drive_app_t *app)
{
    if (drive_sup_release(&app->sup) == (uint8_t)OD_DRIVE_REASON_NONE) return;
    if (drive_cia402_fault_reset(&app->cia)) power_changed(app, 0);
}

/* Supervision: 0x2209:05 clear = 1 was written. */
static void on_clear(void *root) { leave_safe_state((drive_app_t *)root); }

/* CiA 402: a controlword changed the state; a fault reset leaves the safe state first. */
static void on_cia402_change(void *root, int was_powered, int from_fault)
{
    drive_app_t *app = (drive_app_t *)root;
    if (from_fault) leave_safe_state(app);
    power_changed(app, was_powered);
}

/* ------------------------------------------------------------------ the step */

static void open_loop_step(drive_app_t *app, const od_drive_mfr_t *m)
{
    drive_t *d = &app->drv;
    drive_state_t *s = &d->st;
    trace_recorder_t *rec = drive_output_step_without_output(d, &app->meas, &app->cmd);

    float vd = m->x2202_References.v_d_open_V;
    float vq = m->x2202_References.v_q_open_V;
    if (!is_finite_f(vd)) {
        vd = 0.0f;
        drive_sup_note_rejected(&app->sup, 1u);
    }
    if (!is_finite_f(vq)) {
        vq = 0.0f;
        drive_sup_note_rejected(&app->sup, 1u);
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
    drive_sup_note_values(&app->sup, bad, x->sample_index);
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
    drive_sup_note_rejected(&app->sup, refs_bad);
#undef r
    return mode;
}

/* A step in the safe state: the core runs (observers, speed estimate), the command is zero. */
static void safe_step(drive_app_t *app)
{
    drive_t *d = &app->drv;
    trace_recorder_t *rec = drive_output_step_without_output(d, &app->meas, &app->cmd);
    drive_output_clear_memory(d);
    drive_output_zero(d);
    if (rec != NULL) trace_sample(rec, d->st.signals);
    app->cmd.v_alpha_V = 0.0f;
    app->cmd.v_beta_V = 0.0f;
}

/* An event-driven TPDO3/4 that maps no CiA 402 object (0x6000-0x67FF, sent on their own events) is a trace of the
 * period: it goes out when the next period's measurement arrives, before that period's step, the state after the
 * step before (the bench maps the trace TPDOs so when no SYNC marks the period: a synchronous one would go out at
 * SYNC k + 1 with the same values; sent after the step, the plant's next measurement could overtake it). */
static int period_trace_tpdo(const co_pdo_t *p)
{
    if (!p->valid || p->trans_type < 254u) return 0;
    for (uint8_t i = 0; i < p->count; ++i)
        if (p->entry[i]->index >= 0x6000u && p->entry[i]->index <= 0x67FFu) return 0;
    return 1;
}

/* The current step on the measurement and references of the OD: CiA 402 power -> law step, 0 V or open loop ->
 * guard (law output, overrun) -> fault transition -> TPDO1 (and the live trace's TPDO2 when due).  Supervision
 * counts it when it finishes the period. */
static void step(drive_app_t *app)
{
    co_node_t *node = app->node;
    od_drive_mfr_t *m = mfr_of(node);
    drive_t *d = &app->drv;

    take_measurement(app, m);
    const uint8_t mode = take_references(app, m);
    app->open_loop =
        (uint8_t)(m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP || mode == OD_DRIVE_MODE_OPEN_LOOP);
    /* CiA 402: a quick stop that has ended leaves before this command; then the mode's references */
    const drive_cia402_power_t power = drive_cia402_power(&app->cia, d, m);
    if (power.stopped) power_changed(app, 0);
    drive_recorder_begin(&app->rec, m->x2200_Controller.controller);
    const uint32_t c0 = drive_recorder_now(&app->rec);
    if (drive_sup_safe(&app->sup) || !power.powered || (app->open_loop && drive_cia402_quick_stopping(&app->cia))) {
        safe_step(app); /* 0 V */
    } else if (app->open_loop) {
        open_loop_step(app, m);
    } else {
        drive_current_step(d, &app->meas, &app->cmd); /* a law's bad command is 0 V (drive_core.h) */
        if (d->st.law_fault != (uint8_t)DRIVE_LAW_FAULT_NONE)
            enter_safe_state(app, (uint8_t)OD_DRIVE_REASON_LAW_OUTPUT, 0);
    }
    const uint32_t c1 = drive_recorder_now(&app->rec);
    const drive_recorder_step_t rec = drive_recorder_end(&app->rec, c1 - c0);
    if (rec.counted && app->overrun_check != 0u && (float)rec.cycles > d->cfg.Ts_s * (float)app->rec.cycle_clock_Hz)
        enter_safe_state(app, (uint8_t)OD_DRIVE_REASON_OVERRUN, 0);

    m->x2102_voltage_command.v_alpha_V = app->cmd.v_alpha_V;
    m->x2102_voltage_command.v_beta_V = app->cmd.v_beta_V;
    co_tpdo_request(node, 0);                   /* event-driven: goes out now */
    if (rec.live_due) co_tpdo_request(node, 1); /* values refreshed when read */
}

/* One period, on the measurement's RPDO2: supervision admits it (or not: a second copy of the sample just
 * answered), the step, then the measurement's EMCYs after its command. */
static void drive_app_period(drive_app_t *app)
{
    const uint16_t si = mfr_of(app->node)->x2100_Measurement.sample_index;
    const drive_sup_verdict_t v = drive_sup_admit(&app->sup);
    if (v == DRIVE_SUP_STEP) step(app);
    drive_sup_finish(&app->sup, v, si);
}

void drive_app_current_step(drive_app_t *app)
{
    if (app->node == NULL) return;
    step(app);
    drive_sup_finish(&app->sup, DRIVE_SUP_STEP, mfr_of(app->node)->x2100_Measurement.sample_index);
}

/* ------------------------------------------------------------------ hooks */

static void hk_bind(void *user, co_node_t *node)
{
    drive_app_t *app = (drive_app_t *)user;
    app->node = node;
    drive_sup_bind(&app->sup, node, &app->drv, on_clear, app);
    drive_cia402_bind(&app->cia, node, &app->drv, on_cia402_change, app);
    drive_law_slot_bind(&app->law, node, &app->drv);
    drive_recorder_bind(&app->rec, node);
}

static void hk_on_sync(void *user, co_node_t *node, uint8_t counter)
{
    drive_app_t *app = (drive_app_t *)user;
    if (drive_sup_on_sync(&app->sup, counter, node->nmt == CO_NMT_OPERATIONAL))
        enter_safe_state(app, (uint8_t)OD_DRIVE_REASON_MEAS_TIMEOUT, 1);
}

static void hk_on_rpdo(void *user, co_node_t *node, uint8_t pdo)
{
    drive_app_t *app = (drive_app_t *)user;
    app->node = node;
    const co_pdo_t *p = &node->rpdo[pdo];
    /* the measurement: the RPDO with the SYNC counter is the period's (RPDO2 by default); another one of
     * 0x2100 carries the currents before it (RPDO1); the compact frame carries both, and its codes */
    if (co_pdo_maps_entry(p, OD_DRIVE_MEASUREMENT_IDX, OD_DRIVE_MEASUREMENT_SYNC_COUNTER_SUB)) {
        for (uint8_t n = 2; n < CO_NUM_PDO; ++n) /* the step before's traces, before this period's step */
            if (period_trace_tpdo(&node->tpdo[n])) co_tpdo_request(node, n);
        const int coded = drive_meas_coding_take(&app->coding, node, p);
        if (coded || co_pdo_maps_entry(p, OD_DRIVE_MEASUREMENT_IDX, OD_DRIVE_MEASUREMENT_I_A_A_SUB))
            drive_sup_on_rpdo1(&app->sup);
        drive_app_period(app);
    } else if (co_pdo_maps(p, OD_DRIVE_MEASUREMENT_IDX))
        drive_sup_on_rpdo1(&app->sup);
    else if (co_pdo_maps(p, OD_DRIVE_CONTROLWORD_IDX))
        drive_cia402_controlword(&app->cia); /* RPDO4 by default; the target torque is read by the next step */
    /* pdo 2 (references): read by the next step */
}

static void hk_on_nmt(void *user, co_node_t *node, co_nmt_state_t state)
{
    drive_app_t *app = (drive_app_t *)user;
    drive_sup_reset_sequencing(&app->sup);
    drive_meas_coding_reset(&app->coding);
    /* CiA 402: leaving OPERATIONAL disables the power stage (the "disable voltage" reaction of 0x6007) */
    if (state != CO_NMT_OPERATIONAL) {
        const int was_powered = drive_cia402_powered(&app->cia);
        if (drive_cia402_disable_voltage(&app->cia)) power_changed(app, was_powered);
    }
    /* started while the plant's heartbeat is still lost: not a state to run in */
    if (state == CO_NMT_OPERATIONAL && drive_heartbeat_lost(node))
        enter_safe_state(app, (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST, 1);
    if (state == CO_NMT_OPERATIONAL) drive_cia402_send_statusword(&app->cia);
}

static void hk_on_hb_timeout(void *user, co_node_t *node, uint8_t node_id)
{
    drive_app_t *app = (drive_app_t *)user;
    (void)node_id; /* the stack's EMCY 0x8130 names it */
    if (node->nmt == CO_NMT_OPERATIONAL) enter_safe_state(app, (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST, 1);
}

static void hk_on_reset(void *user, co_node_t *node, int communication_only)
{
    drive_app_t *app = (drive_app_t *)user;
    app->node = node;
    if (!communication_only) {
        /* reset application: OD defaults -> fresh firmware core */
        drive_config_t cfg;
        drive_default_config(&cfg);
        drive_law_slot_od_to_config(mfr_of(node), &cfg, cfg.controller);
        drive_init(&app->drv, &cfg);
        if (drive_law_slot_sync(&app->law)) drive_apply_config(&app->drv);
        drive_recorder_reset(&app->rec);
        memset(&app->meas_good, 0, sizeof app->meas_good);
        app->open_loop = 0u;
        memset(&app->meas, 0, sizeof app->meas);
        memset(&app->cmd, 0, sizeof app->cmd);
    }
    /* both resets leave the safe state (the stack has forgotten the active EMCYs), and the CiA 402 state
     * machine starts again in SWITCH ON DISABLED */
    drive_sup_reset(&app->sup, !communication_only);
    drive_meas_coding_reset(&app->coding);
    drive_cia402_reset(&app->cia);
    drive_recorder_publish_buffer(&app->rec);
}

static const co_hooks_t g_hooks = {
    .bind = hk_bind,
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
    drive_recorder_init(&app->rec, &app->drv);
}

void drive_app_bind(drive_app_t *app, co_node_t *node) { app->node = node; }

void drive_app_set_cycle_counter(drive_app_t *app, drive_app_cycles_fn fn, void *user, uint32_t clock_Hz)
{
    drive_recorder_set_cycle_counter(&app->rec, fn, user, clock_Hz);
}

void drive_app_set_overrun_check(drive_app_t *app, uint8_t on) { app->overrun_check = on; }

void drive_app_load_config(drive_app_t *app)
{
    if (app->node == NULL) return;
    drive_law_slot_od_to_config(mfr_of(app->node), &app->drv.cfg, app->drv.cfg.controller);
    (void)drive_law_slot_sync(&app->law);
    drive_apply_config(&app->drv);
}
