/* plant_fluxmap_obj.c - the plant's object 0x2008 "Flux map" (plant_fluxmap_obj.h). Portable: no OS headers. */
#include "plant_fluxmap_obj.h"

#include <string.h>

static uint32_t u32_le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static double f64_le(const uint8_t *p)
{
    uint64_t u = 0;
    for (int i = 7; i >= 0; --i) u = (u << 8) | p[i];
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static void f64_to_le(double d, uint8_t *p)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int i = 0; i < 8; ++i) p[i] = (uint8_t)(u >> (8 * i));
}

void plant_fluxmap_obj_init(plant_fluxmap_obj_t *o, co_domain_t *d)
{
    o->valid = false;
    o->live_bytes = 0u;
    d->data = o->blob;
    d->size = 0u;
    d->capacity = (uint32_t)sizeof o->blob;
}

/* The map's four tables in `words`, laid out as the blob's body. */
static void point_into(plant_flux_map_t *m, const double *words, uint32_t n_d, uint32_t n_q)
{
    m->n_d = n_d;
    m->n_q = n_q;
    m->id_A = words;
    m->iq_A = words + n_d;
    m->psi_d_Wb = words + n_d + n_q;
    m->psi_q_Wb = words + n_d + n_q + n_d * n_q;
}

/* The abort codes (plant.eds 0x2008): a download of the wrong length for its header - a truncated table above all
 * (a transfer cut short, a file cut) - is CiA 301's 0x0607 0013 "length of service parameter too low" (0x0607 0012
 * too high), as the stack answers any object given too few or too many bytes: the length is what is wrong, and a
 * tool that shows the code says so.  0x0609 0030 "value range of parameter exceeded" is for a map whose bytes are
 * all there but whose values are not a map (header, sizes, not finite, grids, not invertible). */
uint32_t plant_fluxmap_obj_accept(plant_fluxmap_obj_t *o, const uint8_t *data, uint32_t len)
{
    if (len < PLANT_FLUXMAP_HEADER_BYTES) return CO_ABORT_TOO_SHORT; /* not even the header: cut short */
    if (memcmp(data, "FMAP", 4) != 0 || u32_le(data + 4) != 1u) return CO_ABORT_INVALID_VALUE;
    const uint32_t n_d = u32_le(data + 8), n_q = u32_le(data + 12);
    if (n_d < 2u || n_q < 2u || n_d > PLANT_FLUXMAP_MAX_POINTS || n_q > PLANT_FLUXMAP_MAX_POINTS) {
        return CO_ABORT_INVALID_VALUE;
    }
    const uint32_t words = n_d + n_q + 2u * n_d * n_q;
    if (len != PLANT_FLUXMAP_HEADER_BYTES + 8u * words) {
        return len < PLANT_FLUXMAP_HEADER_BYTES + 8u * words ? CO_ABORT_TOO_SHORT : CO_ABORT_TOO_LONG;
    }
    /* checked in place of the live tables' copy only once it passes: parse into a view of the blob's words */
    static double scratch[PLANT_FLUXMAP_WORDS]; /* not in the period's path: a download's check */
    for (uint32_t k = 0; k < words; ++k) scratch[k] = f64_le(data + PLANT_FLUXMAP_HEADER_BYTES + 8u * k);
    plant_flux_map_t m;
    point_into(&m, scratch, n_d, n_q);
    if (plant_flux_map_check(&m) != 0) return CO_ABORT_INVALID_VALUE;
    memcpy(o->live, scratch, 8u * words);
    memcpy(o->live_header, data, PLANT_FLUXMAP_HEADER_BYTES);
    point_into(&o->map, o->live, n_d, n_q);
    o->live_bytes = PLANT_FLUXMAP_HEADER_BYTES + 8u * words;
    o->valid = true;
    return 0u;
}

void plant_fluxmap_obj_publish(plant_fluxmap_obj_t *o, co_domain_t *d)
{
    if (!o->valid) {
        d->size = 0u;
        return;
    }
    memcpy(o->blob, o->live_header, PLANT_FLUXMAP_HEADER_BYTES);
    const uint32_t words = (o->live_bytes - PLANT_FLUXMAP_HEADER_BYTES) / 8u;
    for (uint32_t k = 0; k < words; ++k) f64_to_le(o->live[k], o->blob + PLANT_FLUXMAP_HEADER_BYTES + 8u * k);
    d->size = o->live_bytes;
}
