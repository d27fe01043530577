/* drive_meas_coding.c - the compact measurement frame, decoded (see drive_meas_coding.h). */
#include "drive_meas_coding.h"

#include "drive_od.h"
#include "meas_coding.h"

#define MEAS OD_DRIVE_MEASUREMENT_IDX

void drive_meas_coding_reset(drive_meas_coding_t *c)
{
    c->have_last = 0u;
    c->last_counter = 0u;
    c->index = 0u;
}

/* The sample index of a coded sample: counter steps since the last one (0: the same sample again). A counter
 * behind the last one (more than half a cycle ahead: a late or reordered frame) is an old sample: its index is
 * that many before the last one, which stays (the supervision counts it late, never 239 lost). */
static uint16_t next_index(drive_meas_coding_t *c, uint8_t counter, uint8_t overflow)
{
    if (!c->have_last) {
        c->have_last = 1u;
        c->index = (uint16_t)(overflow >= 2u && counter > 0u ? counter - 1u : 0u);
    } else if (overflow >= 2u) {
        const unsigned steps = ((unsigned)counter + overflow - c->last_counter) % overflow;
        if (steps > overflow / 2u) return (uint16_t)(c->index - (overflow - steps));
        c->index = (uint16_t)(c->index + steps);
    } else {
        c->index = (uint16_t)(c->index + 1u);
    }
    c->last_counter = counter;
    return c->index;
}

int drive_meas_coding_take(drive_meas_coding_t *c, co_node_t *node, const co_pdo_t *pdo)
{
    if (!co_pdo_maps_entry(pdo, MEAS, OD_DRIVE_MEASUREMENT_I_A_CODE_SUB)) return 0;
    od_drive_mfr_t *m = mfr_of(node);
    od_drive_measurement_t *x = &m->x2100_Measurement;
    const od_drive_measurement_coding_t *k = &m->x2104_measurement_coding;
    x->i_a_A = meas_decode_current(x->i_a_code, k->current_lsb_A);
    x->i_b_A = meas_decode_current(x->i_b_code, k->current_lsb_A);
    if (co_pdo_maps_entry(pdo, MEAS, OD_DRIVE_MEASUREMENT_THETA_CODE_SUB))
        x->theta_m_rad = meas_decode_angle(x->theta_code, k->angle_counts);
    if (!co_pdo_maps_entry(pdo, MEAS, OD_DRIVE_MEASUREMENT_SAMPLE_INDEX_SUB))
        x->sample_index = next_index(c, x->sync_counter, node->c_sync_overflow);
    return 1;
}
