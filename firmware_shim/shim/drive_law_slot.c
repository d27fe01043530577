/* drive_law_slot.c - the law slot, a component of the drive app (drive_law_slot.h): the parameter records
 * 0x2200-0x2203 -> drive_config_t and their checks, and every law's EDS record (its CurrentLaws key:
 * the papers' law folders' 0x25xx, a user law's 0x24xx), bound generically through the registry
 * (firmware_shim/core/current_law.h): its parameters reach the selected law, it checks them, its
 * commands act at once, its status entries are the law's own.  Each record is bound to this file's
 * handlers at init (drive_law_slot_bind): the parameter records to ext_config, the laws' to ext_law.
 * Portable: no OS headers, no allocation, float32. */
#include <string.h>

#include "co_field_map.h"
#include "drive_law_slot.h"
#include "drive_od.h"

/* The drive's parameter records -> drive_config_t, one row per EDS entry (the
 * lists od_drive_fields.h generates; the config's fields carry the EDS names). */
#define AT_ROOT(index, sub, record, field, eds_default) CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_config_t, record, field),
#define IN_OUTER(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, record, field),
/* one list a line (clang-format would run the macro lists together) */
/* clang-format off */
static const co_field_map_t config_rows[] = {
    OD_DRIVE_CONTROLLER_PARAMS(AT_ROOT)
    OD_DRIVE_OUTER_LOOPS_PARAMS(IN_OUTER)
    /* the profile of References belongs to the outer loops */
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, x2202_References, profile_speed_rad_s),
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, x2202_References, profile_accel_rad_s2)};
/* clang-format on */
#undef AT_ROOT
#undef IN_OUTER

/* OD -> drive_config_t.  core_ctrl: controller to keep when the OD selects the
 * open loop (the core has no open-loop controller). */
void drive_law_slot_od_to_config(const od_drive_mfr_t *m, drive_config_t *c, uint8_t core_ctrl)
{
    co_field_map_to_core(config_rows, sizeof config_rows / sizeof config_rows[0], m, c);
    if (c->controller == (uint8_t)OD_DRIVE_CONTROLLER_OPEN_LOOP) c->controller = core_ctrl;
}

/* ------------------------------------------------------------------ the laws' records */

/* The C struct of the manufacturer record at `index` inside the OD struct m (the node's, or a
 * candidate copy): its sub-index 0 is its first member.  NULL for none. */
static void *od_record(const co_node_t *node, const od_drive_mfr_t *m, uint16_t index)
{
    const co_od_entry_t *e = node != NULL ? co_od_find(node->od, index, 0u, NULL) : NULL;
    if (e == NULL) return NULL;
    const size_t off = (size_t)((const uint8_t *)e->data - (const uint8_t *)mfr_of(node));
    return (uint8_t *)(uintptr_t)m + off;
}

typedef struct {
    const co_node_t *node;
    const od_drive_mfr_t *m;
} record_ctx_t;

static const void *record_in(uint16_t index, void *user)
{
    const record_ctx_t *x = (const record_ctx_t *)user;
    return od_record(x->node, x->m, index);
}

/* The law that takes commands on the record at `index`, NULL for none. */
static const current_law_entry_t *commanded_law(uint16_t index)
{
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].record_index == index && current_law_table[i].law->command != NULL)
            return &current_law_table[i];
    return NULL;
}

int drive_law_slot_sync(drive_law_slot_t *slot)
{
    co_node_t *node = slot->node;
    drive_t *d = slot->drv;
    const current_law_entry_t *e = current_law_find(d->cfg.controller);
    if (node == NULL || e == NULL || e->record_index == 0u) return 0;
    const uint8_t *rec = (const uint8_t *)od_record(node, mfr_of(node), e->record_index);
    if (rec == NULL) return 0;
    int differ = d->law_record_index != e->record_index;
    for (uint16_t sub = 1u; !differ && sub <= 0xFFu; ++sub) {
        const co_od_entry_t *x = co_od_find(node->od, e->record_index, (uint8_t)sub, NULL);
        if (x == NULL) break;
        if ((x->flags & CO_ODF_WRITE) == 0u) continue; /* status entries (pre_read writes them) are no change */
        const size_t off = (size_t)((const uint8_t *)x->data - rec);
        differ = memcmp(d->law_record + off, x->data, co_od_value_size(x)) != 0;
    }
    if (differ) drive_set_law_record(d, rec, e->record_bytes);
    return differ;
}

static uint32_t abort_of(current_law_verdict_t v)
{
    switch (v) {
    case CURRENT_LAW_OK:
    case CURRENT_LAW_NOT_COMMAND: return 0u;
    case CURRENT_LAW_INCOMPATIBLE: return CO_ABORT_PARAM_INCOMPAT;
    case CURRENT_LAW_NOT_NOW: return CO_ABORT_DATA_STATE;
    default: return CO_ABORT_INVALID_VALUE;
    }
}

/* Would the core accept the parameter records of m (a candidate OD)?  (Its rules: drive_config_check,
 * and every law's on its record.) */
static uint32_t check_config(const drive_law_slot_t *slot, const od_drive_mfr_t *m, int controller_written)
{
    drive_config_t c = slot->drv->cfg;
    co_field_map_to_core(config_rows, sizeof config_rows / sizeof config_rows[0], m, &c); /* 0 = open loop */
    if (controller_written && drive_config_check_selection(&c) != DRIVE_CONFIG_OK)
        return CO_ABORT_INVALID_VALUE; /* a surface-mounted law with a salient model */
    record_ctx_t ctx = {slot->node, m};
    switch (drive_config_check(&c, m->x2202_References.mode, record_in, &ctx)) {
    case DRIVE_CONFIG_OK: return 0;
    case DRIVE_CONFIG_NO_SUCH_CONTROLLER: return CO_ABORT_INVALID_VALUE;
    default: return CO_ABORT_PARAM_INCOMPAT;
    }
}

/* The one config-change path: copy, and recompute at the next step if it changed. */
static void take_config(drive_law_slot_t *slot, const od_drive_mfr_t *m)
{
    drive_config_t c = slot->drv->cfg;
    drive_law_slot_od_to_config(m, &c, c.controller);
    int changed = memcmp(&c, &slot->drv->cfg, sizeof c) != 0;
    if (changed) slot->drv->cfg = c;
    changed |= drive_law_slot_sync(slot); /* the selected law's record (also when the selection changed) */
    if (changed) drive_apply_config(slot->drv);
}

/* ------------------------------------------------------------------ 0x2200, 0x2202, 0x2203 */

/* Every write is judged on the whole configuration it would make (the references' mode is part of it). */
static uint32_t config_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    const drive_law_slot_t *slot = (const drive_law_slot_t *)object;
    od_drive_mfr_t cand;
    if (!drive_od_candidate(slot->node, e, data, len, &cand)) return 0;
    return check_config(slot, &cand,
                        e->index == OD_DRIVE_CONTROLLER_IDX && e->subindex == OD_DRIVE_CONTROLLER_CONTROLLER_SUB);
}

/* In effect at the next step; of the references only the profile is configuration (the set-points are read by
 * every step). */
static void config_written(void *object, const co_od_entry_t *e)
{
    drive_law_slot_t *slot = (drive_law_slot_t *)object;
    if (e->index == OD_DRIVE_REFERENCES_IDX && e->subindex != OD_DRIVE_REFERENCES_PROFILE_SPEED_RAD_S_SUB &&
        e->subindex != OD_DRIVE_REFERENCES_PROFILE_ACCEL_RAD_S2_SUB)
        return;
    take_config(slot, mfr_of(slot->node));
}

/* ------------------------------------------------------------------ a law's record */

/* A law's command (acts at once, checked by the law now) or its parameters (checked on the configuration). */
static uint32_t law_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    drive_law_slot_t *slot = (drive_law_slot_t *)object;
    od_drive_mfr_t cand;
    if (!drive_od_candidate(slot->node, e, data, len, &cand)) return 0;
    const current_law_entry_t *law = commanded_law(e->index);
    if (law != NULL) {
        const int open_loop = mfr_of(slot->node)->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP;
        const current_law_verdict_t v =
            drive_law_command(slot->drv, law, od_record(slot->node, &cand, e->index), e->subindex, open_loop, 0);
        if (v != CURRENT_LAW_NOT_COMMAND) return abort_of(v);
    }
    return check_config(slot, &cand, 0);
}

static void law_written(void *object, const co_od_entry_t *e)
{
    drive_law_slot_t *slot = (drive_law_slot_t *)object;
    od_drive_mfr_t *m = mfr_of(slot->node);
    const current_law_entry_t *law = commanded_law(e->index);
    if (law != NULL) {
        const int open_loop = m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP;
        if (drive_law_command(slot->drv, law, od_record(slot->node, m, e->index), e->subindex, open_loop, 1) !=
            CURRENT_LAW_NOT_COMMAND)
            return;
    }
    take_config(slot, m);
}

/* Read: the selected law's status entries, as it computes them now; another law's record: its status as that law
 * last wrote it. */
static void law_read(void *object, const co_od_entry_t *e)
{
    drive_law_slot_t *slot = (drive_law_slot_t *)object;
    drive_t *d = slot->drv;
    const current_law_entry_t *selected = current_law_find(d->cfg.controller);
    if (selected != NULL && selected->record_index == e->index) drive_update_config(d); /* selected, not yet run */
    if (d->law != NULL && d->law->record_index == e->index)
        drive_law_status(d, od_record(slot->node, mfr_of(slot->node), e->index));
}

void drive_law_slot_bind(drive_law_slot_t *slot, co_node_t *node, drive_t *drv)
{
    slot->node = node;
    slot->drv = drv;
    slot->ext_config = (co_od_ext_t){slot, NULL, config_check, config_written};
    slot->ext_law = (co_od_ext_t){slot, law_read, law_check, law_written};
    (void)co_node_bind(node, OD_DRIVE_CONTROLLER_IDX, &slot->ext_config);
    (void)co_node_bind(node, OD_DRIVE_REFERENCES_IDX, &slot->ext_config);
    (void)co_node_bind(node, OD_DRIVE_OUTER_LOOPS_IDX, &slot->ext_config);
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].record_index != 0u)
            (void)co_node_bind(node, current_law_table[i].record_index, &slot->ext_law);
}
