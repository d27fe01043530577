/* co_emcy.c - EMCY producer (see co_emcy.h). */
#include "co_emcy.h"

#include <string.h>

#define IDX_ERROR_REGISTER 0x1001u
#define IDX_ERROR_FIELD 0x1003u
#define IDX_EMCY_COBID 0x1014u
#define COB_INVALID 0x80000000u
#define COB_EXTENDED 0x20000000u

void co_emcy_init(co_emcy_t *em, const co_od_t *od, co_tx_t *tx)
{
    memset(em, 0, sizeof *em);
    em->od = od;
    em->tx = tx;
}

void co_emcy_set_sending(co_emcy_t *em, bool pre_or_operational) { em->sending = pre_or_operational; }

void co_emcy_forget_active(co_emcy_t *em) { em->n_active = 0; }

static void emcy_send(co_emcy_t *em, uint16_t code, const uint8_t msef[5])
{
    uint32_t cob = co_od_get_u32(em->od, IDX_EMCY_COBID, 0);
    if ((cob & COB_INVALID) || !em->sending) return;
    uint8_t d[8] = {
        (uint8_t)code, (uint8_t)(code >> 8), (uint8_t)co_od_get_u32(em->od, IDX_ERROR_REGISTER, 0), 0, 0, 0, 0, 0};
    if (msef) memcpy(&d[3], msef, 5);
    co_tx_send(em->tx, (uint16_t)(cob & 0x7FFu), d, 8);
}

void co_emcy_report_error(co_emcy_t *em, uint16_t code, uint8_t err_reg_bits, const uint8_t msef[5])
{
    const co_od_t *od = em->od;
    uint8_t reg = (uint8_t)co_od_get_u32(od, IDX_ERROR_REGISTER, 0);
    reg |= (uint8_t)(err_reg_bits | CO_ERR_REG_GENERIC);
    co_od_set_u32(od, IDX_ERROR_REGISTER, 0, reg);
    /* Pre-defined error field: newest at sub-index 1, at most 8 kept. */
    uint32_t n = co_od_get_u32(od, IDX_ERROR_FIELD, 0);
    for (uint32_t i = (n < 8u ? n : 7u); i >= 1u; --i)
        co_od_set_u32(od, IDX_ERROR_FIELD, (uint8_t)(i + 1u), co_od_get_u32(od, IDX_ERROR_FIELD, (uint8_t)i));
    co_od_set_u32(od, IDX_ERROR_FIELD, 1, code);
    co_od_set_u32(od, IDX_ERROR_FIELD, 0, n < 8u ? n + 1u : 8u);
    bool known = false;
    for (uint8_t i = 0; i < em->n_active; ++i) known |= em->active[i] == code;
    if (!known && em->n_active < CO_EMCY_MAX_ACTIVE) em->active[em->n_active++] = code;
    emcy_send(em, code, msef);
}

void co_emcy_clear_error(co_emcy_t *em, uint16_t code)
{
    uint8_t j = 0;
    for (uint8_t i = 0; i < em->n_active; ++i)
        if (em->active[i] != code) em->active[j++] = em->active[i];
    if (j == em->n_active) return;
    em->n_active = j;
    if (j == 0) {
        co_od_set_u32(em->od, IDX_ERROR_REGISTER, 0, 0);
        emcy_send(em, CO_EMCY_NO_ERROR, NULL);
    }
}

uint32_t co_emcy_check_write(const co_emcy_t *em, const co_od_entry_t *e, const uint8_t *data)
{
    if (e->index == IDX_ERROR_FIELD && e->subindex == 0u && data[0] != 0u) return CO_ABORT_INVALID_VALUE;
    if (e->index == IDX_EMCY_COBID) {
        uint32_t v = (uint32_t)data[0] | (uint32_t)data[1] << 8 | (uint32_t)data[2] << 16 | (uint32_t)data[3] << 24;
        if (v & COB_EXTENDED) return CO_ABORT_INVALID_VALUE; /* 29-bit identifiers not supported */
        /* While valid only the valid bit may change (as the PDO COB-IDs, co_pdo.c). */
        uint32_t cob = co_od_get_u32(em->od, IDX_EMCY_COBID, 0);
        if (!(cob & COB_INVALID) && !(v & COB_INVALID) && ((v ^ cob) & 0x7FFu)) return CO_ABORT_INVALID_VALUE;
        /* Bit 31 = not valid; an identifier in use must not be restricted. */
        if (!(v & COB_INVALID) && co_cob_restricted(v)) return CO_ABORT_INVALID_VALUE;
    }
    return 0;
}

void co_emcy_before_store(co_emcy_t *em, const co_od_entry_t *e)
{
    if (e->index == IDX_ERROR_FIELD && e->subindex == 0u) {
        for (uint8_t s = 1; s <= 8u; ++s) co_od_set_u32(em->od, IDX_ERROR_FIELD, s, 0);
    }
}
