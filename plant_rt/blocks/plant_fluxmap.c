/*
 * plant_fluxmap.c - flux-map tables: bilinear interpolation, the incremental
 * inductances and the inversion by Newton's method (plant_fluxmap.h).
 *
 * Only <math.h>/<stdint.h>: no OS, no heap, no stdio.
 */
#include "plant_fluxmap.h"

#include <math.h>

#define NEWTON_MAX_EVALS 60
#define NEWTON_TOL_REL 1e-13

/* The cell [x[i], x[i+1]] holding v (the edge cell beyond the grid). */
static uint32_t cell_of(const double *x, uint32_t n, double v)
{
    uint32_t lo = 0u, hi = n - 1u; /* x[lo] <= v < x[hi] once inside */
    if (!(v > x[0])) return 0u;
    if (!(v < x[n - 1u])) return n - 2u;
    while (hi - lo > 1u) {
        const uint32_t mid = (lo + hi) / 2u;
        if (v < x[mid]) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    return lo;
}

/* One table's bilinear interpolant and its two derivatives in the cell (i, j). */
static void bilinear(const double *t, uint32_t n_q, uint32_t i, uint32_t j, double u, double w, double hd, double hq,
                     double *val, double *d_did, double *d_diq)
{
    const double f00 = t[i * n_q + j], f01 = t[i * n_q + j + 1u];
    const double f10 = t[(i + 1u) * n_q + j], f11 = t[(i + 1u) * n_q + j + 1u];
    const double a = f10 - f00, b = f01 - f00, c = f11 - f10 - f01 + f00;
    *val = f00 + a * u + b * w + c * u * w;
    *d_did = (a + c * w) / hd;
    *d_diq = (b + c * u) / hq;
}

void plant_flux_map_eval(const plant_flux_map_t *m, double id_A, double iq_A, plant_flux_eval_t *out)
{
    const uint32_t i = cell_of(m->id_A, m->n_d, id_A);
    const uint32_t j = cell_of(m->iq_A, m->n_q, iq_A);
    const double hd = m->id_A[i + 1u] - m->id_A[i], hq = m->iq_A[j + 1u] - m->iq_A[j];
    const double u = (id_A - m->id_A[i]) / hd, w = (iq_A - m->iq_A[j]) / hq;
    bilinear(m->psi_d_Wb, m->n_q, i, j, u, w, hd, hq, &out->psi_d_Wb, &out->Ldd_H, &out->Ldq_H);
    bilinear(m->psi_q_Wb, m->n_q, i, j, u, w, hd, hq, &out->psi_q_Wb, &out->Lqd_H, &out->Lqq_H);
}

int plant_flux_map_currents(const plant_flux_map_t *m, double psi_d_Wb, double psi_q_Wb, double *id_A, double *iq_A)
{
    double id = *id_A, iq = *iq_A;
    plant_flux_eval_t e;
    plant_flux_map_eval(m, id, iq, &e);
    double rd = e.psi_d_Wb - psi_d_Wb, rq = e.psi_q_Wb - psi_q_Wb;
    double r2 = rd * rd + rq * rq;
    int evals = 1;
    while (evals < NEWTON_MAX_EVALS) {
        const double det = e.Ldd_H * e.Lqq_H - e.Ldq_H * e.Lqd_H;
        if (!(det > 0.0)) break; /* a checked map has det > 0 everywhere */
        double dd = (e.Lqq_H * rd - e.Ldq_H * rq) / det;
        double dq = (e.Ldd_H * rq - e.Lqd_H * rd) / det;
        /* step, halved while the residual grows (a kink between cells) */
        plant_flux_eval_t e2;
        double nd, nq, rd2, rq2, r22;
        for (;;) {
            nd = id - dd;
            nq = iq - dq;
            plant_flux_map_eval(m, nd, nq, &e2);
            ++evals;
            rd2 = e2.psi_d_Wb - psi_d_Wb;
            rq2 = e2.psi_q_Wb - psi_q_Wb;
            r22 = rd2 * rd2 + rq2 * rq2;
            if (r22 <= r2 || evals >= NEWTON_MAX_EVALS) break;
            dd *= 0.5;
            dq *= 0.5;
        }
        if (r22 > r2) break; /* no step helped: the previous point is the best found */
        const bool small = fabs(dd) + fabs(dq) <= NEWTON_TOL_REL * (1.0 + fabs(nd) + fabs(nq));
        id = nd;
        iq = nq;
        e = e2;
        rd = rd2;
        rq = rq2;
        r2 = r22;
        if (small || r2 == 0.0) {
            *id_A = id;
            *iq_A = iq;
            return evals;
        }
    }
    *id_A = id;
    *iq_A = iq;
    return -1;
}

/* The incremental inductances at every corner of every cell (the interpolant's one-sided slopes there), each
 * handed to `visit` until it returns false. */
typedef bool (*corner_visit_t)(void *ctx, double ldd, double ldq, double lqd, double lqq);

static bool each_corner(const plant_flux_map_t *m, corner_visit_t visit, void *ctx)
{
    for (uint32_t i = 0; i + 1u < m->n_d; ++i) {
        for (uint32_t j = 0; j + 1u < m->n_q; ++j) {
            const double hd = m->id_A[i + 1u] - m->id_A[i], hq = m->iq_A[j + 1u] - m->iq_A[j];
            for (int corner = 0; corner < 4; ++corner) {
                const double u = (double)(corner & 1), w = (double)(corner >> 1);
                double v, ldd, ldq, lqd, lqq;
                bilinear(m->psi_d_Wb, m->n_q, i, j, u, w, hd, hq, &v, &ldd, &ldq);
                bilinear(m->psi_q_Wb, m->n_q, i, j, u, w, hd, hq, &v, &lqd, &lqq);
                if (!visit(ctx, ldd, ldq, lqd, lqq)) return false;
            }
        }
    }
    return true;
}

static bool invertible_at(void *ctx, double ldd, double ldq, double lqd, double lqq)
{
    (void)ctx;
    return ldd > 0.0 && lqq > 0.0 && ldd * lqq - ldq * lqd > 0.0;
}

/* the smaller eigenvalue of the symmetric part bounds the stiffness */
static bool lower_lmin(void *ctx, double ldd, double ldq, double lqd, double lqq)
{
    double *lmin = (double *)ctx;
    const double b = 0.5 * (ldq + lqd);
    const double mean = 0.5 * (ldd + lqq), rad = sqrt(0.25 * (ldd - lqq) * (ldd - lqq) + b * b);
    double l = mean - rad;
    if (!(l > 0.0)) l = 0.5 * (ldd < lqq ? ldd : lqq); /* strongly cross-coupled: the diagonal's */
    if (l < *lmin) *lmin = l;
    return true;
}

static bool increasing(const double *x, uint32_t n)
{
    for (uint32_t i = 0; i + 1u < n; ++i) {
        if (!(x[i + 1u] > x[i])) return false;
    }
    return true;
}

int plant_flux_map_check(const plant_flux_map_t *m)
{
    if (m == 0 || m->id_A == 0 || m->iq_A == 0 || m->psi_d_Wb == 0 || m->psi_q_Wb == 0 || m->n_d < 2u || m->n_q < 2u ||
        m->n_d > PLANT_FLUXMAP_MAX_POINTS || m->n_q > PLANT_FLUXMAP_MAX_POINTS) {
        return 1;
    }
    for (uint32_t i = 0; i < m->n_d; ++i) {
        if (!isfinite(m->id_A[i])) return 2;
    }
    for (uint32_t j = 0; j < m->n_q; ++j) {
        if (!isfinite(m->iq_A[j])) return 2;
    }
    for (uint32_t k = 0; k < m->n_d * m->n_q; ++k) {
        if (!isfinite(m->psi_d_Wb[k]) || !isfinite(m->psi_q_Wb[k])) return 2;
    }
    if (!increasing(m->id_A, m->n_d) || !increasing(m->iq_A, m->n_q)) return 3;
    if (!each_corner(m, invertible_at, 0)) return 4;
    return 0;
}

double plant_flux_map_Lmin_H(const plant_flux_map_t *m)
{
    double lmin = INFINITY;
    (void)each_corner(m, lower_lmin, &lmin);
    return lmin;
}

double plant_flux_map_cell_min_A(const plant_flux_map_t *m)
{
    double h = INFINITY;
    for (uint32_t i = 0; i + 1u < m->n_d; ++i) h = fmin(h, m->id_A[i + 1u] - m->id_A[i]);
    for (uint32_t j = 0; j + 1u < m->n_q; ++j) h = fmin(h, m->iq_A[j + 1u] - m->iq_A[j]);
    return h;
}

bool plant_flux_map_inside(const plant_flux_map_t *m, double id_A, double iq_A)
{
    return id_A >= m->id_A[0] && id_A <= m->id_A[m->n_d - 1u] && iq_A >= m->iq_A[0] && iq_A <= m->iq_A[m->n_q - 1u];
}
