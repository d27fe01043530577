/*
 * plant_fluxmap.h - a motor's flux linkages as tables over the current plane,
 * psi_d(id, iq) and psi_q(id, iq) on a rectangular grid (FEA or measured flux
 * maps, docs/YOUR_MOTOR.md), interpolated bilinearly, and their inversion: the
 * currents for given flux linkages.
 *
 * The tables belong to the caller (the plant node holds them in its object
 * 0x2008 "Flux map"); the plant keeps a pointer.  Nothing here allocates.
 *
 * Interpolation: bilinear in the cell of (id, iq); outside the grid the edge
 * cell is extended (linear extrapolation).  The incremental inductances
 * L_xy = d psi_x / d i_y are the derivatives of that interpolant (constant
 * along a cell's edge direction, one-sided on a grid line).
 *
 * Inversion: Newton's method on the interpolant, warm-started from the last
 * solution, with step halving when the residual grows (the interpolant has
 * kinks on the grid lines).  It is the exact inverse of the forward map (to
 * ~1e-13 relative), not a second table with its own interpolation error, and
 * a tabulated linear model (psi_d = Ld id + psi, psi_q = Lq iq) is inverted in
 * one step.  The cost: 2-3 evaluations per call from a warm start
 * (docs/BENCHMARKS.md "The flux-map plant").
 *
 * Only <math.h>/<stdint.h>: no OS, no heap, no stdio.
 */
#ifndef PLANT_FLUXMAP_H
#define PLANT_FLUXMAP_H

#include <stdbool.h>
#include <stdint.h>

#define PLANT_FLUXMAP_MAX_POINTS 128u /* per axis */

typedef struct {
    uint32_t n_d, n_q;      /* grid points on the id and iq axes, 2 .. PLANT_FLUXMAP_MAX_POINTS */
    const double *id_A;     /* n_d, strictly increasing */
    const double *iq_A;     /* n_q, strictly increasing */
    const double *psi_d_Wb; /* n_d * n_q: [i * n_q + j] at (id_A[i], iq_A[j]) */
    const double *psi_q_Wb; /* same layout */
} plant_flux_map_t;

/* The interpolant at one point: the flux linkages and the incremental inductances. */
typedef struct {
    double psi_d_Wb, psi_q_Wb;
    double Ldd_H; /* d psi_d / d id */
    double Ldq_H; /* d psi_d / d iq */
    double Lqd_H; /* d psi_q / d id */
    double Lqq_H; /* d psi_q / d iq */
} plant_flux_eval_t;

/* Whether the map can be used: sizes in range, finite values, strictly increasing grids, and invertible: in
 * every cell, at each corner, d psi_d/d id > 0, d psi_q/d iq > 0 and the Jacobian's determinant > 0 (the
 * cell's interpolant is then one-to-one).  Returns 0, or the 1-based number of the first failing check
 * (1 sizes, 2 non-finite, 3 grid order, 4 not invertible). */
int plant_flux_map_check(const plant_flux_map_t *m);

void plant_flux_map_eval(const plant_flux_map_t *m, double id_A, double iq_A, plant_flux_eval_t *out);

/* The currents whose interpolated flux linkages are (psi_d_Wb, psi_q_Wb): Newton from (*id_A, *iq_A), the
 * answer written back.  Returns the evaluations used (>= 1), or -1 when it did not converge (the point with the
 * smallest residual found is written back). */
int plant_flux_map_currents(const plant_flux_map_t *m, double psi_d_Wb, double psi_q_Wb, double *id_A, double *iq_A);

/* The smallest incremental inductance on the diagonal over the grid's corners (the integration's stiffness
 * bound), and whether (id, iq) lies inside the grid. */
double plant_flux_map_Lmin_H(const plant_flux_map_t *m);
double plant_flux_map_cell_min_A(const plant_flux_map_t *m);
bool plant_flux_map_inside(const plant_flux_map_t *m, double id_A, double iq_A);

#endif
