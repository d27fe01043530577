/*
 * plant_rk4.h - the one integrator of the machine models that integrate (the linear model off its exact path, the
 * flux map, the harmonic model): classical RK4 over a period in N equal sub-steps, and the rule for N, the
 * stiffness bound of the RK4 path (pmsm_plant.h): N = max(rk4_min_substeps, ceil(Ts lambda / rk4_h_rel)),
 * lambda = lam_base + p |omega_m|, at most PLANT_RK4_MAX_SUBSTEPS.  The mechanics' part of a model's derivative
 * is here too: every model with free mechanics shares it.
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#ifndef PLANT_RK4_H
#define PLANT_RK4_H

#include "plant_types.h"

#define PLANT_RK4_MAX_SUBSTEPS 100000u
#define PLANT_RK4_MAX_Y 16 /* the longest state a model integrates */

/* A model's derivative dy = f(y) (ctx: the model's own context of the period). */
typedef void (*plant_rk4_deriv_fn)(void *ctx, const double *y, double *dy);

/* n sub-steps of h each from y (n_y <= PLANT_RK4_MAX_Y values), in place. */
void plant_rk4_run(plant_rk4_deriv_fn f, void *ctx, double *y, int n_y, uint32_t n, double h);

/* The stiffness bound's sub-steps, before the clamp: ceil(Ts (lam_base + p |omega_m|) / rk4_h_rel). */
double plant_rk4_stiff_substeps(const plant_state_t *s, const plant_config_t *c, double p);
/* nreal clamped to [max(1, rk4_min_substeps), PLANT_RK4_MAX_SUBSTEPS] (a NaN gives the maximum). */
uint32_t plant_rk4_clamp_substeps(const plant_config_t *c, double nreal);

/* The mechanics' part of a derivative: the speed's derivative and the friction and load powers (0 unless FREE). */
static inline void plant_rk4_mech_deriv(const plant_config_t *c, bool free_mech, double invJ, double Te, double wm,
                                        double *dw, double *p_fric, double *p_load)
{
    if (free_mech) {
        *dw = (Te - c->B_Nm_per_rad_s * wm - c->T_load_Nm) * invJ;
        *p_fric = c->B_Nm_per_rad_s * wm * wm;
        *p_load = c->T_load_Nm * wm;
    } else {
        *dw = 0.0;
        *p_fric = 0.0;
        *p_load = 0.0;
    }
}

/* The state the rotor-frame models integrate over a period (the linear model off its exact path, the harmonic model):
 * the currents, the electrical angle's cos/sin, the mechanical angle's increment, the speed, and the energies. */
enum { DQ_ID, DQ_IQ, DQ_C, DQ_S, DQ_TH, DQ_W, DQ_EIN, DQ_ECU, DQ_EME, DQ_EFR, DQ_ELD, DQ_N };

/* y[DQ_N] from the state at the period's start (the increments and energies 0). */
void plant_rk4_dq_begin(const plant_state_t *s, double *y);
/* The state from y at the period's end: currents, speed, the energies added, the angle wrapped with its whole turns
 * and its cos/sin re-derived from it (the angle and the encoder exactly consistent). */
void plant_rk4_dq_end(plant_state_t *s, const plant_config_t *c, const double *y);

#endif
