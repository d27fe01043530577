/*
 * plant_inverter.c - the inverter block of the plant emulator (see
 * plant_inverter.h).
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include "plant_inverter.h"

#include <math.h>

double plant_inverter_deadtime_phase_error_V(const plant_config_t *c, double i_phase_A)
{
    if (c->t_dead_s <= 0.0) {
        return 0.0;
    }
    const double Tpwm = (c->Ts_pwm_s > 0.0) ? c->Ts_pwm_s : c->Ts_s;
    const double Vdt = c->Vdc_V * c->t_dead_s / Tpwm;
    double g;
    if (c->deadtime_I_sat_A > 0.0) {
        g = tanh(i_phase_A / c->deadtime_I_sat_A);
    } else {
        g = (i_phase_A > 0.0) ? 1.0 : ((i_phase_A < 0.0) ? -1.0 : 0.0);
    }
    return -Vdt * g;
}

void plant_inverter_modulation_limit(const plant_config_t *c, double *v_alpha_V, double *v_beta_V)
{
    const double va = *v_alpha_V, vb = *v_beta_V;
    const double r = c->Vdc_V / PLANT_SQRT3; /* inscribed circle radius */
    double scale = 1.0;
    if (c->mod_limit == PLANT_MOD_CIRCLE) {
        const double m2 = va * va + vb * vb;
        if (m2 > r * r) {
            scale = r / sqrt(m2);
        }
    } else if (c->mod_limit == PLANT_MOD_SVPWM_HEX) {
        /* Hexagon = intersection of three slabs |v . n_k| <= Vdc/sqrt(3),
         * n_k at 30, 90 and 150 degrees (vertices on the phase axes). */
        const double p30 = fabs(0.5 * PLANT_SQRT3 * va + 0.5 * vb);
        const double p150 = fabs(-0.5 * PLANT_SQRT3 * va + 0.5 * vb);
        double m = fabs(vb);
        if (p30 > m) {
            m = p30;
        }
        if (p150 > m) {
            m = p150;
        }
        if (m > r) {
            scale = r / m;
        }
    }
    *v_alpha_V = va * scale;
    *v_beta_V = vb * scale;
}

void plant_inverter_prepare(plant_state_t *s, const plant_config_t *c)
{
    if (c->t_dead_s > 0.0) {
        const double Tpwm = (c->Ts_pwm_s > 0.0) ? c->Ts_pwm_s : c->Ts_s;
        s->Vdt_V = c->Vdc_V * c->t_dead_s / Tpwm;
    } else {
        s->Vdt_V = 0.0;
    }
}

/* A broken model state is a trip whatever the level: every comparison with
 * NaN is false, so a level alone would never see it. */
void plant_inverter_check_trip(plant_state_t *s, const plant_config_t *c, double ia_A, double ib_A, double ic_A)
{
    if (s->tripped) {
        return;
    }
    if (!isfinite(ia_A) || !isfinite(ib_A) || !isfinite(ic_A)) {
        s->tripped = true;
    } else if (c->I_trip_A > 0.0 &&
               (fabs(ia_A) > c->I_trip_A || fabs(ib_A) > c->I_trip_A || fabs(ic_A) > c->I_trip_A)) {
        s->tripped = true;
    }
}

void plant_inverter_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V, double ia_A,
                         double ib_A, double ic_A)
{
    /* An inverter cannot output a non-finite voltage: such a command (a
     * diverged controller whose float state overflowed) trips the bridge
     * before it reaches the model, so the state stays finite and the trip is
     * latched from this period on. */
    if (!isfinite(v_alpha_V) || !isfinite(v_beta_V)) {
        s->tripped = true;
    }

    double va = v_alpha_V, vb = v_beta_V;
    if (c->mod_limit != PLANT_MOD_NONE) {
        plant_inverter_modulation_limit(c, &va, &vb);
    }
    s->v_lim_alpha_V = va;
    s->v_lim_beta_V = vb;
    if (s->Vdt_V > 0.0) {
        const double ea = plant_inverter_deadtime_phase_error_V(c, ia_A);
        const double eb = plant_inverter_deadtime_phase_error_V(c, ib_A);
        const double ec = plant_inverter_deadtime_phase_error_V(c, ic_A);
        va += (2.0 / 3.0) * (ea - 0.5 * (eb + ec));
        vb += (eb - ec) / PLANT_SQRT3;
    }
    if (s->tripped) {
        va = 0.0;
        vb = 0.0;
    }
    s->v_app_alpha_V = va;
    s->v_app_beta_V = vb;
}
