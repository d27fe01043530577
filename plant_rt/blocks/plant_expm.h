/*
 * plant_expm.h - small dense matrix exponential (n <= PLANT_EXPM_NMAX).
 *
 * Scaling and squaring with a truncated Taylor series: A is scaled by 2^-s so
 * that ||A 2^-s||_1 <= 1/4, the series is summed until the next term is below
 * 1e-20 relative (at most 30 terms; the truncation bound at norm 1/4 is
 * 0.25^25/25! < 1e-40 after 24 terms), then squared s times.  Used only in
 * plant_prepare (not in the per-period path), so clarity beats speed.
 */
#ifndef PLANT_EXPM_H
#define PLANT_EXPM_H

#define PLANT_EXPM_NMAX 12

/* E = expm(A); A and E are n*n row-major, may not alias.  Returns 0, or -1
 * if n is out of range or the result is not finite. */
int plant_expm(int n, const double *A, double *E);

/* C = A*B (n*n row-major); C may not alias A or B. */
void plant_matmul(int n, const double *A, const double *B, double *C);

#endif
