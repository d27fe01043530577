/* co_emcy.h - EMCY producer (CiA 301 7.2.7): error register 0x1001, pre-defined
 * error field 0x1003, EMCY COB-ID 0x1014 and the list of active errors
 * (CANopenNode's CO_Emergency.h, reduced to the producer).
 *
 * Initialised with the object dictionary and the transmit side only; whoever owns
 * the NMT state tells it when sending is allowed (co_emcy_set_sending).
 */
#ifndef CO_EMCY_H
#define CO_EMCY_H

#include <stdbool.h>
#include <stdint.h>

#include "co_od.h"
#include "co_tx.h"
/* The EMCY error codes used by the slave itself (CiA 301 table 21), CO_EMCY_*: generated from the
 * [EmergencyCodes] of protocols/eds/common.ini by protocols/gen_od.py. */
#include "eds_common.h"

/* Error register bits (0x1001). */
#define CO_ERR_REG_GENERIC 0x01u
#define CO_ERR_REG_CURRENT 0x02u
#define CO_ERR_REG_VOLTAGE 0x04u
#define CO_ERR_REG_TEMPERATURE 0x08u
#define CO_ERR_REG_COMMUNICATION 0x10u
#define CO_ERR_REG_PROFILE 0x20u
#define CO_ERR_REG_MANUFACTURER 0x80u

#define CO_EMCY_MAX_ACTIVE 8u

typedef struct {
    const co_od_t *od;
    co_tx_t *tx;
    bool sending;                        /* NMT pre-operational or operational */
    uint16_t active[CO_EMCY_MAX_ACTIVE]; /* error codes raised and not cleared */
    uint8_t n_active;
} co_emcy_t;

void co_emcy_init(co_emcy_t *em, const co_od_t *od, co_tx_t *tx);

/* NMT state changed: EMCY frames go out only in pre-operational and operational. */
void co_emcy_set_sending(co_emcy_t *em, bool pre_or_operational);

/* Reset: no error is active any more (the OD itself is restored by co_od_reset). */
void co_emcy_forget_active(co_emcy_t *em);

/* Raise an error: adds it to 0x1003, sets 0x1001 bits, sends the EMCY frame. */
void co_emcy_report_error(co_emcy_t *em, uint16_t code, uint8_t err_reg_bits, const uint8_t msef[5]);

/* Clear an active error; when none is left, send the "error reset" EMCY and clear 0x1001. */
void co_emcy_clear_error(co_emcy_t *em, uint16_t code);

/* CiA 301 rules of an SDO write to the EMCY objects (0x1003:00, 0x1014); an abort code or 0.
 * The value already passed co_od_check_write.  0x1014 (CiA 301 7.5.2.32): while the EMCY
 * is valid (bit 31 = 0) its CAN-ID may not change (0x06090030); set bit 31 first. */
uint32_t co_emcy_check_write(const co_emcy_t *em, const co_od_entry_t *e, const uint8_t *data);

/* A checked write of e is about to be stored: writing 0x1003:00 clears the error history. */
void co_emcy_before_store(co_emcy_t *em, const co_od_entry_t *e);

#endif /* CO_EMCY_H */
