/* co_field_map.h - copy a record of the object dictionary to and from a core's config struct.
 *
 * The rows come from the X-macro lists protocols/gen_od.py writes for each manufacturer record
 * (OD_<NODE>_<RECORD>_FIELDS in od_<node>.h): the core's field carries the name of the EDS entry,
 * and the compiler refuses a name the core does not have. So a name, a default or a range is
 * written once, in the EDS; the node app expands the list and loops over the rows.
 *
 * Values go through a double: exact for the OD types used in records (REAL32, UNSIGNED8..32,
 * INTEGER8..32) and the core types (float, double, bool, fixed-width integers, enums).
 * Portable: no OS headers, no allocation. */
#ifndef CO_FIELD_MAP_H
#define CO_FIELD_MAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef enum {
    CO_FM_FLOAT = 0,
    CO_FM_DOUBLE,
    CO_FM_BOOL,
    CO_FM_SINT, /* int8_t .. int64_t */
    CO_FM_UINT  /* unsigned integers and enums of any size */
} co_fm_kind_t;

typedef struct {
    uint16_t od_offset;   /* offsetof(OD struct, record.field) */
    uint16_t core_offset; /* offsetof(core struct, [member.]field) */
    uint8_t od_kind, od_size;
    uint8_t core_kind, core_size;
} co_field_map_t;

/* Written by hand: clang-format 14 does not parse _Generic (nor offsetof in a braced list in a macro). */
/* clang-format off */
#define CO_FM_KIND(x)                                                                                  \
    _Generic((x), float: CO_FM_FLOAT, double: CO_FM_DOUBLE, bool: CO_FM_BOOL, int8_t: CO_FM_SINT,   \
             int16_t: CO_FM_SINT, int32_t: CO_FM_SINT, int64_t: CO_FM_SINT, default: CO_FM_UINT)

/* One row: od_t.record.field <-> core_t.field. */
#define CO_FIELD_MAP_ROW(od_t, core_t, record, field)                                                  \
    {(uint16_t)offsetof(od_t, record.field), (uint16_t)offsetof(core_t, field),                        \
     (uint8_t)CO_FM_KIND(((od_t *)0)->record.field), (uint8_t)sizeof(((od_t *)0)->record.field),        \
     (uint8_t)CO_FM_KIND(((core_t *)0)->field), (uint8_t)sizeof(((core_t *)0)->field)}

/* One row into a member struct of the core's config: od_t.record.field <-> core_t.member.field. */
#define CO_FIELD_MAP_ROW_IN(od_t, core_t, member, record, field)                                       \
    {(uint16_t)offsetof(od_t, record.field), (uint16_t)offsetof(core_t, member.field),                 \
     (uint8_t)CO_FM_KIND(((od_t *)0)->record.field), (uint8_t)sizeof(((od_t *)0)->record.field),        \
     (uint8_t)CO_FM_KIND(((core_t *)0)->member.field), (uint8_t)sizeof(((core_t *)0)->member.field)}
/* clang-format on */

/* A row as one assignment, for a record copied every period (a loop over rows costs tens of instructions a field
 * there): od.record.field = core->field by C's own conversion, which is what a row does between real types, and
 * between integer types (bool, enums) of any size; for those only. The names are still the EDS's: expand the
 * generated list with it. */
#define CO_FIELD_SET_OD(od, core, record, field) ((od).record.field = (core)->field)

/* One value of a kind and size (CO_FM_KIND, sizeof) as a double: exact for the types above. */
double co_field_map_value(const void *p, uint8_t kind, uint8_t size);

/* Every row's OD value (in the OD struct at `od`) -> the core struct at `core`. */
void co_field_map_to_core(const co_field_map_t *rows, size_t n, const void *od, void *core);
/* Every row's core value -> the OD. */
void co_field_map_to_od(const co_field_map_t *rows, size_t n, void *od, const void *core);

#endif
