/* plant_fluxmap_obj.h - the plant's object 0x2008 "Flux map" (plant.eds): the owner of the flux-map tables the
 * flux_map model (plant_fluxmap.h) reads.  Portable glue: no OS headers.
 *
 * A download of the DOMAIN streams into `blob` (the SDO server writes there); when it completes, the check
 * parses it (the layout: plant.eds 0x2008's description), checks it (plant_flux_map_check) and only then copies
 * it into the live tables `map` points at: a refused download leaves the live map as it was.  Written only
 * while the plant is not running.  An upload reads back the live map's bytes. */
#ifndef PLANT_FLUXMAP_OBJ_H
#define PLANT_FLUXMAP_OBJ_H

#include <stdbool.h>
#include <stdint.h>

#include "co_od.h"
#include "plant_fluxmap.h"

#define PLANT_FLUXMAP_HEADER_BYTES 16u
#define PLANT_FLUXMAP_MAX_BYTES   \
    (PLANT_FLUXMAP_HEADER_BYTES + \
     8u * (2u * PLANT_FLUXMAP_MAX_POINTS + 2u * PLANT_FLUXMAP_MAX_POINTS * PLANT_FLUXMAP_MAX_POINTS))
#define PLANT_FLUXMAP_WORDS ((PLANT_FLUXMAP_MAX_BYTES - PLANT_FLUXMAP_HEADER_BYTES) / 8u)

typedef struct {
    uint8_t blob[PLANT_FLUXMAP_MAX_BYTES]; /* where a download lands */
    uint32_t live_bytes;                   /* the live map's size in bytes (0: none) */
    uint8_t live_header[PLANT_FLUXMAP_HEADER_BYTES];
    double live[PLANT_FLUXMAP_WORDS]; /* id_A, iq_A, psi_d_Wb, psi_q_Wb of the live map */
    plant_flux_map_t map;             /* points into `live` */
    bool valid;                       /* a map was accepted */
} plant_fluxmap_obj_t;

/* No map; the DOMAIN `d` (the OD's 0x2008) points at the object's buffer. */
void plant_fluxmap_obj_init(plant_fluxmap_obj_t *o, co_domain_t *d);
/* A completed download of `len` bytes (in o->blob): 0 and the live map replaced, or an SDO abort code
 * (CO_ABORT_TOO_SHORT / CO_ABORT_TOO_LONG: fewer / more bytes than its header's sizes take; CO_ABORT_INVALID_VALUE:
 * header, sizes or plant_flux_map_check; the live map unchanged). */
uint32_t plant_fluxmap_obj_accept(plant_fluxmap_obj_t *o, const uint8_t *data, uint32_t len);
/* Before an upload: the blob holds the live map's bytes, `d` its size. */
void plant_fluxmap_obj_publish(plant_fluxmap_obj_t *o, co_domain_t *d);
/* The map for plant_config_t.flux_map: NULL until one was accepted. */
static inline const plant_flux_map_t *plant_fluxmap_obj_map(const plant_fluxmap_obj_t *o)
{
    return o->valid ? &o->map : (const plant_flux_map_t *)0;
}

#endif
