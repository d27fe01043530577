/*
 * dq_linear.h - the linear dq machine model (Motor model.model = dq_linear; the equations and the exact path:
 * pmsm_plant.h): R, Ld, Lq, psi and the q-axis saturation knob.  Locked or imposed speed without saturation:
 * exact (expm(A Ts) and Van Loan's energy integrals); free mechanics or saturation: RK4 (plant_rk4.h).
 *
 * Its descriptor is plant_model_dq_linear (plant_model.h); the functions below are the folder's own and the
 * API's (plant_psi_q_Wb, plant_Lq_inc_H; the harmonic model builds on its prepare).
 */
#ifndef DQ_LINEAR_H
#define DQ_LINEAR_H

#include "plant_model.h"

extern const plant_model_desc_t plant_model_dq_linear;

/* q-axis flux linkage and incremental inductance (the saturation knob of plant_config_t). */
double dq_linear_psi_q_Wb(const plant_config_t *c, double iq_A);
double dq_linear_Lq_inc_H(const plant_config_t *c, double iq_A);
/* Lmin, the stiffness bound and, when it applies, the exact path's discretization (dq_linear.c). */
int dq_linear_prepare(plant_state_t *s, const plant_config_t *c, double p);
/* The RK4 bound alone (Lmin, lam_base): a model on the linear one's inductances that always integrates. */
void dq_linear_prepare_bound(plant_state_t *s, const plant_config_t *c, double p);

#endif
