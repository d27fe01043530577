/* drive_output.c - see drive_output.h. */
#include "drive_output.h"

void drive_output_zero(drive_t *d)
{
    drive_state_t *s = &d->st;
    s->out.v_d_V = s->out.v_q_V = 0.0f;
    s->out.v_d_star_V = s->out.v_q_star_V = 0.0f;
    s->out.v_d_ff_V = s->out.v_q_ff_V = 0.0f;
    s->out.v_alpha_V = s->out.v_beta_V = 0.0f;
    s->out.v_limited = 0u;
    s->signals[TRACE_SIG_VQ] = 0.0f;
    s->signals[TRACE_SIG_VD] = 0.0f;
    s->signals[TRACE_SIG_VQ_STAR] = 0.0f;
    s->signals[TRACE_SIG_VD_STAR] = 0.0f;
    s->signals[TRACE_SIG_V_ALPHA] = 0.0f;
    s->signals[TRACE_SIG_V_BETA] = 0.0f;
    s->signals[TRACE_SIG_V_LIMITED] = 0.0f;
}

void drive_output_clear_memory(drive_t *d)
{
    drive_reset_controller_memory(d);
    d->outer.integ_A = 0.0f;
    d->outer.iq_ref_A = 0.0f;
    d->outer.pos_ref_rad = d->outer.theta_unwrapped_rad;
    d->outer.vel_ref_rad_s = 0.0f;
    d->st.signals[TRACE_SIG_POS_REF] = d->outer.pos_ref_rad;
}

trace_recorder_t *drive_output_step_without_output(drive_t *d, const drive_meas_t *meas, drive_cmd_t *cmd)
{
    trace_recorder_t *rec = d->trace;
    d->trace = NULL;
    drive_current_step(d, meas, cmd);
    d->trace = rec;
    drive_reset_controller_memory(d);
    return rec;
}
