/* hil_fluxmap.c - the plant's flux map (plant_rt/blocks/plant_fluxmap.h) and its object 0x2008's bytes
 * (plant_rt/node/plant_fluxmap_obj.h) for the Python side: bench/motor/fluxmap.py's FluxMap evaluates, checks,
 * writes and reads a map here, so the interpolant, the check and the layout a motor check, the findings' truth and a
 * sweep use are the plant's own code, not a copy.  Exported from libhil.so for ctypes; the map is passed as the
 * plant holds it (plant_flux_map_t's four tables, row-major [i * n_q + j]). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "plant_fluxmap.h"
#include "plant_fluxmap_obj.h"

#define HIL_FLUXMAP_VERSION 1u /* the blob's version (plant.eds 0x2008; plant_fluxmap_obj_accept takes 1) */
#define EVAL_VALUES 6u         /* psi_d, psi_q, Ldd, Ldq, Lqd, Lqq: plant_flux_eval_t's order */

uint32_t hil_fluxmap_max_points(void);
int32_t hil_fluxmap_check(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                          const double *psi_q);
void hil_fluxmap_eval(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                      const double *psi_q, const double *id_at, const double *iq_at, uint32_t n, double *out);
int32_t hil_fluxmap_cells(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                          const double *psi_q, uint8_t *codes);
void hil_fluxmap_corners(uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d, const double *psi_q,
                         uint32_t i, uint32_t j, double *out);
uint32_t hil_fluxmap_blob_bytes(uint32_t n_d, uint32_t n_q);
uint32_t hil_fluxmap_blob(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                          const double *psi_q, uint8_t *out, uint32_t cap);
uint32_t hil_fluxmap_read(const uint8_t *data, uint32_t len, uint32_t *n_d, uint32_t *n_q, double *words,
                          uint32_t cap_words);

static plant_flux_map_t map_of(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                               const double *psi_q)
{
    const plant_flux_map_t m = {n_d, n_q, id_A, iq_A, psi_d, psi_q};
    return m;
}

uint32_t hil_fluxmap_max_points(void) { return PLANT_FLUXMAP_MAX_POINTS; }

/* plant_flux_map_check: 0, or the number of the first failing check (plant_fluxmap.h). */
int32_t hil_fluxmap_check(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                          const double *psi_q)
{
    const plant_flux_map_t m = map_of(n_d, n_q, id_A, iq_A, psi_d, psi_q);
    return (int32_t)plant_flux_map_check(&m);
}

/* plant_flux_map_eval at n points: out[6 k ..] = psi_d, psi_q, Ldd, Ldq, Lqd, Lqq at (id_at[k], iq_at[k]). */
void hil_fluxmap_eval(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                      const double *psi_q, const double *id_at, const double *iq_at, uint32_t n, double *out)
{
    const plant_flux_map_t m = map_of(n_d, n_q, id_A, iq_A, psi_d, psi_q);
    for (uint32_t k = 0; k < n; ++k) {
        plant_flux_eval_t e;
        plant_flux_map_eval(&m, id_at[k], iq_at[k], &e);
        double *o = out + EVAL_VALUES * k;
        o[0] = e.psi_d_Wb;
        o[1] = e.psi_q_Wb;
        o[2] = e.Ldd_H;
        o[3] = e.Ldq_H;
        o[4] = e.Lqd_H;
        o[5] = e.Lqq_H;
    }
}

/* The cell (i, j) as a map of its own: its two grid values per axis and its four corners per table. */
typedef struct {
    double id_A[2], iq_A[2], psi_d[4], psi_q[4];
    plant_flux_map_t m;
} cell_map_t;

static void cell_of(cell_map_t *c, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                    const double *psi_q, uint32_t i, uint32_t j)
{
    for (uint32_t a = 0; a < 2u; ++a) {
        c->id_A[a] = id_A[i + a];
        c->iq_A[a] = iq_A[j + a];
        for (uint32_t b = 0; b < 2u; ++b) {
            c->psi_d[2u * a + b] = psi_d[(i + a) * n_q + j + b];
            c->psi_q[2u * a + b] = psi_q[(i + a) * n_q + j + b];
        }
    }
    c->m = map_of(2u, 2u, c->id_A, c->iq_A, c->psi_d, c->psi_q);
}

/* plant_flux_map_check of every cell as a map of its own: codes[i * (n_q - 1) + j], 0 for a usable cell.  The check
 * takes the same differences and products in a cell's map as in the whole map's cell (the same grid values and
 * corners), so a map that passes its sizes, values and grids fails the invertibility check exactly where a cell's
 * code is 4.  Returns the number of failing cells, or -1 for sizes out of range. */
int32_t hil_fluxmap_cells(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                          const double *psi_q, uint8_t *codes)
{
    if (n_d < 2u || n_q < 2u || n_d > PLANT_FLUXMAP_MAX_POINTS || n_q > PLANT_FLUXMAP_MAX_POINTS) return -1;
    int32_t bad = 0;
    for (uint32_t i = 0; i + 1u < n_d; ++i) {
        for (uint32_t j = 0; j + 1u < n_q; ++j) {
            cell_map_t c;
            cell_of(&c, n_q, id_A, iq_A, psi_d, psi_q, i, j);
            const int code = plant_flux_map_check(&c.m);
            codes[i * (n_q - 1u) + j] = (uint8_t)code;
            bad += code != 0;
        }
    }
    return bad;
}

/* The interpolant at the four corners of cell (i, j), as the check sees them (the cell's own map evaluated at its
 * corners: u and w exactly 0 or 1): out[6 c ..] as hil_fluxmap_eval's, corner c = (u, w) = (c & 1, c >> 1). */
void hil_fluxmap_corners(uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d, const double *psi_q,
                         uint32_t i, uint32_t j, double *out)
{
    cell_map_t c;
    cell_of(&c, n_q, id_A, iq_A, psi_d, psi_q, i, j);
    double at_d[4], at_q[4];
    for (uint32_t k = 0; k < 4u; ++k) {
        at_d[k] = c.id_A[k & 1u];
        at_q[k] = c.iq_A[k >> 1];
    }
    hil_fluxmap_eval(2u, 2u, c.id_A, c.iq_A, c.psi_d, c.psi_q, at_d, at_q, 4u, out);
}

/* ---------------------------------------------------------------- the object's bytes (plant.eds 0x2008) */

uint32_t hil_fluxmap_blob_bytes(uint32_t n_d, uint32_t n_q)
{
    return PLANT_FLUXMAP_HEADER_BYTES + 8u * (n_d + n_q + 2u * n_d * n_q);
}

static void u32_to_le(uint32_t v, uint8_t *p)
{
    for (int i = 0; i < 4; ++i) p[i] = (uint8_t)(v >> (8 * i));
}

static uint8_t *f64s_to_le(const double *v, uint32_t n, uint8_t *p)
{
    for (uint32_t k = 0; k < n; ++k, p += 8) {
        uint64_t u;
        memcpy(&u, &v[k], sizeof u);
        for (int i = 0; i < 8; ++i) p[i] = (uint8_t)(u >> (8 * i));
    }
    return p;
}

/* The bytes a download of the map takes (what plant_fluxmap_obj_accept parses): "FMAP", the version, n_d, n_q as
 * little-endian UNSIGNED32, then id_A, iq_A, psi_d, psi_q as little-endian REAL64.  Returns the bytes written, or 0
 * when `cap` is too small (hil_fluxmap_blob_bytes) or the sizes are out of range.  Writes any values: a map the
 * plant would refuse too (a test's download). */
uint32_t hil_fluxmap_blob(uint32_t n_d, uint32_t n_q, const double *id_A, const double *iq_A, const double *psi_d,
                          const double *psi_q, uint8_t *out, uint32_t cap)
{
    if (n_d > PLANT_FLUXMAP_MAX_POINTS || n_q > PLANT_FLUXMAP_MAX_POINTS) return 0u;
    const uint32_t bytes = hil_fluxmap_blob_bytes(n_d, n_q);
    if (cap < bytes) return 0u;
    memcpy(out, "FMAP", 4);
    u32_to_le(HIL_FLUXMAP_VERSION, out + 4);
    u32_to_le(n_d, out + 8);
    u32_to_le(n_q, out + 12);
    uint8_t *p = out + PLANT_FLUXMAP_HEADER_BYTES;
    p = f64s_to_le(id_A, n_d, p);
    p = f64s_to_le(iq_A, n_q, p);
    p = f64s_to_le(psi_d, n_d * n_q, p);
    (void)f64s_to_le(psi_q, n_d * n_q, p);
    return bytes;
}

/* A blob read as the plant node reads a download (plant_fluxmap_obj_accept: its parser and its check): 0 and the
 * map in `words` (id_A, iq_A, psi_d, psi_q: n_d + n_q + 2 n_d n_q values) with its sizes, or the SDO abort code the
 * plant answers such a download with.  Not reentrant (the node's parser keeps a static scratch): one call at a time. */
uint32_t hil_fluxmap_read(const uint8_t *data, uint32_t len, uint32_t *n_d, uint32_t *n_q, double *words,
                          uint32_t cap_words)
{
    plant_fluxmap_obj_t *o = calloc(1u, sizeof *o);
    if (o == NULL) return CO_ABORT_OUT_OF_MEMORY;
    const uint32_t code = plant_fluxmap_obj_accept(o, data, len);
    if (code == 0u) {
        const plant_flux_map_t *m = plant_fluxmap_obj_map(o);
        const uint32_t table = m->n_d * m->n_q;
        if (m->n_d + m->n_q + 2u * table > cap_words) {
            free(o);
            return CO_ABORT_OUT_OF_MEMORY;
        }
        *n_d = m->n_d;
        *n_q = m->n_q;
        memcpy(words, m->id_A, 8u * m->n_d);
        memcpy(words + m->n_d, m->iq_A, 8u * m->n_q);
        memcpy(words + m->n_d + m->n_q, m->psi_d_Wb, 8u * table);
        memcpy(words + m->n_d + m->n_q + table, m->psi_q_Wb, 8u * table);
    }
    free(o);
    return code;
}
