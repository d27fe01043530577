/* yao2020_law.h - Yao 2020's DPCC as a current law of the drive
 * (current_law.h): the deadbeat predictive law with one-period delay
 * compensation (Eq. 9-12), its sliding-mode observer (Eq. 13-18), the R/L
 * identification by d-axis injection (Sec. IV-E, started and aborted by the
 * ident_command entry of its EDS record 0x2501, law.eds) and the RLS baseline beside it
 * (Sec. VI-B, Eq. 46-48).  A surface-mounted law: L_hat = Lq_hat_H; it limits
 * its own command radially to Vmax_V.  Registered as current_law_dpcc_yao2020. */
#ifndef YAO2020_LAW_H
#define YAO2020_LAW_H

#include <stdint.h>

#include "current_law.h"
#include "yao2020_dpcc.h"
#include "yao2020_rls.h"

typedef struct {
    yao2020_dpcc_config_t cfg; /* the record's parameters with the drive's Ts_s, model and Vmax_V */
    yao2020_dpcc_state_t st;
    yao2020_dpcc_cmd_t cmd; /* last command */
    yao2020_rls_config_t rls_cfg;
    yao2020_rls_state_t rls;
    float R_hat_cache, Lq_hat_cache; /* the drive's model at the last configure */
    uint8_t rls_cache;               /* rls_enable at the last configure */
} yao2020_law_state_t;

extern const current_law_t current_law_dpcc_yao2020;

#endif
