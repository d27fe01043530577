/* plant_expm.c - see plant_expm.h */
#include "plant_expm.h"

#include <math.h>
#include <string.h>

void plant_matmul(int n, const double *A, const double *B, double *C)
{
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            double acc = 0.0;
            for (int k = 0; k < n; ++k) {
                acc += A[i * n + k] * B[k * n + j];
            }
            C[i * n + j] = acc;
        }
    }
}

static double norm1(int n, const double *A)
{
    double best = 0.0;
    for (int j = 0; j < n; ++j) {
        double col = 0.0;
        for (int i = 0; i < n; ++i) {
            col += fabs(A[i * n + j]);
        }
        if (col > best) {
            best = col;
        }
    }
    return best;
}

int plant_expm(int n, const double *A, double *E)
{
    enum { NN = PLANT_EXPM_NMAX * PLANT_EXPM_NMAX };
    double As[NN], term[NN], tmp[NN];

    if (n < 1 || n > PLANT_EXPM_NMAX) {
        return -1;
    }
    const int nn = n * n;
    const double nrm = norm1(n, A);
    if (!isfinite(nrm)) {
        return -1;
    }
    int sq = 0;
    double scaled = nrm;
    while (scaled > 0.25 && sq < 200) {
        scaled *= 0.5;
        ++sq;
    }
    for (int i = 0; i < nn; ++i) {
        As[i] = ldexp(A[i], -sq);
    }
    /* E = I + As + As^2/2! + ... */
    memset(E, 0, sizeof(double) * (size_t)nn);
    memset(term, 0, sizeof(double) * (size_t)nn);
    for (int i = 0; i < n; ++i) {
        E[i * n + i] = 1.0;
        term[i * n + i] = 1.0;
    }
    for (int k = 1; k <= 30; ++k) {
        plant_matmul(n, term, As, tmp);
        const double inv_k = 1.0 / (double)k;
        for (int i = 0; i < nn; ++i) {
            term[i] = tmp[i] * inv_k;
            E[i] += term[i];
        }
        if (norm1(n, term) <= 1e-20 * norm1(n, E)) {
            break;
        }
    }
    for (int s = 0; s < sq; ++s) {
        plant_matmul(n, E, E, tmp);
        memcpy(E, tmp, sizeof(double) * (size_t)nn);
    }
    for (int i = 0; i < nn; ++i) {
        if (!isfinite(E[i])) {
            return -1;
        }
    }
    return 0;
}
